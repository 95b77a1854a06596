"""The binary binned-SAH tree under the wide BVH, built by one compiled Warp kernel on the CPU.

Why a kernel: the numpy build (``wide_bvh._build_binary``, level by level, whole-array calls)
costs about 7 us per triangle at a million (dozens of array passes and scatters per level);
this is the classic recursive build, compiled: per node one pass bins the triangles' centroids on
all three axes and one pass partitions them in place (their boxes and centroids move with them,
so every pass reads memory in order). ``benchmarks/bench_wide_build.py`` measures both.

The kernel runs on one thread (``dim=1``) over host arrays: a tree build is a sequence of
dependent splits, and Warp's CPU launches are single-threaded anyway.

Rules (the same kind of tree as the numpy build, not the same tree):

- ``NUM_BINS`` bins per axis over the node's centroid bounds, all three axes (the longest only for
  ranges of at most ``ALL_AXES_ABOVE`` triangles), the cut of least
  ``area(left) * n_left + area(right) * n_right``; ties go to the more balanced cut, then to the
  first axis and bin.
- A node of more than ``max_leaf`` triangles is always split (the traversal's leaf loop is
  fixed-size). Where no bin boundary separates the centroids (all equal along every axis), or
  where SAH cuts could no longer finish within ``depth_budget`` levels by halving, the range is
  halved in its current order, whole leaves on the left.
- Boxes are float32 mins and maxes of the triangles' float32 boxes (exact: no rounding).
"""

from __future__ import annotations

import numpy as np
import warp as wp

NUM_BINS = 16
ALL_AXES_ABOVE = 64  # ranges of more triangles bin all three axes, smaller ones their longest
STACK = 512          # pending nodes; a depth-first build holds at most depth + 1


@wp.func
def _half_area(lo: wp.vec3, hi: wp.vec3) -> float:
    d = hi - lo
    return d[0] * d[1] + d[1] * d[2] + d[2] * d[0]


@wp.func
def _up() -> wp.vec3:
    """The lower corner of an empty box. (Each running bound starts from its own call: two loop
    variables initialised from one shared vector are one variable to Warp's code generator.)"""
    return wp.vec3(wp.inf, wp.inf, wp.inf)


@wp.func
def _down() -> wp.vec3:
    return wp.vec3(-wp.inf, -wp.inf, -wp.inf)


@wp.func
def _bin(x: float, lo: float, scale: float) -> int:
    return wp.clamp(int((x - lo) * scale), 0, NUM_BINS - 1)


@wp.func
def _levels(count: int, max_leaf: int) -> int:
    """Binary levels that halving needs to cut ``count`` triangles into leaves of ``max_leaf``."""
    leaves = (count + max_leaf - 1) // max_leaf
    n = int(0)
    while (1 << n) < leaves:
        n += 1
    return n


