"""An Owen-scrambled, padded Sobol' sampler as pure Warp functions.

Interface (both are pure functions of their arguments, so an image is bit-identical whatever the
threads, tiles or split of samples across runs, and renders of disjoint sample ranges merge exactly):

    sobol_1d(seed, pixel, index, dim) -> float     # uses sample dimension ``dim``
    sobol_2d(seed, pixel, index, dim) -> wp.vec2   # uses sample dimensions ``dim`` and ``dim + 1``

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
  * Each component is Owen-scrambled (nested uniform scrambling): bit k of the value, counted from
    the most significant, is flipped by a random bit chosen by the k bits above it. Scrambling keeps
    the net property, makes every single point uniformly distributed over the 2**24 grid (so the
    estimator is unbiased), and gives Owen's variance rates: O(N**-3) for smooth integrands (RMSE
    slope -1.5), about O(N**-1.5) for integrands with discontinuities along curves (RMSE slope
    ~-0.75), and for any square-integrable integrand at most (b/(b-1))**(s-1) = 2 times the variance
    of plain Monte Carlo (Owen 1997, for a (0,m,s)-net in base b = 2, s = 2 dimensions).
  * The sample index is shuffled per (seed, pixel, dim) by another nested uniform scramble, of the
    index read as a 32-bit binary fraction (equivalently Burley's "nested uniform scramble" of the
    index, which bit-reverses, applies a scramble that flips each bit by the bits below it, and
    reverses back). Bit k of the index is flipped by a random function of the bits above k, so
    every aligned block of 2**m indices maps onto an aligned block of 2**m Sobol' indices -- a
    (0,m,2)-net again -- while the order within and between blocks differs per dimension pair. That
    is the padding: two 2D requests of the same sample are paired by independent random orders,
    which decorrelates them (with the caveat under Limits), while each pair keeps its own 2D
    stratification.
  * A 1D request is the scrambled van der Corput sequence under the same shuffle (so
    ``sobol_1d(s, p, i, d) == sobol_2d(s, p, i, d).x``); every aligned block of 2**m values holds one
    value in each interval [j 2**-m, (j+1) 2**-m).
  * Random bits: the flips of a scramble form a binary tree (one flip per node, chosen by the prefix
    of bits above it). The top 15 levels are cut into three subtrees of 5 levels; each subtree takes
    its 31 flips from the 31 low bits of one 32-bit hash of (seed, depth, prefix), so every node has
    its own random bit, at one hash per 5 levels instead of one per level (Laine-Karras-style
    multiply hashes are cheaper still but only approximate independent node flips). Below level 15
    a value's 9 remaining flips come from one hash of its 15-bit prefix, and the index's bits above
    its low 15 are XORed with key bits (a digital shift), its low 15 bits getting exact flips keyed
    by their block of 2**15. Both shortcuts are still nested scrambles (a flip depends only on bits
    above it), so nets and aligned blocks are kept at every size, and for any aligned block of up to
    2**15 samples the joint distribution is exactly that of full Owen scrambling: such a block's
    points have distinct 15-bit prefixes in each coordinate and share one index block, so no two
    points share a tail hash. The hash is Wellons' "lowbias32" integer finaliser (two multiplies;
    near-full avalanche in every output bit by its author's measurements; a bijection, so distinct
    nodes of one tree never share a hash), keyed by hash(seed, pixel, dim).

Limits:
  * The stratification guarantees hold for aligned power-of-two blocks. With a non-power-of-two spp
    the first n samples are a union of aligned blocks (the binary digits of n), each a net, so the
    estimate is still unbiased and better than independent sampling, but the error is that of its
    worst (smallest) blocks, and convergence as a function of spp is irregular between powers of two.
    Slices [offset, offset + n) merge bit-exactly with any others, but are best aligned
    (offset a multiple of n, n a power of two) for the quality of each slice alone.
  * Stratification is per 2D pair only: there is no joint stratification across pairs (in 4D, 8D...),
    so high-dimensional integrands gain only from their low-dimensional structure. A 2D request at
    d uses dimensions d and d+1: no other request of the same sample may use either (sobol_1d at d
    would repeat its x); callers assign dimensions explicitly.
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
  * Beyond 2**15 samples per pixel, the fine digits (below 2**-15) of points sharing a 15-bit prefix
    share their flips: still unbiased and stratified, slightly less random than Owen's scrambling.
  * Cost: per 2D request 17 hashes (3 for the key, 2 of them per pixel and shared by a sample's requests
    through ``pixel_key`` and the ``*_keyed`` functions, 2 for the component seeds, 4 for the index
    shuffle, 4 per component), several times a PCG draw; benchmarks/bench_sampler.py prints both.
    Seven of a request's fifteen own hashes depend only on (pixel, dimension) below index 2**15, but
    a path's vertex cannot keep them across samples without per-thread storage for every dimension;
    instead ``make_batch`` computes a vertex's requests as the lanes of one call (the same values),
    which clang packs into vector registers (docs/performance.md, "A vertex's Sobol' requests as one
    batch").
"""

