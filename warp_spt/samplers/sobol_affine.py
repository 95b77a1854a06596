"""Padded Sobol' points with a cheaper nested scramble, affine in the digits (``sobol-affine``).

The padded Sobol' points of :mod:`warp_spt.samplers.sobol_points`, as ``sobol``'s (Sobol' dimensions 0
and 1 per 2-D request, an index shuffle per (seed, pixel, dimension), ``next_1d(d) == next_2d(d).x``,
values multiples of 2**-24 in [0, 1 - 2**-24], global sample index below 2**31, ``make_batch``), with a
different scramble, cheaper per request (docs/performance.md, "A per-pixel cache, and a cheaper
scramble").

The scramble. Write a 0.32 fraction's digits in reverse order, r = sum_k d_k 2**k (d_0 is the most
significant digit). Its last stage maps x -> (x + a) * m mod 2**32 with a uniform 32-bit ``a`` and a
uniform odd ``m``. Adding and multiplying by an odd number carry only upwards, so digit k of the
result is digit k of x xor a function of the digits before it: a nested scramble, which keeps every
net and every stratum of an aligned power-of-two block (as Owen's scrambling and the Laine-Karras
family of hash scrambles do; written here from that defining property).

Why its error is Owen's: the variance of an estimate from scrambled points is a sum over pairs of
points of the covariance of the integrand at them, so it depends only on the joint distribution of
each pair. Take two inputs whose first differing digit is k: x_A - x_B = 2**k * o with o odd. Their
images are s_A = (x_A + a) m, uniform (``a`` is), and s_B = s_A - 2**k o m, where o m is a uniform odd
number independent of s_A (given ``m``, ``s_A`` is uniform whatever ``m``). So s_A and s_B share
digits 0..k-1, differ at k, and digits k+1.. of s_B are uniform and independent of s_A: exactly the
pair distribution of Owen's nested uniform scrambling. Hence the same variance for every
square-integrable integrand (Owen's rates: RMSE slope -1.5 for smooth 2-D integrands, ~-0.75 with
discontinuities, never above twice plain Monte Carlo's variance) and each point uniform on the 2**24
grid (unbiased).

The first stage, before it: the same affine map keyed by one more word h (h as addend, h with its
halves swapped as multiplier), then the fixed nonlinear nested bijection x ^ (x * MIX_MUL) (an even
multiplier: each bit changes by the bits below it). Any nested bijection keeps the first differing
digit of two inputs, so the pair law above stays exact; what the first stage adds is randomness in
three- and more-point statistics, on which no mean error depends but the spread of the error from
pixel to pixel does: with the last stage alone (a multiplier m = 1 mod 2**t leaves the first t
digits merely shifted), the RMSE's own standard error over 8192 estimates was up to 10x ``sobol``'s;
with both stages it is ``sobol``'s (docs/performance.md). ``tests/samplers/test_sobol.py`` checks the pair
distribution and the nets (for both scrambles), ``tests/samplers/test_sobol_affine.py`` the error against
``sobol``'s.

Per 2-D request: the key (one hash of the pixel key and the dimension), eight more hashes for the
stages' words (index shuffle, x, y; the key itself is the shuffle's addend), six affine maps, three
bit reversals (the index's own reversal is shared by a sample's requests) and Sobol' dimension 1's
butterfly: 9 hashes against ``sobol``'s 15 plus its flip-tree look-ups. The hashes stand in for
independent uniform words (Wellons' lowbias32, as in ``sobol``), the usual approximation of every
hash-seeded sampler.

The index shuffle is the same scramble of the index's bits read from the top (the index
reversed, mapped, reversed back): bit k of the index is flipped by a function of the bits above
it, so aligned blocks of 2**m indices map onto aligned blocks, in an order private to the
dimension. Limits as ``sobol``'s (non-power-of-two spp, stratification per 2-D pair only, two pairs
of a sample paired by independent shuffles), except that no size is special: the scramble is the
same for any number of samples below 2**31.
"""

from __future__ import annotations

import warp as wp

from warp_spt.samplers.sobol_points import Scramble, mix32, pascal, points, reverse_bits, to_unit

