"""Path guiding's host half: building and refining the SD-tree between training passes (numpy).

The tree's layout is documented in :mod:`warp_spt.core.guiding`. After training pass k (which
rendered 2**k samples per pixel while recording into the tree ``rec``), :func:`refine` turns the
integer sums the pass recorded into

* the *sampling* tree for pass k + 1: ``rec``'s structure with the energies it collected, and
* the *recording* tree for pass k + 1: every quadtree refined where its energy is concentrated
  (a node holding more than ``rho`` of its tree's energy is split, one holding less is merged, as
  deep as ``max_depth``), and every spatial leaf that collected more than ``c * sqrt(2**k)``
  records (over its NORMAL_BINS quadtrees) split in two at the middle of its longest side (both
  halves start from its refined quadtrees), so that leaves keep about the same number of records
  as the passes double.

Everything here is a pure function of its integer inputs, visited in a fixed order: the same
records give the same trees bit for bit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from warp_spt.core.guiding import ENERGY_SCALE, NORMAL_BINS

SPATIAL_C = 4000          # records a spatial leaf may collect in a 1 spp pass before it splits
RHO = 0.01                # a quadtree node holding more than this fraction of its tree's energy splits
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


def summed_energy(tree: SDTree, energy: np.ndarray) -> np.ndarray:
    """Per-node energy of ``tree`` from the fixed-point sums recorded at its leaves: every inner
    node gets the sum of its children (children always come after their parent)."""
    e = (energy.astype(np.float64) / ENERGY_SCALE).tolist()
    child = tree.d_child.tolist()
    for n in range(tree.dir_nodes - 1, -1, -1):
        c = child[n]
        if c >= 0:
            e[n] = e[c] + e[c + 1] + e[c + 2] + e[c + 3]
    return np.array(e)


def _quadtree_nodes(child: list, root: int) -> list[int]:
    """The nodes of the quadtree at ``root`` (root first); ``child``: ``d_child`` as a list."""
    out, todo = [], [root]
    while todo:
        n = todo.pop()
        out.append(n)
        c = child[n]
        if c >= 0:
            todo += [c, c + 1, c + 2, c + 3]
    return out


def _refined_quadtree(child: list, root: int, e: list, rho: float, max_depth: int) -> list[list]:
    """The quadtree at ``root`` refined by its energies ``e``: rows [first child or -1, energy estimate]
    in breadth-first order. A node with more than ``rho`` of the total is split (a former leaf's
    children estimated at a quarter each), one with less becomes a leaf. No energy: kept as it is.
    (``child`` and ``e``: the tree's arrays as lists, which Python indexes fast.)"""
    total = e[root]
    rows: list[list] = []
    queue = [(root, total, 0)]         # (old node or -1, energy estimate, depth)
    head = 0
    while head < len(queue):
        old, energy, depth = queue[head]
        head += 1
        rows.append([-1, energy])
        old_child = child[old] if old >= 0 else -1
        if total > 0.0:
            split = depth < max_depth and energy > rho * total
        else:
            split = old_child >= 0         # nothing learnt: keep the structure
        if split:
            rows[-1][0] = len(queue)       # breadth first: children are queued consecutively
            if old_child >= 0:
                queue += [(old_child + k, e[old_child + k], depth + 1) for k in range(4)]
            else:
                queue += [(-1, energy / 4.0, depth + 1) for _ in range(4)]
    return rows


def refine(rec: SDTree, energy: np.ndarray, hits: np.ndarray, k: int, c: float = SPATIAL_C,
           rho: float = RHO, max_depth: int = MAX_DIR_DEPTH) -> tuple[SDTree, SDTree]:
    """(sampling tree for the next pass, recording tree for the next pass) after training pass
    ``k`` recorded the integer sums ``energy`` and ``hits`` per directional node of ``rec``."""
    e = summed_energy(rec, energy)
    sampling = SDTree(rec.lo, rec.hi, rec.s_axis, rec.s_child, rec.d_root, rec.d_child, e)
    child, e_list, hit_list = rec.d_child.tolist(), e.tolist(), hits.tolist()
    threshold = c * math.sqrt(2.0 ** k)

    s_axis: list[int] = []
    s_child: list[int] = []
    d_root: list[int] = []
    d_rows: list[list] = []

    def add_quadtree(rows: list[list]) -> int:
        base = len(d_rows)
        d_rows.extend([[r[0] + base if r[0] >= 0 else -1, r[1]] for r in rows])
        return base

    def emit(slot: int, old: int, lo: np.ndarray, hi: np.ndarray, depth: int, quads, count: float) -> None:
        """Fill the reserved spatial node ``slot`` from node ``old`` of ``rec`` (or, old -1, from half
        of a split leaf: its quadtrees ``quads`` and about ``count`` records) and its subtree, depth
        first; a node's two children take consecutive slots, reserved before either is filled."""
        inner = old >= 0 and rec.s_axis[old] >= 0
        if old >= 0 and not inner:
            roots = rec.d_root[NORMAL_BINS * int(rec.s_child[old]):][:NORMAL_BINS]
            quads = [_refined_quadtree(child, int(r), e_list, rho, max_depth) for r in roots]
            count = float(sum(hit_list[n] for r in roots for n in _quadtree_nodes(child, int(r))))
        split = inner or (count > threshold and depth < MAX_SPATIAL_DEPTH)
        if not split:
            s_child[slot] = len(d_root) // NORMAL_BINS
            d_root.extend(add_quadtree(q) for q in quads)
            return
        ax = int(rec.s_axis[old]) if inner else int(np.argmax(hi - lo))
        mid = 0.5 * (lo[ax] + hi[ax])
        hi_a, lo_b = hi.copy(), lo.copy()
        hi_a[ax], lo_b[ax] = mid, mid
        s_axis[slot] = ax
        first = len(s_axis)
        s_axis.extend([-1, -1])
        s_child.extend([-1, -1])
        s_child[slot] = first
        for j, (clo, chi) in enumerate(((lo, hi_a), (lo_b, hi))):
            src = int(rec.s_child[old]) + j if inner else -1
            emit(first + j, src, clo, chi, depth + 1, quads, count / 2.0)

    s_axis.append(-1)
    s_child.append(-1)
    emit(0, 0, rec.lo.copy(), rec.hi.copy(), 0, None, 0.0)
    nxt = SDTree(rec.lo, rec.hi, np.array(s_axis, np.int32), np.array(s_child, np.int32),
                 np.array(d_root, np.int32), np.array([r[0] for r in d_rows], np.int32), np.array([r[1] for r in d_rows], np.float64))
    return sampling, nxt
