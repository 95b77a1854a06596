"""A numpy reference for warp_spt.samplers.sobol, written from the textbook definitions, not from the kernel.

* Sobol' points: a 32x32 generator matrix over GF(2) per dimension, built from the direction numbers
  m_k of the dimension (dimension 0: m_k = 1; dimension 1: primitive polynomial x + 1, so
  m_k = 2 m_{k-1} xor m_{k-1}, m_1 = 1, Bratley & Fox's recurrence), multiplied with the index bits.
* Owen scrambling: bit by bit, bit l (from the top) xor flip(l, prefix of the l bits above it), where
  flip is the random bit of the flip-tree node (l, prefix), looked up directly from its definition
  (levels < 15: subtree of 5 levels, one hash per subtree root, bit 2**j - 1 + sub-prefix; levels
  15..23: bits of one hash of the 15-bit prefix). The index shuffle likewise, bit by bit.
Only the hash and the seed chain (warp_spt.samplers.sobol_points) and the salts are shared with the
modules: they are their specification.
"""

from __future__ import annotations

import numpy as np

from warp_spt.samplers import sobol as S
from warp_spt.samplers import sobol_points as P

M32 = np.uint64(0xFFFFFFFF)


def mix32(x):
    """lowbias32 on uint32 arrays, computed in uint64 and masked (no reliance on wrap-around)."""
    x = np.asarray(x, dtype=np.uint64) & M32
    x ^= x >> np.uint64(16)
    x = (x * np.uint64(P.LOWBIAS_MUL1)) & M32
    x ^= x >> np.uint64(15)
    x = (x * np.uint64(P.LOWBIAS_MUL2)) & M32
    x ^= x >> np.uint64(16)
    return x


def direction_numbers(dim: int, bits: int = 32) -> list[int]:
    """m_1..m_bits of Sobol' dimension 0 or 1 (odd integers, m_k < 2**k)."""
    if dim == 0:
        return [1] * bits
    m = [1]
    for _ in range(bits - 1):
        m.append((2 * m[-1]) ^ m[-1])
    return m


def generator_matrix(dim: int) -> np.ndarray:
    """C[r, k]: bit r (r = 0 is the most significant, weight 1/2) of direction number v_{k+1}
    = m_{k+1} / 2**(k+1), i.e. of the contribution of index bit k."""
    m = direction_numbers(dim)
    c = np.zeros((32, 32), dtype=np.uint8)
    for k, mk in enumerate(m):
        for r in range(k + 1):                 # m_{k+1} has k+1 binary digits
            c[r, k] = (mk >> (k - r)) & 1
    return c


def sobol_u32(index, dim: int) -> np.ndarray:
    """Unscrambled Sobol' dimension ``dim`` of each index, as 0.32 fractions (uint64 holding uint32)."""
    idx = np.asarray(index, dtype=np.uint64)
    bits = ((idx[..., None] >> np.arange(32, dtype=np.uint64)) & np.uint64(1)).astype(np.int64)
    out_bits = (bits @ generator_matrix(dim).T.astype(np.int64)) & 1      # [..., r]
    weights = np.uint64(1) << (np.uint64(31) - np.arange(32, dtype=np.uint64))
    return (out_bits.astype(np.uint64) * weights).sum(axis=-1, dtype=np.uint64)


def node_flip(seed, level: int, prefix) -> np.ndarray:
    """The random bit of flip-tree node (level, prefix) for level < 15, prefix being the ``level``
    bits above it: subtree of 5 levels, one hash per subtree root, bit 2**j - 1 + sub-prefix."""
    chunk_root = level - level % S.CHUNK_LEVELS
    j = level - chunk_root
    root_prefix = np.asarray(prefix, dtype=np.uint64) >> np.uint64(j)
    sub = np.asarray(prefix, dtype=np.uint64) & np.uint64((1 << j) - 1)
    h = mix32((root_prefix | np.uint64(1 << chunk_root)) ^ np.asarray(seed, dtype=np.uint64))
    return (h >> (np.uint64((1 << j) - 1) + sub)) & np.uint64(1)


