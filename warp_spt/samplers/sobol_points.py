"""Padded, scrambled Sobol' points per pixel: the one builder of the ``sobol`` and ``sobol-affine`` samplers.

Interface (built per scramble by :func:`points`; all pure functions of their arguments, so an image is
bit-identical whatever the threads, tiles or split of samples across runs, and renders of disjoint
sample ranges merge exactly):

    one(seed, pixel, index, dim) -> float     # uses sample dimension ``dim``
    two(seed, pixel, index, dim) -> wp.vec2   # uses sample dimensions ``dim`` and ``dim + 1``

``index`` is the GLOBAL sample index of the pixel (0 .. 2**31 - 1, so a render of samples
[offset, offset + n) passes ``offset + j``). Values lie in [0, 1 - 2**-24]: every value is a multiple
of 2**-24, converted exactly to float32, so 1.0 is never returned.

Design: padded 2D pairs (after Burley 2020, "Practical Hash-based Owen Scrambling", and pbrt-v4's
PaddedSobolSampler; written from their descriptions).
  * Every 2D request is Sobol' dimensions 0 and 1 (van der Corput and the Pascal-matrix dimension),
    which together form a (0,2)-sequence in base 2: every aligned block of 2**m consecutive indices is
    a (0,m,2)-net, i.e. each of the 2**m elementary intervals of any shape 2**-a x 2**-(m-a) holds
    exactly one point. Only these two dimensions are used because higher Sobol' dimensions have much
    worse 2D projections, and a path tracer's integrand is dominated by its 2D pieces (pixel area,
    lens, BSDF direction, light position).
  * Each component is scrambled by a nested scramble: digit k of the value, counted from the most
    significant, is flipped by a random function of the k digits above it. Any nested scramble keeps
    the net property, and a uniform one makes every single point uniform over the 2**24 grid (so the
    estimator is unbiased).
  * The sample index is shuffled per (seed, pixel, dim) by a nested scramble of the index read as a
    32-bit binary fraction: bit k of the index is flipped by a function of the bits above k, so every
    aligned block of 2**m indices maps onto an aligned block of 2**m Sobol' indices -- a (0,m,2)-net
    again -- while the order within and between blocks differs per dimension pair. That is the
    padding: two 2D requests of the same sample are paired by independent random orders, which
    decorrelates them (with the caveat under Limits), while each pair keeps its own 2D stratification.
  * A 1D request is the scrambled van der Corput sequence under the same shuffle (so
    ``one(s, p, i, d) == two(s, p, i, d).x``); every aligned block of 2**m values holds one value in
    each interval [j 2**-m, (j+1) 2**-m).
  * Random words come from Wellons' "lowbias32" integer finaliser (two multiplies; near-full avalanche
    in every output bit by its author's measurements; a bijection), keyed by hash(seed, pixel, dim).

A scramble (:class:`Scramble`) is four Warp functions: the sample index's own word (what every lane
of a batch shares), the index shuffle, and each component's scramble. ``sobol`` (Owen's nested
uniform scrambling, :mod:`warp_spt.samplers.sobol`) and ``sobol-affine`` (nested affine maps,
:mod:`warp_spt.samplers.sobol_affine`) are two records; the request functions, the batch and the
sampler record are built here from either, the scramble bound when the functions are built (a closure),
so the generated code has no branch on it.

Limits:
  * The stratification guarantees hold for aligned power-of-two blocks. With a non-power-of-two spp
    the first n samples are a union of aligned blocks (the binary digits of n), each a net, so the
    estimate is still unbiased and better than independent sampling, but the error is that of its
    worst (smallest) blocks, and convergence as a function of spp is irregular between powers of two.
    Slices [offset, offset + n) merge bit-exactly with any others, but are best aligned
    (offset a multiple of n, n a power of two) for the quality of each slice alone.
  * Stratification is per 2D pair only: there is no joint stratification across pairs (in 4D, 8D...),
    so high-dimensional integrands gain only from their low-dimensional structure. A 2D request at
    d uses dimensions d and d+1: no other request of the same sample may use either (a 1D request at
    d would repeat its x); callers assign dimensions explicitly.
  * Two dimension pairs of one sample are paired by independent nested shuffles. Because every
    aligned pair of samples is stratified in each dimension, the first digits of two dimension pairs
    are, per aligned pair of samples, either (lo,lo)+(hi,hi) or (lo,hi)+(hi,lo): one coin per sample
    pair instead of one per sample. An integrand's interaction between two pairs (e.g. a step in x_a
    times a step in x_b) can therefore get up to twice the variance that independent numbers give
    it (the correlation between pairs has variance ~1.6/N in place of 1/N; tests/samplers/test_sobol.py
    bounds it by 2/N). A sampler that knows spp (pbrt's PaddedSobol: a uniform random permutation
    of the spp indices) avoids this but loses progressive stratification and the global index. The
    2D parts converge at Owen's rates, so it wins whenever they dominate; the benchmark measures both.
  * Values are quantised to 24 bits (float32's resolution near 1); indices beyond 2**31 - 1 are not
    supported (the ``int`` argument).
  * Cost: two of a request's hashes are per pixel, shared by a sample's requests through ``pixel_key``
    and the ``*_keyed`` functions. Most of the rest depend only on (pixel, dimension) below index
    2**15, but a path's vertex cannot keep them across samples without per-thread storage for every
    dimension; instead ``make_batch`` computes a vertex's requests as the lanes of one call (the same
    values), which clang packs into vector registers (docs/performance.md, "A vertex's Sobol'
    requests as one batch").
"""

