"""A numpy reference for warp_spt.samplers.sobol_affine, from the definitions, not from the kernel.

Sobol' points from the generator matrices of tests/support/sobol_reference.py; a 0.32 fraction's digits
reversed one bit at a time; the scramble on the reversed digits: (r + h) * (h's halves swapped | 1),
x xor x * MIX_MUL, then (x + a) * (m | 1), all mod 2**32; the index shuffle the same scramble of the
index's bits read from the top. Only the hash, the seed chain
and the salts are shared with the module: they are its specification.
"""

from __future__ import annotations

import numpy as np

from warp_spt.samplers import sobol_affine as A

from tests.support import sobol_reference as R

M32 = np.uint64(0xFFFFFFFF)


def reverse(v) -> np.ndarray:
    """The 32 bits of each v in reverse order, bit by bit."""
    v = np.asarray(v, dtype=np.uint64)
    out = np.zeros_like(v)
    for k in range(32):
        out |= ((v >> np.uint64(k)) & np.uint64(1)) << np.uint64(31 - k)
    return out


def affine(r, a, m) -> np.ndarray:
    """(r + a) * (m | 1) mod 2**32."""
    return (((r + np.asarray(a, dtype=np.uint64)) & M32) * (np.asarray(m, dtype=np.uint64) | np.uint64(1))) & M32


def scramble(v, h, a, m) -> np.ndarray:
    """The nested scramble of 0.32 fractions v: digits reversed; the affine map keyed by h (its
    halves swapped for the multiplier); x xor x * MIX_MUL; the affine map (a, m); reversed back."""
    h = np.asarray(h, dtype=np.uint64)
    x = affine(reverse(v), h, ((h >> np.uint64(16)) | (h << np.uint64(16))) & M32)
    x = x ^ ((x * np.uint64(A.MIX_MUL)) & M32)
    return reverse(affine(x, a, m))


def _words(key, inner: int, add, mul):
    return (R.mix32(key ^ np.uint64(inner)), add, R.mix32(key ^ np.uint64(mul)))


def _request(seed, pixel, index, dim):
    seed, pixel, index, dim = np.broadcast_arrays(seed, pixel, index, dim)
    key = R.request_seed(seed, pixel, dim)
    # the index as a fraction (its bit 31 the first digit): scrambled, it is the Sobol' index
    i = scramble(np.asarray(index, dtype=np.uint64), *_words(key, A.SHUFFLE_INNER_SALT, key, A.SHUFFLE_MUL_SALT))
    return key, i


def affine_2d(seed, pixel, index, dim) -> np.ndarray:
    """[..., 2] float32 points, as sobol_affine.POINTS.two for broadcast (seed, pixel, index, dim)."""
    key, i = _request(seed, pixel, index, dim)
    x = scramble(R.sobol_u32(i, 0), *_words(key, A.X_INNER_SALT, R.mix32(key ^ np.uint64(A.X_ADD_SALT)), A.X_MUL_SALT))
    y = scramble(R.sobol_u32(i, 1), *_words(key, A.Y_INNER_SALT, R.mix32(key ^ np.uint64(A.Y_ADD_SALT)), A.Y_MUL_SALT))
    return np.stack([R.to_unit(x), R.to_unit(y)], axis=-1)


def affine_1d(seed, pixel, index, dim) -> np.ndarray:
    key, i = _request(seed, pixel, index, dim)
    x = scramble(R.sobol_u32(i, 0), *_words(key, A.X_INNER_SALT, R.mix32(key ^ np.uint64(A.X_ADD_SALT)), A.X_MUL_SALT))
    return R.to_unit(x)
