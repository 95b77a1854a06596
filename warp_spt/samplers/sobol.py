"""The ``sobol`` sampler: padded Sobol' points (:mod:`warp_spt.samplers.sobol_points`) under Owen's
nested uniform scrambling.

    POINTS.one(seed, pixel, index, dim) -> float     # uses sample dimension ``dim``
    POINTS.two(seed, pixel, index, dim) -> wp.vec2   # uses sample dimensions ``dim`` and ``dim + 1``

The scramble (after Burley 2020, "Practical Hash-based Owen Scrambling"; written from its description):
  * Each component is Owen-scrambled (nested uniform scrambling): bit k of the value, counted from
    the most significant, is flipped by a random bit chosen by the k bits above it. Scrambling keeps
    the net property, makes every single point uniformly distributed over the 2**24 grid (so the
    estimator is unbiased), and gives Owen's variance rates: O(N**-3) for smooth integrands (RMSE
    slope -1.5), about O(N**-1.5) for integrands with discontinuities along curves (RMSE slope
    ~-0.75), and for any square-integrable integrand at most (b/(b-1))**(s-1) = 2 times the variance
    of plain Monte Carlo (Owen 1997, for a (0,m,s)-net in base b = 2, s = 2 dimensions).
  * The index shuffle is another nested uniform scramble, of the index read as a 32-bit binary
    fraction (equivalently Burley's "nested uniform scramble" of the index, which bit-reverses,
    applies a scramble that flips each bit by the bits below it, and reverses back).
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
    points share a tail hash. The hash being a bijection, distinct nodes of one tree never share one.

Limits, beyond the points' own (:mod:`warp_spt.samplers.sobol_points`):
  * Beyond 2**15 samples per pixel, the fine digits (below 2**-15) of points sharing a 15-bit prefix
    share their flips: still unbiased and stratified, slightly less random than Owen's scrambling.
  * Cost: per 2D request 17 hashes (3 for the key, 2 of them per pixel, 2 for the component seeds,
    4 for the index shuffle, 4 per component), several times a PCG draw; benchmarks/bench_sampler.py
    prints both. Seven of a request's fifteen own hashes depend only on (pixel, dimension) below index
    2**15, which is what ``make_batch``'s lanes share the work of.
"""

from __future__ import annotations

import warp as wp

from warp_spt.samplers.sobol_points import Scramble, mix32, points, reverse_bits, sobol_dim1, to_unit

# Python-int spellings of the salts, shared with the numpy reference in the tests.
X_SALT = 0x68E31DA4
Y_SALT = 0xB5297A4D
BLOCK_SALT = 0x27D4EB2F  # differs from X_SALT and Y_SALT above bit 16, so no block key equals theirs
EXACT_LEVELS = wp.constant(15)  # levels with one independent flip per node (3 subtrees)
CHUNK_LEVELS = wp.constant(5)  # levels of the flip tree served by one 32-bit hash (2**5 - 1 = 31 bits)

_X_SALT = wp.constant(wp.uint32(X_SALT))
_Y_SALT = wp.constant(wp.uint32(Y_SALT))
_BLOCK_SALT = wp.constant(wp.uint32(BLOCK_SALT))
_HIGH_17 = wp.constant(wp.uint32(0xFFFF8000))     # index bits above the exactly scrambled 15
_TOP_24 = wp.constant(wp.uint32(0xFFFFFF00))      # a value's bits that reach the float


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


@wp.func
def sample_index(index: int) -> int:
    """The word of the sample index that ``shuffled_index`` reads: the index itself."""
    return index


@wp.func
def owen_x(key: wp.uint32, i: wp.uint32) -> float:
    """Sobol' dimension 0 of index i (its radical inverse), Owen-scrambled."""
    return to_unit(owen_scramble(reverse_bits(i), mix32(key ^ _X_SALT)))


@wp.func
def owen_y(key: wp.uint32, i: wp.uint32) -> float:
    """Sobol' dimension 1 of index i, Owen-scrambled."""
    return to_unit(owen_scramble(sobol_dim1(i), mix32(key ^ _Y_SALT)))


OWEN = Scramble("sobol", "Owen-scrambled Sobol' points, a (0,2)-sequence per pixel",
                sample_index, shuffled_index, owen_x, owen_y)
POINTS = points(OWEN)   # one(seed, pixel, index, dim), two, their *_keyed forms, make_batch


def make():
    """The record of ``SAMPLERS["sobol"]``."""
    return POINTS.sampler()
