"""Wide (8-ary) BVH over triangles, built on the host, for the kernels' own traversal (accel.wide_traversal).

The default build is ``accel/wide_build.py``'s two compiled Warp kernels; this module holds the
tree's type, the input checks, the triangle boxes, and the numpy build described below, kept as
``build_wide(..., builder="numpy")``: the second opinion the tests compare the kernels against.

Why not ``warp_spt.accel.tlas.build_tlas`` + a collapse loop (the prototype): build_tlas
re-partitions every item on every level (a lexsort and an argsort per level), and collapsing its
binary tree node by node in Python costs as much again. This module builds the same kind of tree
(binned SAH, then "open the largest child" collapse) with whole-array numpy calls only: Python
loops run over tree *levels* and the W - 1 collapse steps, never over nodes or triangles.

How:

1. **Binned SAH, one level at a time, items never moved.** Each triangle carries the id of the
   node it is in. Per level, every range (node) to split bins its triangles' centroids along its
   longest centroid axis (and along all three axes when it holds more than ``ALL_AXES_ABOVE``
   triangles), all ranges at once: bin counts by ``bincount``, bin boxes by ``ufunc.at`` scatters
   (fast in numpy 2), and the SAH sweep over bin boundaries by segmented prefix / suffix scans
   (see ``_segmented_scan``). Triangles then just take their child's id: no partition, no sort.
   Ties (e.g. thousands of coincident triangles, where every cut costs the same) go to the most
   balanced cut; where no bin boundary separates a range (all centroids equal) it is halved.
   A range of more than ``max_leaf`` triangles is always split: the traversal's leaf loop is
   fixed-size. Ranges of at most ``SMALL_RANGE`` triangles are halved in centroid order (whole
   leaves on the left), which costs a few operations per triangle instead of a binning pass.
2. **Depth-first leaf order.** Each node's first position follows from its parent's and its left
   sibling's sizes, so one argsort of the triangles by their leaf's position gives ``order``.
3. **Exact boxes.** Triangle boxes are the float64 vertex bounds rounded outward to float32; leaf
   boxes are one ``reduceat`` over them and interior boxes are merged bottom-up per level, so every
   float32 box contains its triangles exactly (a flat box stays flat: slab tests are inclusive).
4. **Vectorised collapse.** Every wide node starts from one binary node and, W - 1 times, opens
   its child of largest surface area (ties: most triangles), for all wide nodes of a level at
   once. Wide nodes are numbered breadth first (root = 0); a node's filled slots come first.

Depth is kept in check as build_tlas does: once a range could only just finish within
``DEPTH_BUDGET`` binary levels by halving, it is halved instead of SAH-cut. The wide depth is at
most the binary depth, so ``stack_bound`` <= 1 + DEPTH_BUDGET * (W - 1) in the worst case; the
actual bound is computed exactly for each tree (see WideBvh) and is what a traversal must size
its stack by.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_spt.device.layout import WIDTH

# Tuned on the built-in demo by the SAH cost of bench_wide_build.py (prototype tree: 7.51):
# 16 bins on 3 axes at every level 7.51; 8 bins 7.52; 3 axes only above 64 triangles 7.53 (and
# ~40% less build time); halving ranges of <= 4 in centroid order 7.55, of <= 8: 7.87, <= 32: 8.27.
# SAH along a Morton order instead of bins (an earlier version of this module): 8.2, and 10-30%
# slower traversal.
NUM_BINS = 8                # SAH bins per range and axis
SMALL_BINS = 2              # ... but at most this many per triangle of the range
ALL_AXES_ABOVE = 64         # ranges of more triangles bin all three axes, others the longest
SMALL_RANGE = 4             # ranges of at most this many triangles are halved in centroid order
# Deepest binary leaf allowed (the wide tree is at most this deep too). Median cuts take over near it.
DEPTH_BUDGET = 48
MAX_TRIANGLES = (2**31 - 1) // 8 - 1   # a leaf is encoded as -(first * 8 + count) - 1 in int32


@dataclass
class WideBvh:
    """A W-wide BVH over triangles (root = node 0, nodes in breadth-first order).

    box: (M, 6, W) float32. Node i's child slot j: [i, 0..2, j] lower x, y, z, [i, 3..5, j] upper
        x, y, z, rounded outward from float64 so they contain their triangles exactly. An empty
        slot has lower = +inf and upper = -inf: any slab test rejects it, whatever the ray's t_max.
    child: (M, W) int32. >= 0: an interior node's index; < 0: a leaf, -(first * 8 + count) - 1,
        whose triangles are order[first:first + count] (1 <= count <= max_leaf <= 7); empty slot: 0.
        Empty slots come after the filled ones.
    order: (K,) int32 triangle ids in leaf order, every triangle exactly once.
    depth: levels of wide nodes (a root alone = 1).
    stack_bound: the most entries a stack traversal that pops one node and pushes its (hit)
        children can hold: max over nodes X of [sum over X's proper ancestors A of (children(A) - 1)]
        + children(X), where children() counts non-empty slots (leaves included, since the
        traversal pushes leaves too). It is at most 1 + depth * (W - 1): each level on the way down
        leaves at most W - 1 siblings behind, and the deepest node pushes at most W.
    """

    box: np.ndarray
    child: np.ndarray
    order: np.ndarray
    depth: int
    stack_bound: int

    @property
    def num_nodes(self) -> int:
        return int(self.child.shape[0])

    @property
    def width(self) -> int:
        return int(self.child.shape[1])

    def child_shifted(self, nodes: int, triangles: int) -> np.ndarray:
        """``child`` for this tree stored after ``nodes`` nodes and ``triangles`` leaf-order triangles
        of other trees (one concatenated array for every mesh of a scene): interior children move by
        ``nodes``, leaves by ``triangles``, in the same leaf encoding (int32)."""
        # -(first * 8 + count) - 1 moved by ``triangles`` is the code minus 8 * triangles; in int32 (no
        # int64 copies of a large tree) while the last leaf's code fits, as build_wide's limit keeps it
        if 8 * (triangles + len(self.order)) > 2**31 - 8 or nodes + len(self.child) > 2**31 - 1:
            raise ValueError(f"wide BVHs of more than {MAX_TRIANGLES} triangles in all do not fit the int32 "
                             "leaf code")
        shifted = self.child.astype(np.int32, copy=True)
        leaf = shifted < 0
        shifted[leaf] -= np.int32(8 * triangles)
        shifted[~leaf] += np.int32(nodes)
        return shifted


# --------------------------------------------------------------------------------------------
# Input and triangle boxes


def _validate(points, tris, width: int, max_leaf: int) -> tuple[np.ndarray, np.ndarray]:
    if not (isinstance(width, (int, np.integer)) and 2 <= width <= 64):
        raise ValueError(f"build_wide: width must be an int in [2, 64], got {width!r}")
    if not (isinstance(max_leaf, (int, np.integer)) and 1 <= max_leaf <= 7):
        raise ValueError(f"build_wide: max_leaf must be an int in [1, 7] (3 bits of a leaf's code), got {max_leaf!r}")
    p = np.asarray(points)
    t = np.asarray(tris)
    if p.ndim != 2 or p.shape[1] != 3 or p.dtype.kind != "f":
        raise ValueError(f"build_wide: points must be an (N, 3) float array, got shape {p.shape} dtype {p.dtype}")
    if t.ndim != 2 or t.shape[1] != 3 or t.dtype.kind not in "iu":
        raise ValueError(f"build_wide: tris must be a (K, 3) integer array, got shape {t.shape} dtype {t.dtype}")
    if len(t) == 0:
        raise ValueError("build_wide: no triangles (K == 0)")
    if len(t) > MAX_TRIANGLES:
        raise ValueError(f"build_wide: {len(t)} triangles; at most {MAX_TRIANGLES} fit the int32 leaf code")
    if t.min() < 0 or t.max() >= len(p):
        raise ValueError(f"build_wide: triangle indices must be in [0, {len(p)}), got [{t.min()}, {t.max()}]")
    if p.dtype != np.float32:         # float32 is exact as it is: no float64 copy of a large mesh
        p = p.astype(np.float64, copy=False)
    used = np.zeros(len(p), dtype=bool)
    used[t.reshape(-1)] = True
    u = p if used.all() else p[used]
    limit = float(np.finfo(np.float32).max)
    if not np.isfinite(u).all() or np.abs(u).max() > limit:
        raise ValueError(f"build_wide: the triangles' vertices must be finite and within float32 range (|x| <= {limit:.4g})")
    return p, t


def _round_outward(lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """float32 boxes containing the float64 boxes: the largest float32 <= lo, the smallest >= hi."""
    lo32 = lo.astype(np.float32)
    hi32 = hi.astype(np.float32)
    down = lo32 > lo
    up = hi32 < hi
    if down.any():
        lo32[down] = np.nextafter(lo32[down], np.float32(-np.inf))
    if up.any():
        hi32[up] = np.nextafter(hi32[up], np.float32(np.inf))
    return lo32, hi32


def _triangle_boxes(p: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(K, 3) float32 lower/upper of each triangle, exact (outward-rounded) bounds of its float64 vertices
    (float32 vertices need no rounding)."""
    # np.take along axis 0 gathers rows 2-3x faster than fancy indexing (p[t[:, 0]])
    a, b, c = (np.take(p, t[:, j], axis=0) for j in range(3))
    lo = np.minimum(np.minimum(a, b, out=a), c, out=a)
    hi = np.maximum(np.maximum(b, c, out=b), np.take(p, t[:, 0], axis=0), out=b)
    if p.dtype == np.float32:         # float32 vertices: their bounds are exact already
        return lo, hi
    return _round_outward(lo, hi)


# --------------------------------------------------------------------------------------------
# Binary tree: binned SAH, one level at a time, items never moved


def _segmented_scan(x: np.ndarray, seg: np.ndarray, op: np.ufunc, reverse: bool) -> np.ndarray:
    """Running ``op`` (np.minimum or np.maximum) of x (M, 3), restarted at every segment.

    numpy has no segmented scan, but a plain one does the job if each segment is lifted past the
    previous ones: finite x lies in [0, 1], so with a shift of 2 * seg the values of a later
    segment all lie beyond the earlier ones in the scan's direction and the running min/max never
    looks back across a boundary (+-inf, empty bins, pass through unchanged). The shift costs ~21
    of float64's 52 bits (up to 2^20 segments): the results are approximate to ~2^-31 of the scene
    size, plenty for SAH costs (node boxes are computed exactly elsewhere).
    """
    sign = -1.0 if (op is np.minimum) != reverse else 1.0
    shift = (sign * 2.0) * seg[:, None]
    y = x + shift
    if reverse:
        out = op.accumulate(y[::-1], axis=0)[::-1]
    else:
        out = op.accumulate(y, axis=0)
    out -= shift
    return out


def _half_area(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    d = np.maximum(hi - lo, 0.0)
    return d[:, 0] * d[:, 1] + d[:, 1] * d[:, 2] + d[:, 2] * d[:, 0]


def _segment_argmin(value: np.ndarray, offsets: np.ndarray, seg: np.ndarray) -> np.ndarray:
    """Index (into value) of the first minimum of every segment (segments contiguous, non-empty)."""
    m = np.minimum.reduceat(value, offsets)
    hit = np.flatnonzero(value <= m[seg])
    first = np.ones(len(hit), dtype=bool)
    first[1:] = seg[hit[1:]] != seg[hit[:-1]]
    return hit[first]


def _scatter_min_max(num: int, key: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(num, 3) min of lo and max of hi over the rows with each key (empty: +inf / -inf).
    ufunc.at on flat 1-D views is several times faster than on (n, 3)."""
    flat = (key[:, None] * 3 + np.arange(3)).ravel()
    out_lo = np.full(num * 3, np.inf)
    out_hi = np.full(num * 3, -np.inf)
    np.minimum.at(out_lo, flat, lo.ravel())
    np.maximum.at(out_hi, flat, hi.ravel())
    return out_lo.reshape(num, 3), out_hi.reshape(num, 3)


def _sah_along(g, n, axis, cmin, ext, c, lo, hi):
    """Binned SAH of every range along its ``axis``: (bins of the items, best last-left bin, its cost)."""
    num = len(n)
    b = np.minimum(NUM_BINS, np.maximum(SMALL_BINS * n, 2))     # bins per range
    off = np.zeros(num, dtype=np.int64)
    np.cumsum(b[:-1], out=off[1:])
    total = int(off[-1] + b[-1])
    e = ext[np.arange(num), axis]
    scale = np.divide(b, e, out=np.zeros(num), where=e > 0)
    ax = axis[g]
    ca = c[np.arange(len(g)), ax]
    bins = np.minimum(((ca - cmin[g, ax]) * scale[g]).astype(np.int64), b[g] - 1)
    key = off[g] + bins
    cnt = np.bincount(key, minlength=total)
    blo, bhi = _scatter_min_max(total, key, lo, hi)
    # cut after bin i of a range: left = bins 0..i, right = bins i+1..b-1
    bg = np.repeat(np.arange(num), b)
    llo = _segmented_scan(blo, bg, np.minimum, False)
    lhi = _segmented_scan(bhi, bg, np.maximum, False)
    rlo = _segmented_scan(blo, bg, np.minimum, True)
    rhi = _segmented_scan(bhi, bg, np.maximum, True)
    csum = np.cumsum(cnt)
    n_left = csum - (csum[off] - cnt[off])[bg]
    n_right = n[bg] - n_left
    nxt = np.minimum(np.arange(total) + 1, total - 1)
    with np.errstate(invalid="ignore"):
        cost = _half_area(llo, lhi) * n_left + _half_area(rlo[nxt], rhi[nxt]) * n_right
    cost[(n_left == 0) | (n_right == 0)] = np.inf     # includes each range's last bin
    # ties within a relative 1e-9 go to the most balanced cut
    best = np.minimum.reduceat(cost, off)
    near = cost <= best * (1.0 + 1e-9) if num == 1 else cost <= best[bg] * (1.0 + 1e-9)
    imbalance = np.where(near, np.abs(2 * n_left - n[bg]), np.iinfo(np.int64).max)
    last_left = _segment_argmin(imbalance, off, bg) - off
    return bins, last_left, best


def _split_level(g, n, depth, c, lo, hi, max_leaf):
    """Choose every range's split and return go_right per item.

    g: (A,) the range (0 .. R-1) of each active item; n: (R,) range sizes (> max_leaf); c, lo, hi:
    (A, 3) the items' centroids and boxes, scaled into [0, 1] (float64).
    """
    num = len(n)
    cmin, cmax = _scatter_min_max(num, g, c, c)
    ext = cmax - cmin
    longest = np.argmax(ext, axis=1)
    # Candidate axes: all three for ranges of more than ALL_AXES_ABOVE items, the longest centroid
    # axis for smaller ones (where binning three axes costs 3x for little gain). Each (range, axis)
    # pair is a "virtual range" and one _sah_along call bins them all; big ranges' items are listed
    # three times.
    big = np.flatnonzero(n > ALL_AXES_ABOVE)
    vr = np.concatenate([np.arange(num), big, big])                     # virtual range -> range
    va = np.concatenate([longest, (longest[big] + 1) % 3, (longest[big] + 2) % 3])
    if len(big):
        vid = np.full(num, -1, dtype=np.int64)
        vid[big] = np.arange(len(big))
        copy = np.flatnonzero(vid[g] >= 0)
        item = np.concatenate([np.arange(len(g)), copy, copy])
        gv = np.concatenate([g, num + vid[g[copy]], num + len(big) + vid[g[copy]]])
    else:
        item, gv = np.arange(len(g)), g
    bins, last_left, cost = _sah_along(gv, n[vr], va, cmin[vr], ext[vr], c[item], lo[item], hi[item])
    # per range, the cheapest axis (first on ties: the longest)
    best = np.full(num, np.inf)
    choice = np.arange(num)
    for part in (slice(0, num), slice(num, num + len(big)), slice(num + len(big), None)):
        r = vr[part]
        better = cost[part] < best[r]
        best[r[better]] = cost[part][better]
        choice[r[better]] = np.arange(len(vr))[part][better]
    chosen = choice[vr[gv]] == gv
    go_right = np.empty(len(g), dtype=bool)
    go_right[item[chosen]] = bins[chosen] > last_left[gv[chosen]]
    # Median splits where no bin boundary separates the items (all centroids coincide) or where
    # SAH may no longer choose (see DEPTH_BUDGET): sort those ranges' items along the longest axis.
    leaves = -(-n // max_leaf)
    halving = np.ceil(np.log2(np.maximum(leaves, 1))).astype(np.int64)
    median = ~np.isfinite(best) | (depth + halving >= DEPTH_BUDGET)
    if median.any():
        sel = np.flatnonzero(median[g])
        gs = g[sel]
        ca = c[sel, longest[gs]]
        perm = np.lexsort((ca, gs))                  # by range, then centroid (stable: ties keep id order)
        first = np.searchsorted(gs[perm], gs[perm])
        rank = np.arange(len(sel)) - first
        go_right[sel[perm]] = rank >= n[gs[perm]] // 2
    return go_right


def _build_binary(lo, hi, max_leaf):
    """Breadth-first binary tree. Returns per-node arrays (start, count, left, right, level) and the
    item order (node ids BFS, root = 0; a leaf has left = right = -1 and owns order[start:start+count])."""
    k = len(lo)
    # scale into [0, 1] with one factor for all axes (SAH areas only need to be proportional)
    gmin = lo.min(axis=0).astype(np.float64)
    ext = float((hi.max(axis=0).astype(np.float64) - gmin).max())
    inv = 1.0 / ext if ext > 0 else 0.0
    lo_n = np.clip((lo - gmin) * inv, 0.0, 1.0)
    hi_n = np.clip((hi - gmin) * inv, 0.0, 1.0)
    c_n = 0.5 * (lo_n + hi_n)
    counts, lefts, rights, levels = [np.array([k])], [], [], []
    leaf_of = np.empty(k, dtype=np.int64)              # leaf node of every item
    items = np.arange(k)                               # items of ranges still to split, in id order
    node = np.zeros(k, dtype=np.int64)                 # their current node id
    pos = np.full(k, -1, dtype=np.int64)               # rank within a small range (-1: range not small yet)
    first_id = 0                                       # id of the level's first node
    num_nodes = 1
    level = 0
    while True:
        n = counts[-1]
        split = n > max_leaf
        num_split = int(split.sum())
        ids = np.full(len(n), -1, dtype=np.int64)
        ids[split] = num_nodes + 2 * np.arange(num_split)
        lefts.append(ids)
        rights.append(np.where(split, ids + 1, -1))
        levels.append(np.full(len(n), level))
        local = node - first_id
        done = ~split[local]
        leaf_of[items[done]] = node[done]
        if num_split == 0:
            break
        items, local = items[~done], local[~done]
        pos = pos[~done]
        rank = np.cumsum(split) - 1                    # range index among the split nodes
        g = rank[local]
        ns = n[split]
        go_right = np.empty(len(g), dtype=bool)
        in_small = (ns <= SMALL_RANGE)[g]
        if in_small.any():
            # Small ranges: a balanced split in centroid order along the range's longest axis
            # (items ranked once, when their range first gets small; then only ranks shift).
            new = np.flatnonzero(in_small & (pos < 0))
            if len(new):
                gi, cc = g[new], c_n[items[new]]
                cmin, cmax = _scatter_min_max(num_split, gi, cc, cc)
                axis = np.argmax(cmax - cmin, axis=1)
                perm = np.lexsort((cc[np.arange(len(new)), axis[gi]], gi))
                first = np.searchsorted(gi[perm], gi[perm])
                pos[new[perm]] = np.arange(len(new)) - first
            si = np.flatnonzero(in_small)
            leaves = -(-ns // max_leaf)                # fewest leaves: the left side gets whole leaves
            n_left = np.minimum((leaves + 1) // 2 * max_leaf, ns - 1)[g[si]]
            right = pos[si] >= n_left
            go_right[si] = right
            pos[si] -= right * n_left
        bi = np.flatnonzero(~in_small)
        if len(bi):
            big = np.flatnonzero(ns > SMALL_RANGE)
            bid = np.full(num_split, -1, dtype=np.int64)
            bid[big] = np.arange(len(big))
            it = items[bi]
            go_right[bi] = _split_level(bid[g[bi]], ns[big], level, c_n[it], lo_n[it], hi_n[it], max_leaf)
        n_right = np.bincount(g, weights=go_right, minlength=num_split).astype(np.int64)
        counts.append(np.stack([n[split] - n_right, n_right], axis=1).ravel())
        node = ids[local] + go_right
        first_id = num_nodes
        num_nodes += 2 * num_split
        level += 1
    cat = np.concatenate
    count, left, right, level_of = cat(counts), cat(lefts), cat(rights), cat(levels)
    # depth-first placement: a node's items start where its parent's do, the right child's after
    # the left child's; levels are contiguous id ranges, so this is one vectorised step per level
    start = np.zeros(len(left), dtype=np.int64)
    inner = np.flatnonzero(left >= 0)
    bounds = np.searchsorted(level_of[inner], np.arange(int(level_of.max()) + 2))
    for d in range(len(bounds) - 1):
        at = inner[bounds[d]:bounds[d + 1]]
        start[left[at]] = start[at]
        start[right[at]] = start[at] + count[left[at]]
    order = np.argsort(start[leaf_of])                 # items grouped by leaf, leaves depth-first
    return start, count, left, right, level_of, order


def _binary_boxes(blo, bhi, start, left, right, level):
    """float32 box of every binary node: leaves by reduceat over their ranges, interiors bottom-up."""
    n = len(left)
    nlo = np.empty((n, 3), dtype=np.float32)
    nhi = np.empty((n, 3), dtype=np.float32)
    leaves = np.flatnonzero(left < 0)
    leaves = leaves[np.argsort(start[leaves])]          # leaves tile [0, K) in Morton order
    nlo[leaves] = np.minimum.reduceat(blo, start[leaves], axis=0)
    nhi[leaves] = np.maximum.reduceat(bhi, start[leaves], axis=0)
    interior = left >= 0
    # BFS ids: a level's nodes are contiguous, so walk the level boundaries bottom-up
    bounds = np.flatnonzero(np.diff(level)) + 1
    edges = np.concatenate([[0], bounds, [n]])
    for a, z in zip(edges[-2::-1], edges[:0:-1]):
        at = a + np.flatnonzero(interior[a:z])
        if len(at):
            nlo[at] = np.minimum(nlo[left[at]], nlo[right[at]])
            nhi[at] = np.maximum(nhi[left[at]], nhi[right[at]])
    return nlo, nhi


# --------------------------------------------------------------------------------------------
# Collapse to wide nodes


def _collapse(start, count, left, right, nlo, nhi, width):
    """Wide nodes from the binary tree, all wide nodes of a level at once (W - 1 vectorised steps per
    level, no per-node Python). Returns (box, child, depth, stack_bound)."""
    ext = np.maximum(nhi.astype(np.float64) - nlo.astype(np.float64), 0.0)
    area = ext[:, 0] * ext[:, 1] + ext[:, 1] * ext[:, 2] + ext[:, 2] * ext[:, 0]
    interior = left >= 0
    # key of a slot's node for opening: its area if interior; leaves and empty slots (index -1,
    # the appended entry) never open
    open_key = np.append(np.where(interior, area, -1.0), -1.0)
    count_key = np.append(count, 0)
    rows_by_level, slots_by_level = [], []
    rows = np.array([0])                              # binary nodes that become this level's wide nodes
    while len(rows):
        m = len(rows)
        slots = np.full((m, width), -1, dtype=np.int64)
        slots[:, 0] = rows                            # the first step opens the node itself (if interior)
        ar = np.arange(m)
        for step in range(1, width):
            key = open_key[slots]
            top = key.max(axis=1)
            # the largest area (the prototype's rule); among equal areas (e.g. a pile of coincident
            # or zero-area triangles) the child with the most triangles, so such piles stay shallow
            j = np.argmax(np.where(key >= top[:, None], count_key[slots], -1), axis=1)
            go = top >= 0.0
            if not go.any():
                break
            r, jr = ar[go], j[go]
            node = slots[r, jr]
            slots[r, jr] = left[node]
            slots[r, step] = right[node]              # rows that stopped earlier never resume: slots stay packed
        rows_by_level.append(rows)
        slots_by_level.append(slots)
        nxt = slots[slots >= 0]
        rows = nxt[interior[nxt]]
    # breadth-first numbering: a level's wide nodes follow the previous level's, row-major
    wide_of = np.full(len(left), -1, dtype=np.int64)
    base = 0
    for rows in rows_by_level:
        wide_of[rows] = base + np.arange(len(rows))
        base += len(rows)
    total = base
    box = np.empty((total, 6, width), dtype=np.float32)
    child = np.zeros((total, width), dtype=np.int32)
    # stack bound: acc = siblings left behind by a node's ancestors; a node pushes fan entries
    acc = np.zeros(1, dtype=np.int64)
    stack_bound = 0
    base = 0
    for slots in slots_by_level:
        m = len(slots)
        used = slots >= 0
        s = np.where(used, slots, 0)
        lo = np.where(used[:, :, None], nlo[s], np.float32(np.inf))      # (m, W, 3)
        hi = np.where(used[:, :, None], nhi[s], np.float32(-np.inf))
        box[base:base + m, 0:3, :] = lo.transpose(0, 2, 1)
        box[base:base + m, 3:6, :] = hi.transpose(0, 2, 1)
        inner = used & interior[s]
        leaf_code = -(start[s] * 8 + count[s]) - 1
        child[base:base + m] = np.where(inner, wide_of[s], np.where(used, leaf_code, 0))
        fan = used.sum(axis=1)
        stack_bound = max(stack_bound, int((acc + fan).max()))
        acc = np.repeat(acc + fan - 1, inner.sum(axis=1))
        base += m
    return box, child, len(slots_by_level), stack_bound


BUILDERS = ("warp", "numpy")


def build_wide(points: np.ndarray, tris: np.ndarray, width: int = WIDTH, max_leaf: int = 2,
               builder: str = "warp") -> WideBvh:
    """Build a ``width``-wide BVH over the triangles ``tris`` (K, 3) of ``points`` (N, 3).

    Every triangle is kept, degenerate (zero-area) ones included, in a leaf of 1..max_leaf
    triangles. Raises ValueError for empty or malformed inputs, out-of-range indices, vertices
    that are not finite or beyond float32 range, width outside [2, 64], max_leaf outside [1, 7].

    ``builder``: "warp" (the default) builds the binary tree and collapses it in compiled Warp
    kernels (``accel/wide_build.py``, about 1 us per triangle); "numpy", level by level in numpy
    (this module, 6-10 us per triangle), kept as the second opinion the tests compare against.
    """
    if builder not in BUILDERS:
        raise ValueError(f"build_wide: builder must be one of {BUILDERS}, got {builder!r}")
    p, t = _validate(points, tris, width, max_leaf)
    lo, hi = _triangle_boxes(p, t)
    if builder == "warp":
        from warp_spt.accel.wide_build import build_binary, collapse
        del p, t
        start, count, left, right, nlo, nhi, order = build_binary(lo, hi, max_leaf, DEPTH_BUDGET)
        del lo, hi, right           # the collapse reads left only (right = left + 1)
        box, child, depth, stack_bound = collapse(start, count, left, nlo, nhi, width)
        return WideBvh(box=box, child=child, order=order.astype(np.int32, copy=False), depth=depth,
                       stack_bound=stack_bound)
    start, count, left, right, level, order = _build_binary(lo, hi, max_leaf)
    nlo, nhi = _binary_boxes(lo[order], hi[order], start, left, right, level)
    box, child, depth, stack_bound = _collapse(start, count, left, right, nlo, nhi, width)
    return WideBvh(box=box, child=child, order=order.astype(np.int32), depth=depth, stack_bound=stack_bound)