# Salts of the eight words derived from a request's key (arbitrary distinct constants, odd so that
# none is 0; the key's own hash already spreads dimensions and pixels).
SHUFFLE_MUL_SALT = 0x2C1B3C6D
X_ADD_SALT = 0x297A2D39
X_MUL_SALT = 0xB7E15163
Y_ADD_SALT = 0x5BD1E995
Y_MUL_SALT = 0xCC9E2D51
SHUFFLE_INNER_SALT = 0x2545F491
X_INNER_SALT = 0x1B873593
Y_INNER_SALT = 0x66546B65
MIX_MUL = 0x6F4F2A3C     # even: x ^ (x * MIX_MUL) changes each bit by the bits below it only

_SHUFFLE_MUL = wp.constant(wp.uint32(SHUFFLE_MUL_SALT))
_X_ADD = wp.constant(wp.uint32(X_ADD_SALT))
_X_MUL = wp.constant(wp.uint32(X_MUL_SALT))
_Y_ADD = wp.constant(wp.uint32(Y_ADD_SALT))
_Y_MUL = wp.constant(wp.uint32(Y_MUL_SALT))
_SHUFFLE_INNER = wp.constant(wp.uint32(SHUFFLE_INNER_SALT))
_X_INNER = wp.constant(wp.uint32(X_INNER_SALT))
_Y_INNER = wp.constant(wp.uint32(Y_INNER_SALT))
_MIX_MUL = wp.constant(wp.uint32(MIX_MUL))


@wp.func
def affine(r: wp.uint32, a: wp.uint32, m: wp.uint32) -> wp.uint32:
    """The nested scramble of digits in reversed order ``r``: (r + a) * (m | 1) mod 2**32."""
    return (r + a) * (m | wp.uint32(1))


@wp.func
def inner(r: wp.uint32, h: wp.uint32) -> wp.uint32:
    """The first stage of the scramble: an affine map keyed by one word ``h`` (its halves swapped for
    the multiplier), then the fixed nonlinear nested bijection x ^ (x * MIX_MUL)."""
    x = affine(r, h, (h >> wp.uint32(16)) | (h << wp.uint32(16)))
    return x ^ (x * _MIX_MUL)


@wp.func
def scramble(r: wp.uint32, h: wp.uint32, a: wp.uint32, m: wp.uint32) -> wp.uint32:
    """The whole scramble of reversed digits ``r``: ``affine(inner(r, h), a, m)``."""
    return affine(inner(r, h), a, m)


@wp.func
def shuffled(key: wp.uint32, rindex: wp.uint32) -> wp.uint32:
    """The Sobol' index of the sample whose index has reversed bits ``rindex``."""
    return reverse_bits(scramble(rindex, mix32(key ^ _SHUFFLE_INNER), key, mix32(key ^ _SHUFFLE_MUL)))


@wp.func
def scrambled_x(key: wp.uint32, i: wp.uint32) -> float:
    """Sobol' dimension 0 of index i (the radical inverse: its reversed digits are i itself), scrambled."""
    return to_unit(reverse_bits(scramble(i, mix32(key ^ _X_INNER), mix32(key ^ _X_ADD), mix32(key ^ _X_MUL))))


@wp.func
def scrambled_y(key: wp.uint32, i: wp.uint32) -> float:
    """Sobol' dimension 1 of index i, scrambled."""
    return to_unit(reverse_bits(scramble(pascal(i), mix32(key ^ _Y_INNER), mix32(key ^ _Y_ADD), mix32(key ^ _Y_MUL))))


@wp.func
def reversed_index(index: int) -> wp.uint32:
    """The sample index with its bits reversed: what ``shuffled`` reads (the same for every lane of a batch)."""
    return reverse_bits(wp.uint32(index))


AFFINE = Scramble("sobol-affine",
                  "Sobol' points with a cheaper nested scramble (affine in the digits), of sobol's error",
                  reversed_index, shuffled, scrambled_x, scrambled_y)
POINTS = points(AFFINE)   # one(seed, pixel, index, dim), two, their *_keyed forms, make_batch


def make():
    """The record of ``SAMPLERS["sobol-affine"]``."""
    return POINTS.sampler()
