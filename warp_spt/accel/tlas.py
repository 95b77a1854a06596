"""Top-level BVH over world-space boxes (OBJ bounds and spheres), built in numpy with binned SAH.

The build works one tree *level* at a time: every node of a level that must be split is processed
by the same handful of vectorised numpy calls (segmented reductions over the item permutation), so
the Python overhead grows with the tree depth, not with the number of nodes. The result is
flattened into depth-first arrays (root = node 0) that the kernel traverses with a fixed stack.

Guarantees the kernel relies on:

* every item sits in exactly one leaf, and a leaf holds 1..``max_leaf`` items;
* node boxes are float32, rounded outward from the float64 bounds, so they contain their items
  exactly (a flat, zero-thickness box stays flat but is kept: the kernel's slab test is inclusive);
* the depth stays below 57 (the kernel's stack has 64 entries): a node switches to median splits
  as soon as halving is the only way left to finish within that budget.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

NUM_BINS = 16
# Deepest leaf allowed; median splits take over near it (see _must_halve). Stack is 64 entries.
DEPTH_BUDGET = 56
# A node with more than max_leaf items is always split (no SAH leaf-versus-split test): the leaf
# size bound is what the kernel's fixed-size leaf loop relies on; SAH only chooses the plane.


@dataclass
class Tlas:
    """A flattened BVH in depth-first order (root = node 0). See the module docstring."""

    lower: np.ndarray   # (N, 3) float32 node box, rounded outward
    upper: np.ndarray   # (N, 3) float32
    left: np.ndarray    # (N,) int32: interior -> left child; leaf -> -1
    right: np.ndarray   # (N,) int32: interior -> right child; leaf -> -1
    first: np.ndarray   # (N,) int32: leaf -> first position in items; interior -> -1
    count: np.ndarray   # (N,) int32: leaf -> number of items; interior -> 0
    items: np.ndarray   # (K,) int32 item ids, contiguous per leaf
    depth: int          # max depth, root = 0

    @property
    def num_nodes(self) -> int:
        return int(len(self.left))


def _validate_boxes(lowers: np.ndarray, uppers: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    lo = np.asarray(lowers, dtype=np.float64)
    hi = np.asarray(uppers, dtype=np.float64)
    if lo.ndim != 2 or lo.shape[1:] != (3,) or lo.shape != hi.shape:
        raise ValueError(f"build_tlas: lowers and uppers must both be (K, 3), got {lo.shape} and {hi.shape}")
    limit = float(np.finfo(np.float32).max)
    if not (np.isfinite(lo).all() and np.isfinite(hi).all()) or max(-lo.min(initial=0), hi.max(initial=0)) > limit:
        raise ValueError(f"build_tlas: item boxes must be finite and within float32 range (|x| <= {limit:.4g})")
    bad = np.flatnonzero((lo > hi).any(axis=1))
    if len(bad):
        raise ValueError(f"build_tlas: item {int(bad[0])} has lower > upper ({lo[bad[0]]} > {hi[bad[0]]})")
    return lo, hi


def _halving_depth(n: np.ndarray, max_leaf: int) -> np.ndarray:
    """Levels that repeated halving needs to bring ``n`` items down to leaves of <= max_leaf."""
    leaves = -(-n // max_leaf)
    return np.ceil(np.log2(np.maximum(leaves, 1))).astype(np.int64)


def _must_halve(depth: np.ndarray, n: np.ndarray, max_leaf: int) -> np.ndarray:
    """True where SAH may no longer choose: halving from here just reaches DEPTH_BUDGET.

    Once true at a node it stays true for its children (depth +1, halving depth -1), and an SAH
    split never increases the halving depth, so leaves end at depth <= DEPTH_BUDGET.
    """
    return depth + _halving_depth(n, max_leaf) >= DEPTH_BUDGET


def _box_area(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Half surface area of boxes (..., 3); empty boxes (lo > hi, e.g. +inf/-inf) give 0."""
    d = np.maximum(hi - lo, 0.0)
    return d[..., 0] * d[..., 1] + d[..., 1] * d[..., 2] + d[..., 2] * d[..., 0]