def value_flip(seed, level: int, prefix) -> np.ndarray:
    """The flip of level 0..23 of a value scramble: a tree node above level 15, below it bit
    (46 - level) of one hash of the 15-bit prefix with marker 2**15."""
    if level < S.EXACT_LEVELS:
        return node_flip(seed, level, prefix)
    p15 = np.asarray(prefix, dtype=np.uint64) >> np.uint64(level - 15)
    tail = mix32((p15 | np.uint64(1 << 15)) ^ np.asarray(seed, dtype=np.uint64))
    return (tail >> np.uint64(46 - level)) & np.uint64(1)


def owen(v, seed, levels: int = 24) -> np.ndarray:
    """Textbook nested scramble of the top ``levels`` bits of 0.32 fractions v: bit by bit from the
    top, each bit xor the flip of the node its prefix leads to."""
    v = np.asarray(v, dtype=np.uint64)
    out = np.zeros_like(v)
    for level in range(levels):
        shift = np.uint64(31 - level)
        prefix = v >> np.uint64(32 - level) if level else np.zeros_like(v)
        bit = (v >> shift) & np.uint64(1)
        out |= (bit ^ value_flip(seed, level, prefix)) << shift
    return out


def shuffle(index, key) -> np.ndarray:
    """The index shuffle, bit by bit from bit 31 down: bits 31..15 xor the key's same bits; bit b < 15
    xor the node flip of level 14 - b of the tree keyed by the index's block of 2**15."""
    index = np.asarray(index, dtype=np.uint64)
    key = np.asarray(key, dtype=np.uint64)
    block_seed = mix32(key ^ np.uint64(S.BLOCK_SALT) ^ (index >> np.uint64(15)))
    out = np.zeros_like(index)
    for b in range(31, -1, -1):
        bit = (index >> np.uint64(b)) & np.uint64(1)
        if b >= 15:
            flip = (key >> np.uint64(b)) & np.uint64(1)
        else:
            level = 14 - b
            low_prefix = (index >> np.uint64(b + 1)) & np.uint64((1 << level) - 1)
            flip = node_flip(block_seed, level, low_prefix)
        out |= (bit ^ flip) << np.uint64(b)
    return out


def request_seed(seed, pixel, dim) -> np.ndarray:
    h = mix32(np.asarray(seed, dtype=np.uint64) ^ np.uint64(P.SEED_SALT))
    h = mix32(h ^ (np.asarray(pixel, dtype=np.uint64) & M32))
    return mix32(h ^ ((np.asarray(dim, dtype=np.uint64) * np.uint64(P.DIM_MUL)) & M32))


def to_unit(v) -> np.ndarray:
    return ((np.asarray(v, dtype=np.uint64) >> np.uint64(8)).astype(np.float64) / 2.0**24).astype(np.float32)


def _request(seed, pixel, index, dim):
    seed, pixel, index, dim = np.broadcast_arrays(seed, pixel, index, dim)
    key = request_seed(seed, pixel, dim)
    return key, shuffle(index, key)


def sobol_2d(seed, pixel, index, dim) -> np.ndarray:
    """[..., 2] float32 points, as warp_spt.samplers.sobol.POINTS.two for broadcast (seed, pixel, index, dim)."""
    key, i = _request(seed, pixel, index, dim)
    x = owen(sobol_u32(i, 0), mix32(key ^ np.uint64(S.X_SALT)))
    y = owen(sobol_u32(i, 1), mix32(key ^ np.uint64(S.Y_SALT)))
    return np.stack([to_unit(x), to_unit(y)], axis=-1)


def sobol_1d(seed, pixel, index, dim) -> np.ndarray:
    """Float32 values, as warp_spt.samplers.sobol.POINTS.one: the scrambled van der Corput dimension alone."""
    key, i = _request(seed, pixel, index, dim)
    return to_unit(owen(sobol_u32(i, 0), mix32(key ^ np.uint64(S.X_SALT))))
