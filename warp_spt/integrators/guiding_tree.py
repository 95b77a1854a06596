"""Path guiding's host half: building and refining the SD-tree between training passes (numpy).

The tree's layout is documented in :mod:`warp_spt.core.guiding`. After training pass k (which
rendered max(1, 2**(k-1)) samples per pixel while recording into ``rec``), :func:`refine` turns the
integer sums the pass recorded into

* the *sampling* tree for pass k + 1: ``rec``'s structure with the energies it collected, and
* the *recording* tree for pass k + 1: every quadtree refined where its energy is concentrated
  (a node holding more than ``rho`` of its tree's energy is split, one holding less is merged, as
  deep as ``max_depth``), and every spatial leaf that collected more than ``c * sqrt(2**k)``
  records (over its NORMAL_BINS quadtrees) split in two at the middle of its longest side (both
  halves start from its refined quadtrees), so that leaves keep about the same number of records
  as the passes double.

Everything here is a pure function of its integer inputs, visited in a fixed order: the same
records give the same trees bit for bit. The spatial tree is walked in Python (a handful of nodes);
every quadtree is refined at once, level by level, in numpy (0.01 s for the 30k nodes of a 64x64
render at 64 spp, where the former per-node Python loops took 0.1 s, and 10x faster on large trees).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from warp_spt.core.guiding import ENERGY_SCALE, NORMAL_BINS

SPATIAL_C = 4000          # records a spatial leaf may collect in a 1 spp pass before it splits
RHO = 0.03                # a quadtree node holding more than this fraction of its tree's energy splits (0.01 in
                          # the paper; coarser is cheaper to walk and as good here: indirect 64x64 MSE 6.4e-4 -> 6.2e-4)
MAX_DIR_DEPTH = 12        # quadtree depth limit (float32 sample warping keeps ~24 bits over 12 levels)
MAX_SPATIAL_DEPTH = 24
INITIAL_DIR_DEPTH = 2     # a new quadtree: 16 equal squares


@dataclass
class SDTree:
    """A flattened SD-tree (see :mod:`warp_spt.core.guiding`); ``d_energy`` float64 on the host."""

    lo: np.ndarray
    hi: np.ndarray
    s_axis: np.ndarray
    s_child: np.ndarray
    d_root: np.ndarray
    d_child: np.ndarray
    d_energy: np.ndarray

    @property
    def dir_nodes(self) -> int:
        return int(self.d_child.size)

    @property
    def leaves(self) -> int:
        return int((self.s_axis < 0).sum())


def box_of(bounds: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The root box for a scene's (2, 3) bounds: a little larger, never flat."""
    lo, hi = np.asarray(bounds[0], np.float64), np.asarray(bounds[1], np.float64)
    if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
        lo, hi = -np.ones(3), np.ones(3)
    pad = 0.01 * max(float(np.max(hi - lo)), 1e-3)
    return lo - pad, hi + pad


def _uniform_quadtree(depth: int) -> list[list]:
    """A full quadtree of ``depth`` levels as rows [first child or -1, energy] (children after parents)."""
    rows = [[-1, 0.0]]
    frontier = [0]
    for _ in range(depth):
        nxt = []
        for n in frontier:
            rows[n][0] = len(rows)
            nxt += list(range(len(rows), len(rows) + 4))
            rows += [[-1, 0.0] for _ in range(4)]
        frontier = nxt
    return rows


def initial(bounds: np.ndarray) -> SDTree:
    """The first recording tree: one spatial leaf over the scene with uniform quadtrees."""
    lo, hi = box_of(bounds)
    rows = _uniform_quadtree(INITIAL_DIR_DEPTH)
    n = len(rows)
    child = [r[0] + b * n if r[0] >= 0 else -1 for b in range(NORMAL_BINS) for r in rows]
    return SDTree(lo, hi, np.array([-1], np.int32), np.array([0], np.int32),
                  np.arange(NORMAL_BINS, dtype=np.int32) * n, np.array(child, np.int32), np.zeros(n * NORMAL_BINS))


def _levels(d_child: np.ndarray, roots: np.ndarray) -> list[np.ndarray]:
    """The directional nodes under ``roots``, level by level (the roots first)."""
    levels, frontier = [], np.asarray(roots, np.int64)
    while frontier.size:
        levels.append(frontier)
        c = d_child[frontier]
        c = c[c >= 0].astype(np.int64)
        frontier = (c[:, None] + np.arange(4)).ravel()
    return levels


def summed_energy(tree: SDTree, energy: np.ndarray) -> np.ndarray:
    """Per-node energy of ``tree`` from the fixed-point sums recorded at its leaves: every inner
    node gets the sum of its children, level by level from the deepest."""
    e = energy.astype(np.float64) / ENERGY_SCALE
    for level in reversed(_levels(tree.d_child, tree.d_root)):
        c = tree.d_child[level]
        inner = c >= 0
        n, c = level[inner], c[inner].astype(np.int64)
        e[n] = e[c] + e[c + 1] + e[c + 2] + e[c + 3]
    return e