from __future__ import annotations

import warp as wp

from warp_spt.samplers.base import Sampler, SamplerState, batch_lanes, detach_requests, sampler_state

# Python-int spellings of the constants, shared with the numpy reference in the tests.
LOWBIAS_MUL1 = 0x7FEB352D
LOWBIAS_MUL2 = 0x846CA68B
SEED_SALT = 0x9E3779B9   # 2**32 / golden ratio: keeps seed 0 away from the hash's fixed point 0
DIM_MUL = 0x85EBCA77     # odd: spreads consecutive dimensions over the 32-bit range
X_SALT = 0x68E31DA4
Y_SALT = 0xB5297A4D
BLOCK_SALT = 0x27D4EB2F  # differs from X_SALT and Y_SALT above bit 16, so no block key equals theirs
VALUE_BITS = wp.constant(24)  # float32 resolution below 1
EXACT_LEVELS = wp.constant(15)  # levels with one independent flip per node (3 subtrees)
CHUNK_LEVELS = wp.constant(5)  # levels of the flip tree served by one 32-bit hash (2**5 - 1 = 31 bits)

# Unsigned constants above 2**31 must be typed as such, or the generated C++ narrows them.
_MUL1 = wp.constant(wp.uint32(LOWBIAS_MUL1))
_MUL2 = wp.constant(wp.uint32(LOWBIAS_MUL2))
_SEED_SALT = wp.constant(wp.uint32(SEED_SALT))
_DIM_MUL = wp.constant(wp.uint32(DIM_MUL))
_X_SALT = wp.constant(wp.uint32(X_SALT))
_Y_SALT = wp.constant(wp.uint32(Y_SALT))
_BLOCK_SALT = wp.constant(wp.uint32(BLOCK_SALT))
_HIGH_17 = wp.constant(wp.uint32(0xFFFF8000))     # index bits above the exactly scrambled 15
_TOP_24 = wp.constant(wp.uint32(0xFFFFFF00))      # a value's bits that reach the float
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
def sobol_dim1(i: wp.uint32) -> wp.uint32:
    """Sobol' dimension 1 of index i as a 0.32 fraction. Its direction numbers (primitive polynomial
    x + 1) are the rows of Pascal's triangle mod 2, so by Lucas' theorem output bit r (from the top)
    is the XOR of the index bits k whose binary position number k contains r's (k & r == r): a
    superset-sum transform over the 5-bit positions, done in 5 bit-parallel butterfly steps."""
    i = i ^ ((i >> wp.uint32(1)) & wp.uint32(0x55555555))
    i = i ^ ((i >> wp.uint32(2)) & wp.uint32(0x33333333))
    i = i ^ ((i >> wp.uint32(4)) & wp.uint32(0x0F0F0F0F))
    i = i ^ ((i >> wp.uint32(8)) & wp.uint32(0x00FF00FF))
    i = i ^ (i >> wp.uint32(16))
    return reverse_bits(i)


@wp.func
def _subtree_flips(w: wp.uint32, h: wp.uint32) -> wp.uint32:
    """The flips of a 5-level subtree for the input bits at the top of w, placed at the top: level j
    uses node 2**j - 1 + (the j bits above it) of the 31-node tree stored in h's bits."""
    f = (h & wp.uint32(1)) << wp.uint32(31)
    f = f | (((h >> (wp.uint32(1) + (w >> wp.uint32(31)))) & wp.uint32(1)) << wp.uint32(30))
    f = f | (((h >> (wp.uint32(3) + (w >> wp.uint32(30)))) & wp.uint32(1)) << wp.uint32(29))
    f = f | (((h >> (wp.uint32(7) + (w >> wp.uint32(29)))) & wp.uint32(1)) << wp.uint32(28))
    return f | (((h >> (wp.uint32(15) + (w >> wp.uint32(28)))) & wp.uint32(1)) << wp.uint32(27))