def _segment_ids(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For packed segments of the given sizes: the segment of every element and each segment's offset."""
    offsets = np.zeros(len(counts), dtype=np.int64)
    np.cumsum(counts[:-1], out=offsets[1:])
    seg = np.repeat(np.arange(len(counts)), counts)
    return seg, offsets


def _binned_sah(seg, bins, lo, hi, num_seg):
    """Best SAH split per segment over NUM_BINS centroid bins on all three axes.

    Returns (axis, last_left_bin, cost) per segment; cost is inf where no bin boundary separates
    the items (all centroids in one bin on every axis).
    """
    nb = NUM_BINS
    best_cost = np.full(num_seg, np.inf)
    best_axis = np.zeros(num_seg, dtype=np.int64)
    best_bin = np.zeros(num_seg, dtype=np.int64)
    for axis in range(3):
        key = seg * nb + bins[:, axis]
        cnt = np.bincount(key, minlength=num_seg * nb).reshape(num_seg, nb)
        # per-bin boxes; ufunc.at on flat 1-D views is several times faster than on (n, 3)
        flat_key = (key[:, None] * 3 + np.arange(3)).ravel()
        blo = np.full(num_seg * nb * 3, np.inf)
        bhi = np.full(num_seg * nb * 3, -np.inf)
        np.minimum.at(blo, flat_key, lo.ravel())
        np.maximum.at(bhi, flat_key, hi.ravel())
        blo = blo.reshape(num_seg, nb, 3)
        bhi = bhi.reshape(num_seg, nb, 3)
        # left side = bins 0..b, right side = bins b+1..nb-1, for b in 0..nb-2
        n_left = np.cumsum(cnt, axis=1)[:, :-1]
        n_right = cnt.sum(axis=1, keepdims=True) - n_left
        a_left = _box_area(np.minimum.accumulate(blo, axis=1), np.maximum.accumulate(bhi, axis=1))[:, :-1]
        rlo = np.minimum.accumulate(blo[:, ::-1], axis=1)[:, ::-1]
        rhi = np.maximum.accumulate(bhi[:, ::-1], axis=1)[:, ::-1]
        a_right = _box_area(rlo, rhi)[:, 1:]
        cost = a_left * n_left + a_right * n_right
        cost[(n_left == 0) | (n_right == 0)] = np.inf
        b = np.argmin(cost, axis=1)
        c = cost[np.arange(num_seg), b]
        better = c < best_cost
        best_cost[better] = c[better]
        best_axis[better] = axis
        best_bin[better] = b[better]
    return best_axis, best_bin, best_cost


def _split_level(order, starts, counts, depths, centroid, lo, hi, max_leaf):
    """Split every given segment of ``order`` in place; return the left-child sizes."""
    num_seg = len(starts)
    seg, offsets = _segment_ids(counts)
    pos = starts[seg] + (np.arange(len(seg)) - offsets[seg])
    ids = order[pos]
    c = centroid[ids]
    cmin = np.minimum.reduceat(c, offsets, axis=0)
    cmax = np.maximum.reduceat(c, offsets, axis=0)
    extent = cmax - cmin
    scale = np.divide(NUM_BINS, extent, out=np.zeros_like(extent), where=extent > 0)
    bins = np.clip(((c - cmin[seg]) * scale[seg]).astype(np.int64), 0, NUM_BINS - 1)

    axis, last_bin, cost = _binned_sah(seg, bins, lo[ids], hi[ids], num_seg)
    median = ~np.isfinite(cost) | _must_halve(depths, counts, max_leaf)
    # Median segments: sort by centroid on the longest centroid axis (stable, so coincident
    # centroids keep their order) and put the first half left.
    long_axis = np.argmax(extent, axis=1)
    value = np.where(median[seg], c[np.arange(len(seg)), long_axis[seg]], 0.0)
    perm = np.lexsort((value, seg))
    ids, bins = ids[perm], bins[perm]
    rank = np.arange(len(seg)) - offsets[seg]
    go_right = np.where(median[seg], rank >= counts[seg] // 2, bins[np.arange(len(seg)), axis[seg]] > last_bin[seg])
    perm = np.argsort(seg * 2 + go_right, kind="stable")
    order[pos] = ids[perm]
    return counts - np.bincount(seg, weights=go_right, minlength=num_seg).astype(np.int64)


def _build_levels(lo, hi, max_leaf):
    """Breadth-first build. Returns (order, start, count, depth, left, right) with BFS node ids."""
    k = len(lo)
    centroid = 0.5 * (lo + hi)
    order = np.arange(k, dtype=np.int64)
    start, count, depth = [np.array([0])], [np.array([k])], [np.array([0])]
    left, right = [], []
    num_nodes = 1
    while True:
        s, n, d = start[-1], count[-1], depth[-1]
        split = n > max_leaf
        child_ids = np.full(len(n), -1, dtype=np.int64)
        num_split = int(split.sum())
        child_ids[split] = num_nodes + 2 * np.arange(num_split)
        left.append(child_ids)
        right.append(np.where(split, child_ids + 1, -1))
        if num_split == 0:
            break
        n_left = _split_level(order, s[split], n[split], d[split], centroid, lo, hi, max_leaf)
        cs = np.stack([s[split], s[split] + n_left], axis=1).ravel()
        cn = np.stack([n_left, n[split] - n_left], axis=1).ravel()
        start.append(cs)
        count.append(cn)
        depth.append(np.full(len(cs), int(d[0]) + 1))
        num_nodes += len(cs)
    cat = np.concatenate
    return order, cat(start), cat(count), cat(depth), cat(left), cat(right)


def _dfs_positions(left: np.ndarray, right: np.ndarray, depth: np.ndarray) -> np.ndarray:
    """Pre-order position of every BFS node, computed level by level without recursion."""
    n = len(left)
    size = np.ones(n, dtype=np.int64)
    interior = left >= 0
    for d in range(int(depth.max()), -1, -1):            # subtree sizes, bottom-up
        at = np.flatnonzero((depth == d) & interior)
        size[at] = 1 + size[left[at]] + size[right[at]]
    pos = np.zeros(n, dtype=np.int64)
    for d in range(int(depth.max()) + 1):                  # positions, top-down
        at = np.flatnonzero((depth == d) & interior)
        pos[left[at]] = pos[at] + 1
        pos[right[at]] = pos[at] + 1 + size[left[at]]
    return pos


def _node_bounds(order, start, left, right, depth, lo, hi):
    """float64 bounds of every node: leaves by segmented reduction, interiors bottom-up."""
    n = len(left)
    nlo = np.empty((n, 3))
    nhi = np.empty((n, 3))
    leaves = np.flatnonzero(left < 0)
    leaves = leaves[np.argsort(start[leaves])]             # leaves tile [0, K) in order
    nlo[leaves] = np.minimum.reduceat(lo[order], start[leaves], axis=0)
    nhi[leaves] = np.maximum.reduceat(hi[order], start[leaves], axis=0)
    for d in range(int(depth.max()), -1, -1):
        at = np.flatnonzero((depth == d) & (left >= 0))
        nlo[at] = np.minimum(nlo[left[at]], nlo[right[at]])
        nhi[at] = np.maximum(nhi[left[at]], nhi[right[at]])
    return nlo, nhi


def round_outward(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """float32 boxes containing the float64 boxes: the largest float32 <= lo, smallest >= hi."""
    lo32 = lo.astype(np.float32)
    hi32 = hi.astype(np.float32)
    lo32 = np.where(lo32 > lo, np.nextafter(lo32, np.float32(-np.inf)), lo32)
    hi32 = np.where(hi32 < hi, np.nextafter(hi32, np.float32(np.inf)), hi32)
    return lo32.astype(np.float32), hi32.astype(np.float32)


def build_tlas(lowers: np.ndarray, uppers: np.ndarray, max_leaf: int = 2) -> Tlas:
    """Build a binned-SAH BVH over K boxes ``lowers``/``uppers`` (K, 3); K == 0 gives one empty leaf.

    Raises ValueError for mismatched shapes, non-finite or inverted boxes, max_leaf < 1.
    """
    if max_leaf < 1:
        raise ValueError(f"build_tlas: max_leaf must be >= 1, got {max_leaf}")
    lo, hi = _validate_boxes(lowers, uppers)
    if len(lo) == 0:            # an empty scene (an animation's frame that hides everything): one leaf
        return _empty_tlas()    # of no items whose box no ray enters
    order, start, count, depth, left, right = _build_levels(lo, hi, max_leaf)
    nlo, nhi = _node_bounds(order, start, left, right, depth, lo, hi)
    pos = _dfs_positions(left, right, depth)
    n = len(left)
    inv = np.empty(n, dtype=np.int64)
    inv[pos] = np.arange(n)                                  # inv[dfs index] = bfs index
    is_leaf = left[inv] < 0
    lo32, hi32 = round_outward(nlo[inv], nhi[inv])
    return Tlas(
        lower=lo32,
        upper=hi32,
        left=np.where(is_leaf, -1, pos[left[inv]]).astype(np.int32),
        right=np.where(is_leaf, -1, pos[right[inv]]).astype(np.int32),
        first=np.where(is_leaf, start[inv], -1).astype(np.int32),
        count=np.where(is_leaf, count[inv], 0).astype(np.int32),
        items=order.astype(np.int32),
        depth=int(depth.max()),
    )


def _empty_tlas() -> Tlas:
    big = np.float32(np.finfo(np.float32).max)
    none = np.full((1,), -1, np.int32)
    return Tlas(lower=np.full((1, 3), big, np.float32), upper=np.full((1, 3), -big, np.float32), left=none,
                right=none.copy(), first=np.zeros(1, np.int32), count=np.zeros(1, np.int32),
                items=np.zeros(0, np.int32), depth=0)


def ray_box_overlap(lo, hi, origin, direction, t_max: float) -> np.ndarray:
    """Inclusive float64 slab test of boxes (..., 3) against the ray segment t in [0, t_max].

    A zero direction component is handled explicitly (the origin must lie within that slab), so
    no 0 * inf NaNs arise; flat boxes are hit because the comparison is ``t_near <= t_far``.
    """
    lo = np.asarray(lo, dtype=np.float64)
    hi = np.asarray(hi, dtype=np.float64)
    o = np.asarray(origin, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    t_near = np.zeros(lo.shape[:-1])
    t_far = np.full(lo.shape[:-1], float(t_max))
    for a in range(3):
        if d[a] == 0.0:
            inside = (lo[..., a] <= o[a]) & (o[a] <= hi[..., a])
            t_far = np.where(inside, t_far, -np.inf)
            continue
        t0 = (lo[..., a] - o[a]) / d[a]
        t1 = (hi[..., a] - o[a]) / d[a]
        t_near = np.maximum(t_near, np.minimum(t0, t1))
        t_far = np.minimum(t_far, np.maximum(t0, t1))
    return t_near <= t_far


def ray_query_reference(tlas: Tlas, origin, direction, t_max: float) -> list[int]:
    """Items of every leaf whose (float32) box the ray reaches, by an explicit-stack traversal.

    Pure numpy/Python, for tests: what the kernel's traversal must at least visit.
    """
    found: list[int] = []
    stack = [0]
    while stack:
        node = stack.pop()
        if not ray_box_overlap(tlas.lower[node], tlas.upper[node], origin, direction, t_max):
            continue
        if tlas.left[node] < 0:
            f = int(tlas.first[node])
            found.extend(int(i) for i in tlas.items[f:f + int(tlas.count[node])])
        else:
            stack.append(int(tlas.right[node]))
            stack.append(int(tlas.left[node]))
    return found