@wp.kernel(enable_backward=False)
def _build(lo: wp.array(dtype=wp.vec3), hi: wp.array(dtype=wp.vec3), c: wp.array(dtype=wp.vec3),
           idx: wp.array(dtype=wp.int32), max_leaf: int, depth_budget: int,
           n_lo: wp.array(dtype=wp.vec3), n_hi: wp.array(dtype=wp.vec3), n_left: wp.array(dtype=wp.int32),
           n_start: wp.array(dtype=wp.int32), n_count: wp.array(dtype=wp.int32), n_level: wp.array(dtype=wp.int32),
           s_node: wp.array(dtype=wp.int32), s_clo: wp.array(dtype=wp.vec3), s_chi: wp.array(dtype=wp.vec3),
           b_n: wp.array(dtype=wp.int32), b_lo: wp.array(dtype=wp.vec3), b_hi: wp.array(dtype=wp.vec3),
           r_area: wp.array(dtype=float), out: wp.array(dtype=wp.int32)):
    k = lo.shape[0]
    # the root
    blo = _up()
    bhi = _down()
    clo = _up()
    chi = _down()
    for i in range(k):
        blo = wp.min(blo, lo[i])
        bhi = wp.max(bhi, hi[i])
        clo = wp.min(clo, c[i])
        chi = wp.max(chi, c[i])
    n_lo[0] = blo
    n_hi[0] = bhi
    n_start[0] = 0
    n_count[0] = k
    n_level[0] = 0
    num_nodes = int(1)
    sp = int(1)
    s_node[0] = 0
    s_clo[0] = clo
    s_chi[0] = chi
    overflow = int(0)
    while sp > 0:
        sp -= 1
        node = s_node[sp]
        clo = s_clo[sp]
        chi = s_chi[sp]
        start = n_start[node]
        count = n_count[node]
        level = n_level[node]
        if count <= max_leaf:
            n_left[node] = -1
            continue
        ext = chi - clo
        best_cost = float(wp.inf)
        best_axis = int(-1)
        best_bin = int(0)
        best_imb = int(count)
        if level + _levels(count, max_leaf) < depth_budget:
            # small ranges bin their longest centroid axis only (all three cost 3x for little gain)
            longest = int(0)
            if ext[1] > ext[longest]:
                longest = 1
            if ext[2] > ext[longest]:
                longest = 2
            scale = wp.vec3(0.0)
            for a in range(3):
                # (an extent so small that the scale overflows cannot be binned: such centroids are equal)
                if ext[a] > 0.0 and (count > ALL_AXES_ABOVE or a == longest) and float(NUM_BINS) / ext[a] < 1.0e30:
                    scale[a] = float(NUM_BINS) / ext[a]
            for a in range(3):
                if scale[a] > 0.0:          # only the axes binned (a small range bins one)
                    for t in range(NUM_BINS):
                        j = a * NUM_BINS + t
                        b_n[j] = 0
                        b_lo[j] = _up()
                        b_hi[j] = _down()
            for i in range(start, start + count):
                ci = c[i]
                tl = lo[i]
                th = hi[i]
                for a in range(3):
                    if scale[a] > 0.0:
                        j = a * NUM_BINS + _bin(ci[a], clo[a], scale[a])
                        b_n[j] += 1
                        b_lo[j] = wp.min(b_lo[j], tl)
                        b_hi[j] = wp.max(b_hi[j], th)
            for a in range(3):
                if scale[a] > 0.0:
                    rl = _up()
                    rh = _down()
                    for t in range(NUM_BINS - 1):
                        j = a * NUM_BINS + NUM_BINS - 1 - t
                        if b_n[j] > 0:
                            rl = wp.min(rl, b_lo[j])
                            rh = wp.max(rh, b_hi[j])
                        r_area[j] = _half_area(rl, rh)
                    ll = _up()
                    lh = _down()
                    nl = int(0)
                    for t in range(NUM_BINS - 1):
                        j = a * NUM_BINS + t
                        if b_n[j] > 0:
                            ll = wp.min(ll, b_lo[j])
                            lh = wp.max(lh, b_hi[j])
                        nl += b_n[j]
                        nr = count - nl
                        if nl > 0 and nr > 0:
                            cost = _half_area(ll, lh) * float(nl) + r_area[j + 1] * float(nr)
                            imb = wp.abs(2 * nl - count)
                            if cost < best_cost or (cost == best_cost and imb < best_imb):
                                best_cost = float(cost)
                                best_axis = int(a)
                                best_bin = int(t)
                                best_imb = int(imb)
        lclo = _up()
        lchi = _down()
        rclo = _up()
        rchi = _down()
        llo = _up()
        lhi = _down()
        rlo = _up()
        rhi = _down()
        nl = int(0)
        if best_axis >= 0:
            # partition in place: centroids in bins <= best_bin go left
            i = start
            j = start + count - 1
            lo_a = clo[best_axis]
            sc = float(NUM_BINS) / ext[best_axis]
            while i <= j:
                ci = c[i]
                if _bin(ci[best_axis], lo_a, sc) <= best_bin:
                    lclo = wp.min(lclo, ci)
                    lchi = wp.max(lchi, ci)
                    llo = wp.min(llo, lo[i])
                    lhi = wp.max(lhi, hi[i])
                    i += 1
                else:
                    rclo = wp.min(rclo, ci)
                    rchi = wp.max(rchi, ci)
                    rlo = wp.min(rlo, lo[i])
                    rhi = wp.max(rhi, hi[i])
                    tl = lo[i]
                    th = hi[i]
                    ti = idx[i]
                    c[i] = c[j]
                    lo[i] = lo[j]
                    hi[i] = hi[j]
                    idx[i] = idx[j]
                    c[j] = ci
                    lo[j] = tl
                    hi[j] = th
                    idx[j] = ti
                    j -= 1
            nl = i - start
        else:
            # halve in the current order, whole leaves on the left
            leaves = (count + max_leaf - 1) // max_leaf
            nl = wp.min((leaves + 1) // 2 * max_leaf, count - 1)
            for i in range(start, start + count):
                if i < start + nl:
                    lclo = wp.min(lclo, c[i])
                    lchi = wp.max(lchi, c[i])
                    llo = wp.min(llo, lo[i])
                    lhi = wp.max(lhi, hi[i])
                else:
                    rclo = wp.min(rclo, c[i])
                    rchi = wp.max(rchi, c[i])
                    rlo = wp.min(rlo, lo[i])
                    rhi = wp.max(rhi, hi[i])
        left = num_nodes
        num_nodes += 2
        n_left[node] = left
        n_lo[left] = llo
        n_hi[left] = lhi
        n_start[left] = start
        n_count[left] = nl
        n_level[left] = level + 1
        n_lo[left + 1] = rlo
        n_hi[left + 1] = rhi
        n_start[left + 1] = start + nl
        n_count[left + 1] = count - nl
        n_level[left + 1] = level + 1
        if sp + 2 > s_node.shape[0]:
            overflow = 1
            break
        s_node[sp] = left + 1
        s_clo[sp] = rclo
        s_chi[sp] = rchi
        s_node[sp + 1] = left
        s_clo[sp + 1] = lclo
        s_chi[sp + 1] = lchi
        sp += 2
    out[0] = num_nodes
    out[1] = overflow


def build_binary(lo: np.ndarray, hi: np.ndarray, max_leaf: int, depth_budget: int):
    """The binary tree over triangle boxes ``lo``, ``hi`` (K, 3) float32 (C-contiguous float32 arrays
    are permuted in place: they are the kernel's working arrays).

    Returns (start, count, left, right, nlo, nhi, order): per node (root 0; children of a node are
    consecutive ids, left = right - 1; a leaf has left = right = -1 and owns order[start:start +
    count]) and the triangles in depth-first leaf order."""
    from warp_spt.runtime.warp_init import init_warp
    init_warp()
    k = len(lo)
    dev = "cpu"
    # the kernel permutes the boxes in place: work on copies unless they are float32 arrays the caller
    # hands over (build_wide's own), which become the kernel's arrays themselves
    own = lo.dtype == np.float32 and hi.dtype == np.float32 and lo.flags.c_contiguous and hi.flags.c_contiguous
    lo = np.array(lo, dtype=np.float32, copy=not own)
    hi = np.array(hi, dtype=np.float32, copy=not own)
    c = 0.5 * lo
    c += 0.5 * hi
    lo_w = wp.array(lo, dtype=wp.vec3, device=dev, copy=False)
    hi_w = wp.array(hi, dtype=wp.vec3, device=dev, copy=False)
    c_w = wp.array(c, dtype=wp.vec3, device=dev, copy=False)
    idx = wp.array(np.arange(k, dtype=np.int32), dtype=wp.int32, device=dev)
    m = max(2 * k - 1, 1)
    n_lo = wp.empty(m, dtype=wp.vec3, device=dev)
    n_hi = wp.empty(m, dtype=wp.vec3, device=dev)
    n_left, n_start, n_count, n_level = (wp.empty(m, dtype=wp.int32, device=dev) for _ in range(4))
    s_node = wp.empty(STACK, dtype=wp.int32, device=dev)
    s_clo, s_chi = wp.empty(STACK, dtype=wp.vec3, device=dev), wp.empty(STACK, dtype=wp.vec3, device=dev)
    b_n = wp.empty(3 * NUM_BINS, dtype=wp.int32, device=dev)
    b_lo, b_hi = wp.empty(3 * NUM_BINS, dtype=wp.vec3, device=dev), wp.empty(3 * NUM_BINS, dtype=wp.vec3, device=dev)
    r_area = wp.empty(3 * NUM_BINS, dtype=float, device=dev)
    out = wp.zeros(2, dtype=wp.int32, device=dev)
    wp.launch(_build, dim=1, device=dev, inputs=[lo_w, hi_w, c_w, idx, int(max_leaf), int(depth_budget), n_lo, n_hi,
                                                  n_left, n_start, n_count, n_level, s_node, s_clo, s_chi, b_n, b_lo,
                                                  b_hi, r_area, out])
    num, overflow = (int(x) for x in out.numpy())
    if overflow:        # cannot happen while depth_budget keeps the tree shallow; say so if it does
        raise RuntimeError(f"wide BVH build: more than {STACK} pending nodes")
    del lo_w, hi_w, c_w, c
    # views of the kernel's arrays (each keeps its Warp array alive), not copies
    left = n_left.numpy()[:num]
    right = np.where(left >= 0, left + 1, -1).astype(np.int32)
    return (n_start.numpy()[:num], n_count.numpy()[:num], left, right, n_lo.numpy()[:num], n_hi.numpy()[:num],
            idx.numpy())


@wp.func
def _area64(lo: wp.vec3, hi: wp.vec3) -> wp.float64:
    dx = wp.max(wp.float64(hi[0]) - wp.float64(lo[0]), wp.float64(0.0))
    dy = wp.max(wp.float64(hi[1]) - wp.float64(lo[1]), wp.float64(0.0))
    dz = wp.max(wp.float64(hi[2]) - wp.float64(lo[2]), wp.float64(0.0))
    return dx * dy + dy * dz + dz * dx


@wp.kernel(enable_backward=False)
def _collapse(left: wp.array(dtype=wp.int32), start: wp.array(dtype=wp.int32), count: wp.array(dtype=wp.int32),
              nlo: wp.array(dtype=wp.vec3), nhi: wp.array(dtype=wp.vec3), width: int,
              box: wp.array3d(dtype=wp.float32), child: wp.array2d(dtype=wp.int32),
              queue: wp.array(dtype=wp.int32), acc: wp.array(dtype=wp.int32), level: wp.array(dtype=wp.int32),
              slots: wp.array(dtype=wp.int32), out: wp.array(dtype=wp.int32)):
    queue[0] = 0
    acc[0] = 0
    level[0] = 1
    n_wide = int(1)
    bound = int(0)
    depth = int(0)
    i = int(0)
    while i < n_wide:
        slots[0] = queue[i]
        fan = int(1)
        for step in range(1, width):
            # open the interior slot of largest area (ties: most triangles, then the first)
            best = int(-1)
            best_area = wp.float64(-1.0)
            best_count = int(-1)
            for j in range(fan):
                s = slots[j]
                if left[s] >= 0:
                    a = _area64(nlo[s], nhi[s])
                    if a > best_area or (a == best_area and count[s] > best_count):
                        best = int(j)
                        best_area = a
                        best_count = count[s]
            if best < 0:
                break
            s = slots[best]
            slots[best] = left[s]
            slots[fan] = left[s] + 1
            fan += 1
        bound = wp.max(bound, acc[i] + fan)
        depth = wp.max(depth, level[i])
        for j in range(width):
            if j < fan:
                s = slots[j]
                lo = nlo[s]
                hi = nhi[s]
                for r in range(3):
                    box[i, r, j] = lo[r]
                    box[i, 3 + r, j] = hi[r]
                if left[s] >= 0:
                    child[i, j] = n_wide
                    queue[n_wide] = s
                    acc[n_wide] = acc[i] + fan - 1
                    level[n_wide] = level[i] + 1
                    n_wide += 1
                else:
                    child[i, j] = -(start[s] * 8 + count[s]) - 1
            else:
                for r in range(3):
                    box[i, r, j] = wp.inf
                    box[i, 3 + r, j] = -wp.inf
                child[i, j] = 0
        i += 1
    out[0] = n_wide
    out[1] = depth
    out[2] = bound


def collapse(start, count, left, nlo, nhi, width: int):
    """Wide nodes from the binary tree of :func:`build_binary` (the same rules and numbering as
    ``wide_bvh._collapse``, in one kernel). Returns (box, child, depth, stack_bound)."""
    dev = "cpu"
    interior = int((left >= 0).sum())
    m = max(interior, 1)
    # the binary tree's arrays as they are (wp.array copies by default: 39 MB at a million triangles)
    i32 = (lambda a: wp.array(np.ascontiguousarray(a, dtype=np.int32), dtype=wp.int32, device=dev, copy=False))
    v3 = (lambda a: wp.array(np.ascontiguousarray(a, dtype=np.float32), dtype=wp.vec3, device=dev, copy=False))
    box = wp.empty((m, 6, width), dtype=wp.float32, device=dev)
    child = wp.empty((m, width), dtype=wp.int32, device=dev)
    queue, acc, level = (wp.empty(m, dtype=wp.int32, device=dev) for _ in range(3))
    slots = wp.empty(width, dtype=wp.int32, device=dev)
    out = wp.zeros(3, dtype=wp.int32, device=dev)
    wp.launch(_collapse, dim=1, device=dev, inputs=[i32(left), i32(start), i32(count), v3(nlo), v3(nhi), int(width),
                                                     box, child, queue, acc, level, slots, out])
    n, depth, bound = (int(x) for x in out.numpy())
    del queue, acc, level
    return box.numpy()[:n], child.numpy()[:n], depth, bound       # views: rows past n were never touched