from __future__ import annotations

from dataclasses import dataclass

import warp as wp

from warp_spt.samplers.base import Sampler, SamplerState, batch_lanes, detach_requests, sampler_state

# Python-int spellings of the constants, shared with the numpy references in the tests.
LOWBIAS_MUL1 = 0x7FEB352D
LOWBIAS_MUL2 = 0x846CA68B
SEED_SALT = 0x9E3779B9   # 2**32 / golden ratio: keeps seed 0 away from the hash's fixed point 0
DIM_MUL = 0x85EBCA77     # odd: spreads consecutive dimensions over the 32-bit range
VALUE_BITS = wp.constant(24)  # float32 resolution below 1

# Unsigned constants above 2**31 must be typed as such, or the generated C++ narrows them.
_MUL1 = wp.constant(wp.uint32(LOWBIAS_MUL1))
_MUL2 = wp.constant(wp.uint32(LOWBIAS_MUL2))
_SEED_SALT = wp.constant(wp.uint32(SEED_SALT))
_DIM_MUL = wp.constant(wp.uint32(DIM_MUL))
_INV_2_24 = wp.constant(5.9604644775390625e-08)   # 2**-24


@wp.func
def mix32(x: wp.uint32) -> wp.uint32:
    """Wellons' lowbias32: a bijective 32-bit hash with good avalanche in every output bit."""
    x = x ^ (x >> wp.uint32(16))
    x = x * _MUL1
    x = x ^ (x >> wp.uint32(15))
    x = x * _MUL2
    return x ^ (x >> wp.uint32(16))


@wp.func
def reverse_bits(v: wp.uint32) -> wp.uint32:
    """The 32 bits of v in reverse order (the van der Corput radical inverse, as a 0.32 fraction)."""
    v = ((v >> wp.uint32(1)) & wp.uint32(0x55555555)) | ((v & wp.uint32(0x55555555)) << wp.uint32(1))
    v = ((v >> wp.uint32(2)) & wp.uint32(0x33333333)) | ((v & wp.uint32(0x33333333)) << wp.uint32(2))
    v = ((v >> wp.uint32(4)) & wp.uint32(0x0F0F0F0F)) | ((v & wp.uint32(0x0F0F0F0F)) << wp.uint32(4))
    v = ((v >> wp.uint32(8)) & wp.uint32(0x00FF00FF)) | ((v & wp.uint32(0x00FF00FF)) << wp.uint32(8))
    return (v >> wp.uint32(16)) | (v << wp.uint32(16))