def _refined_quadtrees(d_child: np.ndarray, e: np.ndarray, roots: np.ndarray, rho: float,
                       max_depth: int) -> tuple[np.ndarray, np.ndarray]:
    """The quadtrees at ``roots`` (old nodes, repeats allowed) refined by their energies ``e``, all at
    once, breadth first: (d_child, d_energy) of the new quadtrees, whose roots are nodes
    0 .. len(roots) - 1 in the order of ``roots``. A node with more than ``rho`` of its quadtree's
    total is split (a former leaf's children estimated at a quarter each), one with less becomes a
    leaf; a quadtree with no energy keeps its structure."""
    old = np.asarray(roots, np.int64)
    energy = e[old]
    total = energy.copy()
    child_out, energy_out = [], []
    count, depth = 0, 0
    while old.size:
        n = old.size
        old_child = np.where(old >= 0, d_child[np.maximum(old, 0)], -1).astype(np.int64)
        split = np.where(total > 0.0, (depth < max_depth) & (energy > rho * total), old_child >= 0)
        first = count + n + 4 * (np.cumsum(split) - 1)          # children: the next level, in order
        child_out.append(np.where(split, first, -1))
        energy_out.append(energy)
        count += n
        oc, en, tot = old_child[split], energy[split], total[split]
        kids = (oc[:, None] + np.arange(4)).ravel()
        has = np.repeat(oc >= 0, 4)
        old = np.where(has, kids, -1)
        energy = np.where(has, e[np.maximum(kids, 0)], np.repeat(en / 4.0, 4))
        total = np.repeat(tot, 4)
        depth += 1
    return np.concatenate(child_out).astype(np.int32), np.concatenate(energy_out)


def refine(rec: SDTree, energy: np.ndarray, hits: np.ndarray, k: int, c: float = SPATIAL_C,
           rho: float = RHO, max_depth: int = MAX_DIR_DEPTH) -> tuple[SDTree, SDTree]:
    """(sampling tree for the next pass, recording tree for the next pass) after training pass
    ``k`` recorded the integer sums ``energy`` and ``hits`` per directional node of ``rec`` (hits
    at the quadtrees' roots). The spatial tree is walked in Python (a few nodes per thousand
    records); the quadtrees are refined together in numpy (:func:`_refined_quadtrees`)."""
    e = summed_energy(rec, energy)
    sampling = SDTree(rec.lo, rec.hi, rec.s_axis, rec.s_child, rec.d_root, rec.d_child, e)
    threshold = c * math.sqrt(2.0 ** k)
    leaf_hits = np.asarray(hits, np.float64)[rec.d_root].reshape(-1, NORMAL_BINS).sum(axis=1).tolist()
    old_axis, old_child = rec.s_axis.tolist(), rec.s_child.tolist()
    extent = (rec.hi - rec.lo).tolist()

    s_axis: list[int] = [-1]
    s_child: list[int] = [-1]
    sources: list[int] = []            # per new spatial leaf: the old leaf whose quadtrees it refines

    # depth first over (slot, old node or -1, box size, depth, old leaf, records); a node's two
    # children take consecutive slots, reserved before either is filled
    todo = [(0, 0, extent, 0, -1, 0.0)]
    while todo:
        slot, old, size, depth, src, count = todo.pop()
        inner = old >= 0 and old_axis[old] >= 0
        if old >= 0 and not inner:
            src = old_child[old]
            count = leaf_hits[src]
        if not (inner or (count > threshold and depth < MAX_SPATIAL_DEPTH)):
            s_child[slot] = len(sources)
            sources.append(src)
            continue
        ax = old_axis[old] if inner else int(np.argmax(size))
        half = list(size)
        half[ax] *= 0.5
        s_axis[slot] = ax
        first = len(s_axis)
        s_axis += [-1, -1]
        s_child += [-1, -1]
        s_child[slot] = first
        for j in (1, 0):               # the stack pops the first child first
            todo.append((first + j, old_child[old] + j if inner else -1, half, depth + 1, src, count / 2.0))
    roots = rec.d_root.reshape(-1, NORMAL_BINS)[np.array(sources, np.int64)].ravel()
    d_child, d_energy = _refined_quadtrees(rec.d_child, e, roots, rho, max_depth)
    nxt = SDTree(rec.lo, rec.hi, np.array(s_axis, np.int32), np.array(s_child, np.int32),
                 np.arange(roots.size, dtype=np.int32), d_child, d_energy)
    return sampling, nxt