@wp.func
def exact_flips(v: wp.uint32, seed: wp.uint32) -> wp.uint32:
    """The nested uniform flips of the top 15 levels of v (a 0.32 fraction), at their bit positions.

    Bit ``level`` (from the top) is flipped by the flip-tree node reached by the bits above it. The
    tree is cut into three subtrees of 5 levels; each draws its 31 node flips from one hash of its
    root's prefix (with a marker bit above it that encodes the depth) xor seed. The subtrees are
    independent, so their hashes run in parallel (the loop is unrolled)."""
    flips = wp.uint32(0)
    for c in range(wp.static(EXACT_LEVELS // CHUNK_LEVELS)):
        top = c * CHUNK_LEVELS
        prefix = wp.uint32(wp.uint64(v) >> wp.uint64(32 - top))       # 64-bit: top == 0 is legal
        h = mix32((prefix | (wp.uint32(1) << wp.uint32(top))) ^ seed)
        flips = flips | (_subtree_flips(v << wp.uint32(top), h) >> wp.uint32(top))
    return flips


@wp.func
def owen_scramble(v: wp.uint32, seed: wp.uint32) -> wp.uint32:
    """Owen scrambling of the top 24 bits of v (a 0.32 fraction; the lower 8 bits become 0): exact
    flips for the top 15 levels, then, for levels 15..23, nine random bits drawn from one hash of the
    15-bit prefix (whose marker bit 2**15 sets it apart from the subtree roots)."""
    tail = mix32(((v >> wp.uint32(17)) | wp.uint32(0x8000)) ^ seed)
    flips = exact_flips(v, seed) | ((tail >> wp.uint32(23)) << wp.uint32(8))
    return (v ^ flips) & _TOP_24


@wp.func
def pixel_key(seed: wp.uint32, pixel: int) -> wp.uint32:
    """The part of every request key that depends on (seed, pixel) only: a sampler computes it once
    per sample and passes it to the ``*_keyed`` functions."""
    return mix32(mix32(seed ^ _SEED_SALT) ^ wp.uint32(pixel))


@wp.func
def request_seed(seed: wp.uint32, pixel: int, dim: int) -> wp.uint32:
    """The key of one (seed, pixel, dimension) request: it seeds the index shuffle, and, hashed with a
    salt, each component's value scramble."""
    return mix32(pixel_key(seed, pixel) ^ (wp.uint32(dim) * _DIM_MUL))


@wp.func
def to_unit(v: wp.uint32) -> float:
    """The top 24 bits of a 0.32 fraction as a float in [0, 1 - 2**-24] (exact, never 1.0)."""
    return wp.float32(v >> wp.uint32(32 - VALUE_BITS)) * _INV_2_24


@wp.func
def shuffled_index(key: wp.uint32, index: int) -> wp.uint32:
    """The Sobol' index used for global sample ``index``: a nested scramble of the index read as a
    binary fraction (bit k flipped by a function of the bits above k), so aligned power-of-two blocks
    map onto aligned blocks of the same size, in an order private to ``key``. The low 15 bits get
    exact nested uniform flips keyed by the block of 2**15 they lie in; the high bits are XORed with
    the key's (a digital shift: a nested scramble whose flips do not depend on the bits above)."""
    i = wp.uint32(index)
    block_seed = mix32(key ^ _BLOCK_SALT ^ (i >> wp.uint32(EXACT_LEVELS)))
    low = exact_flips(i << wp.uint32(32 - EXACT_LEVELS), block_seed) >> wp.uint32(32 - EXACT_LEVELS)
    return i ^ (key & _HIGH_17) ^ low


# The two request functions are called, not inlined (inline=False): inlined at each of a kernel's
# request sites they made the fast kernel's compile 0.3 s longer for no measurable run time
# (docs/performance.md, Where the time goes).
@wp.func(inline=False)
def sobol_1d_keyed(pkey: wp.uint32, index: int, dim: int) -> float:
    """``sobol_1d`` with its (seed, pixel) part given as ``pkey = pixel_key(seed, pixel)``."""
    key = mix32(pkey ^ (wp.uint32(dim) * _DIM_MUL))
    i = shuffled_index(key, index)
    return to_unit(owen_scramble(reverse_bits(i), mix32(key ^ _X_SALT)))


@wp.func(inline=False)
def sobol_2d_keyed(pkey: wp.uint32, index: int, dim: int) -> wp.vec2:
    """``sobol_2d`` with its (seed, pixel) part given as ``pkey = pixel_key(seed, pixel)``."""
    key = mix32(pkey ^ (wp.uint32(dim) * _DIM_MUL))
    i = shuffled_index(key, index)
    x = owen_scramble(reverse_bits(i), mix32(key ^ _X_SALT))
    y = owen_scramble(sobol_dim1(i), mix32(key ^ _Y_SALT))
    return wp.vec2(to_unit(x), to_unit(y))


@wp.func
def sobol_1d(seed: wp.uint32, pixel: int, index: int, dim: int) -> float:
    """Sample dimension ``dim`` of global sample ``index`` of ``pixel``: a shuffled, Owen-scrambled
    van der Corput value in [0, 1)."""
    return sobol_1d_keyed(pixel_key(seed, pixel), index, dim)


@wp.func
def sobol_2d(seed: wp.uint32, pixel: int, index: int, dim: int) -> wp.vec2:
    """Sample dimensions ``dim`` and ``dim + 1`` of global sample ``index`` of ``pixel``: a shuffled,
    Owen-scrambled point of the 2D Sobol' (0,2)-sequence in [0, 1)^2."""
    return sobol_2d_keyed(pixel_key(seed, pixel), index, dim)


def make_batch(offsets: tuple) -> object:
    """``batch(state, base) -> vector``: the 2-D requests at ``base + offsets[k]`` as the lanes of
    one call (``Sampler.make_batch``), bit for bit ``sobol_2d_keyed``'s values. The lanes are padded
    to a power of two (``batch_lanes``; repeating the last offset) so that clang packs them whole into xmm / ymm
    integer instructions: each lane's hashes are the same straight-line code, so the batch costs
    about what one or two scalar requests do (benchmarks/bench_sampler_lanes.py: 3.3x the scalar
    rate for 4 lanes, 5.3x for 8). Built once per offsets (the kernel cache)."""
    from warp_spt.runtime import kernel_cache

    return kernel_cache.cached("sobol batch", tuple(offsets), lambda: _build_batch(tuple(offsets)))


def _build_batch(offsets: tuple) -> object:
    if not offsets:
        raise ValueError("a Sobol' batch needs at least one dimension offset")
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
        for j in range(wp.static(lanes)):
            key = mix32(pkey ^ (wp.uint32(base + offs[j]) * _DIM_MUL))
            i = shuffled_index(key, index)
            out[j] = to_unit(owen_scramble(reverse_bits(i), mix32(key ^ _X_SALT)))
            out[j + wp.static(lanes)] = to_unit(owen_scramble(sobol_dim1(i), mix32(key ^ _Y_SALT)))
        return out

    @wp.func
    def batch(state: SamplerState, base: int):
        return lanes_2d(state.rng, state.index, base)

    return batch


# ---------------------------------------------------------------------------------------------
# The sampler record (warp_spt.samplers.SAMPLERS["sobol"])


def make():
    """The Sobol' sampler's record: the pixel's key is computed once per sample (``start``), each
    request hashes only its own dimension and index, and no PCG chain is kept."""
    @wp.func
    def start(seed: wp.uint32, pixel: int, index: int) -> SamplerState:
        return sampler_state(seed, pixel, index, pixel_key(seed, pixel))

    @wp.func
    def next_1d(state: SamplerState, dim: int):
        return sobol_1d_keyed(state.rng, state.index, dim), state

    @wp.func
    def next_2d(state: SamplerState, dim: int):
        return sobol_2d_keyed(state.rng, state.index, dim), state

    detach_requests(next_1d, next_2d)
    return Sampler("sobol", start, next_1d, next_2d, random_access=True,
                   summary="Owen-scrambled Sobol' points, a (0,2)-sequence per pixel", make_batch=make_batch)