@wp.func
def pascal(i: wp.uint32) -> wp.uint32:
    """Sobol' dimension 1 of index i with its digits in reversed order. Its direction numbers (primitive
    polynomial x + 1) are the rows of Pascal's triangle mod 2, so by Lucas' theorem output bit r is the
    XOR of the index bits k whose binary position number k contains r's (k & r == r): a superset-sum
    transform over the 5-bit positions, done in 5 bit-parallel butterfly steps."""
    i = i ^ ((i >> wp.uint32(1)) & wp.uint32(0x55555555))
    i = i ^ ((i >> wp.uint32(2)) & wp.uint32(0x33333333))
    i = i ^ ((i >> wp.uint32(4)) & wp.uint32(0x0F0F0F0F))
    i = i ^ ((i >> wp.uint32(8)) & wp.uint32(0x00FF00FF))
    return i ^ (i >> wp.uint32(16))


@wp.func
def sobol_dim1(i: wp.uint32) -> wp.uint32:
    """Sobol' dimension 1 of index i as a 0.32 fraction."""
    return reverse_bits(pascal(i))


@wp.func
def pixel_key(seed: wp.uint32, pixel: int) -> wp.uint32:
    """The part of every request key that depends on (seed, pixel) only: a sampler computes it once
    per sample and passes it to the ``*_keyed`` functions."""
    return mix32(mix32(seed ^ _SEED_SALT) ^ wp.uint32(pixel))


@wp.func
def request_key(pkey: wp.uint32, dim: int) -> wp.uint32:
    """The key of one (seed, pixel, dimension) request, ``pkey = pixel_key(seed, pixel)``: it seeds the
    index shuffle and, hashed with salts, each component's scramble."""
    return mix32(pkey ^ (wp.uint32(dim) * _DIM_MUL))


@wp.func
def to_unit(v: wp.uint32) -> float:
    """The top 24 bits of a 0.32 fraction as a float in [0, 1 - 2**-24] (exact, never 1.0)."""
    return wp.float32(v >> wp.uint32(32 - VALUE_BITS)) * _INV_2_24


@dataclass(frozen=True)
class Scramble:
    """A sampler's scramble, as four Warp functions (``key`` a request's ``request_key``):

    * ``sample(index: int)``: the word of the global sample index that ``shuffle`` reads; the same for
      every request of a sample, so a batch computes it once for all its lanes;
    * ``shuffle(key, sample(index)) -> wp.uint32``: the Sobol' index, a nested scramble of the index;
    * ``x(key, i) -> float`` and ``y(key, i) -> float``: Sobol' dimensions 0 and 1 of Sobol' index i,
      scrambled, as ``to_unit`` values."""

    name: str          # the sampler's name in ``SAMPLERS``
    summary: str       # one line for --help and the docs
    sample: object
    shuffle: object
    x: object
    y: object


@dataclass(frozen=True)
class Points:
    """The request functions of one scramble (built by :func:`points`): ``one_keyed(pkey, index, dim)
    -> float`` and ``two_keyed(pkey, index, dim) -> wp.vec2`` with the pixel's part given as ``pkey =
    pixel_key(seed, pixel)``, and ``one`` / ``two`` of (seed, pixel, index, dim)."""

    scramble: Scramble
    one_keyed: object
    two_keyed: object
    one: object
    two: object

    def make_batch(self, offsets: tuple) -> object:
        """``batch(state, base) -> vector``: the 2-D requests at ``base + offsets[k]`` as the lanes of
        one call (``Sampler.make_batch``), bit for bit ``two_keyed``'s values. The lanes are padded to
        a power of two (``batch_lanes``; repeating the last offset) so that clang packs them whole into
        xmm / ymm integer instructions: each lane's hashes are the same straight-line code, so the
        batch costs about what one or two scalar requests do (benchmarks/bench_sampler_lanes.py: 3.3x
        the scalar rate for 4 lanes, 5.3x for 8). Built once per offsets (the kernel cache)."""
        from warp_spt.runtime import kernel_cache

        offsets = tuple(offsets)
        return kernel_cache.cached(f"{self.scramble.name} batch", offsets,
                                   lambda: _build_batch(self.scramble, offsets))

    def sampler(self) -> Sampler:
        """The sampler's record: the pixel's key is computed once per sample (``start``), each request
        hashes only its own dimension and index, and no PCG chain is kept."""
        one_keyed, two_keyed = self.one_keyed, self.two_keyed

        @wp.func
        def start(seed: wp.uint32, pixel: int, index: int) -> SamplerState:
            return sampler_state(seed, pixel, index, pixel_key(seed, pixel))

        @wp.func
        def next_1d(state: SamplerState, dim: int):
            return one_keyed(state.rng, state.index, dim), state

        @wp.func
        def next_2d(state: SamplerState, dim: int):
            return two_keyed(state.rng, state.index, dim), state

        detach_requests(next_1d, next_2d)
        return Sampler(self.scramble.name, start, next_1d, next_2d, random_access=True,
                       summary=self.scramble.summary, make_batch=self.make_batch)


def points(scramble: Scramble) -> Points:
    """The request functions of ``scramble`` (its functions bound at build time, not branched on)."""
    sample, shuffle, x_of, y_of = scramble.sample, scramble.shuffle, scramble.x, scramble.y

    # The two keyed functions are called, not inlined (inline=False): inlined at each of a kernel's
    # request sites they made the fast kernel's compile 0.3 s longer for no measurable run time
    # (docs/performance.md, Where the time goes).
    @wp.func(inline=False)
    def one_keyed(pkey: wp.uint32, index: int, dim: int) -> float:
        key = request_key(pkey, dim)
        return x_of(key, shuffle(key, sample(index)))

    @wp.func(inline=False)
    def two_keyed(pkey: wp.uint32, index: int, dim: int) -> wp.vec2:
        key = request_key(pkey, dim)
        i = shuffle(key, sample(index))
        return wp.vec2(x_of(key, i), y_of(key, i))

    @wp.func
    def one(seed: wp.uint32, pixel: int, index: int, dim: int) -> float:
        return one_keyed(pixel_key(seed, pixel), index, dim)

    @wp.func
    def two(seed: wp.uint32, pixel: int, index: int, dim: int) -> wp.vec2:
        return two_keyed(pixel_key(seed, pixel), index, dim)

    return Points(scramble, one_keyed, two_keyed, one, two)


def _build_batch(scramble: Scramble, offsets: tuple) -> object:
    if not offsets:
        raise ValueError("a Sobol' batch needs at least one dimension offset")
    sample, shuffle, x_of, y_of = scramble.sample, scramble.shuffle, scramble.x, scramble.y
    lanes = batch_lanes(len(offsets))
    padded = offsets + (offsets[-1],) * (lanes - len(offsets))
    vi = wp.types.vector(length=lanes, dtype=wp.int32)
    vf = wp.types.vector(length=2 * lanes, dtype=wp.float32)
    offs = wp.constant(vi(*padded))

    # out of line: a function of its own keeps the lanes together for clang's vectoriser, and the
    # path kernel calls it once per vertex
    @wp.func(inline=False)
    def lanes_2d(pkey: wp.uint32, index: int, base: int):
        out = vf()
        s = sample(index)
        for j in range(wp.static(lanes)):
            key = request_key(pkey, base + offs[j])
            i = shuffle(key, s)
            out[j] = x_of(key, i)
            out[j + wp.static(lanes)] = y_of(key, i)
        return out

    @wp.func
    def batch(state: SamplerState, base: int):
        return lanes_2d(state.rng, state.index, base)

    return batch
