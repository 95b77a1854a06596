"""Path guiding's device half: the SD-tree's flat arrays and its look-up, sample and pdf functions.

An SD-tree (after Müller, Gross and Novák 2017, "Practical path guiding") is a binary tree over
space whose every leaf owns a quadtree over directions. Both are flat arrays, built on the host by
``warp_spt.integrators.guiding_tree`` (numpy) and uploaded by :func:`upload_tree`:

* spatial nodes ``s_axis`` (the split axis 0-2, or -1 for a leaf) and ``s_child`` (an inner node:
  its first child, the second follows it; a leaf: its leaf number). A node splits its box at the
  middle, so no split position is stored; the root box is ``lo``..``hi``.
* ``d_root``: NORMAL_BINS quadtree roots per spatial leaf, one per bin of the shading normal (its
  dominant axis and that axis's sign). This is our departure from the paper: its leaves hold
  surfaces of every orientation, so half of what their guide learns for one lies below another
  (a guided direction there is lost); split by the normal's bin, a quadtree learns the light
  above surfaces facing one way (in the rooms here: exactly one wall).
* directional nodes ``d_child`` (the first of 4 consecutive children, or -1 for a leaf) and
  ``d_energy`` (the learnt radiance of the node's square: the sum of its children's). Child
  ``ix + 2 * iy`` covers the quarter ``[ix/2, (ix+1)/2) x [iy/2, (iy+1)/2)`` of its parent.

Directions use the cylindrical (equal-area) map ``(cos theta, phi) -> [0, 1)^2`` in world axes, so
a density on the square is the density over the sphere times 4 pi. Sampling walks down the quadtree
choosing children in proportion to their energy (hierarchical sample warping: one uniform 2D point
is rescaled at every level), then takes a uniform point in the leaf; its density is
``prod(4 e_child / e_parent) / (4 pi)``, which :func:`guide_pdf` computes for any direction.

Training records (:class:`GuideRecord`) go to integer arrays (fixed point, ``ENERGY_SCALE``):
integer sums are exact and do not depend on the order of the additions, so the trained tree, and
the image, are the same bit for bit whatever the threads (Warp's CPU ``atomic_add`` is a plain
read-modify-write, so every concurrently running launch records into its own arrays, which the
host adds up).
"""

from __future__ import annotations

import numpy as np
import warp as wp

FOUR_PI = wp.constant(12.566370614359172)
INV_FOUR_PI = wp.constant(0.07957747154594767)
TWO_PI = wp.constant(6.283185307179586)
ENERGY_SCALE = 16777216.0      # 2**24 fixed-point units per unit of recorded radiance / pdf
ENERGY_MAX = 1.0e6             # one record's cap (a firefly would otherwise own the quadtree)
ENERGY_SCALE_W = wp.constant(ENERGY_SCALE)
ENERGY_MAX_W = wp.constant(ENERGY_MAX)
NORMAL_BINS = wp.constant(6)   # quadtrees per spatial leaf: +x, -x, +y, -y, +z, -z


@wp.struct
class GuideTree:
    """An SD-tree on the device (see the module docs). ``alpha``: the probability of sampling the
    guide where a leaf has learnt something (0: a tree that only records, or none at all)."""

    lo: wp.vec3
    hi: wp.vec3
    s_axis: wp.array(dtype=wp.int32)
    s_child: wp.array(dtype=wp.int32)
    d_root: wp.array(dtype=wp.int32)
    d_child: wp.array(dtype=wp.int32)
    d_energy: wp.array(dtype=wp.float32)
    alpha: float


@wp.struct
class GuideRecord:
    """Where a training pass records: the tree whose leaves collect (its ``d_energy`` unused), the
    fixed-point sums of radiance / pdf per directional node and the records per quadtree (counted
    at its root: a few entries, which stay in the cache); ``on`` 0:
    record nothing (the render's last pass). One per concurrently running launch."""

    tree: GuideTree
    energy: wp.array(dtype=wp.int64)
    hits: wp.array(dtype=wp.int64)
    on: int
    # per launch thread, the path being traced: its recording vertices' (leaf and root of their
    # quadtree, radiance gathered so far, 1 / (throughput x pdf)) until the path's radiance is known
    slot_node: wp.array2d(dtype=wp.vec2i)
    slot_value: wp.array2d(dtype=wp.vec2)


@wp.func(inline=True)
def spatial_leaf(t: GuideTree, p: wp.vec3) -> int:
    """The number of the spatial leaf holding ``p`` (points outside the box go to the leaf of the
    nearest box)."""
    node = int(0)
    lo = t.lo
    hi = t.hi
    while t.s_axis[node] >= 0:
        ax = t.s_axis[node]
        mid = 0.5 * (lo[ax] + hi[ax])
        if p[ax] < mid:
            hi[ax] = mid
            node = t.s_child[node]
        else:
            lo[ax] = mid
            node = t.s_child[node] + 1
    return t.s_child[node]


@wp.func(inline=True)
def normal_bin(n: wp.vec3) -> int:
    """The bin of a normal: 2 x its dominant axis, + 1 when that component is negative."""
    ax = int(0)
    if wp.abs(n[1]) > wp.abs(n[ax]):
        ax = 1
    if wp.abs(n[2]) > wp.abs(n[ax]):
        ax = 2
    return 2 * ax + wp.where(n[ax] < 0.0, 1, 0)


@wp.func(inline=True)
def guide_root(t: GuideTree, p: wp.vec3, n: wp.vec3) -> int:
    """The root of the quadtree for point ``p`` with shading normal ``n``."""
    return t.d_root[NORMAL_BINS * spatial_leaf(t, p) + normal_bin(n)]


@wp.func(inline=True)
def dir_to_square(d: wp.vec3) -> wp.vec2:
    """The cylindrical map of a unit direction: (cos theta + 1) / 2 and phi / 2 pi, in [0, 1)."""
    u = wp.clamp(0.5 * (d[2] + 1.0), 0.0, 0.99999994)
    phi = wp.atan2(d[1], d[0])
    if phi < 0.0:
        phi += TWO_PI
    v = wp.clamp(phi / TWO_PI, 0.0, 0.99999994)
    return wp.vec2(u, v)


@wp.func(inline=True)
def square_to_dir(s: wp.vec2) -> wp.vec3:
    """The inverse of :func:`dir_to_square`."""
    z = 2.0 * s[0] - 1.0
    r = wp.sqrt(wp.max(0.0, 1.0 - z * z))
    phi = TWO_PI * s[1]
    return wp.vec3(r * wp.cos(phi), r * wp.sin(phi), z)


@wp.func(inline=True)
def guide_usable(t: GuideTree, root: int) -> bool:
    """The guide may be sampled at this leaf: guiding is on and the leaf has learnt some energy."""
    return t.alpha > 0.0 and t.d_energy[root] > 0.0


@wp.func(inline=True)
def quadrant(s: wp.vec2):
    """(child ``ix + 2 iy`` of a quadtree node holding point ``s`` of its square, ``s`` in that child's square)."""
    ix = int(0)
    iy = int(0)
    if s[0] >= 0.5:
        ix = 1
    if s[1] >= 0.5:
        iy = 1
    return ix + 2 * iy, wp.vec2(2.0 * s[0] - float(ix), 2.0 * s[1] - float(iy))


@wp.func(inline=True)
def pick(r: float, p: float):
    """(0 with probability ``p``, else 1; ``r`` rescaled to a fresh uniform number): one step of
    hierarchical sample warping."""
    if r < p:
        return 0, r / p
    return 1, (r - p) / wp.max(1.0 - p, 1.0e-12)


@wp.func(inline=True)
def guide_pdf(t: GuideTree, root: int, d: wp.vec3) -> float:
    """Solid-angle density of :func:`guide_sample` producing ``d`` from the quadtree at ``root``."""
    s = dir_to_square(d)
    node = root
    pdf = float(INV_FOUR_PI)
    while t.d_child[node] >= 0:
        e = t.d_energy[node]
        if e <= 0.0:
            return 0.0
        q, s = quadrant(s)
        c = t.d_child[node] + q
        pdf = pdf * (4.0 * t.d_energy[c] / e)
        node = c
    return pdf


@wp.func(inline=True)
def guide_sample(t: GuideTree, root: int, u: wp.vec2):
    """(direction, its density) from the quadtree at ``root``, from one uniform 2D point rescaled at
    every level (first the column, ix, then the row, iy); the density is :func:`guide_pdf`'s."""
    node = root
    pdf = float(INV_FOUR_PI)
    r = u
    origin = wp.vec2(0.0, 0.0)
    size = float(1.0)
    while t.d_child[node] >= 0:
        c0 = t.d_child[node]
        e00 = t.d_energy[c0]
        e10 = t.d_energy[c0 + 1]
        e01 = t.d_energy[c0 + 2]
        e11 = t.d_energy[c0 + 3]
        left = e00 + e01
        total = left + e10 + e11
        ix, rx = pick(r[0], left / total)
        iy, ry = pick(r[1], wp.where(ix == 0, e00, e10) / wp.where(ix == 0, left, total - left))
        r = wp.vec2(wp.min(rx, 0.99999994), wp.min(ry, 0.99999994))
        size = 0.5 * size
        origin = origin + wp.vec2(float(ix) * size, float(iy) * size)
        pdf = pdf * (4.0 * t.d_energy[c0 + ix + 2 * iy] / total)
        node = c0 + ix + 2 * iy
    return square_to_dir(origin + r * size), pdf


@wp.func(inline=True)
def dir_leaf(t: GuideTree, root: int, d: wp.vec3) -> int:
    """The leaf of the quadtree at ``root`` whose square holds ``d``."""
    s = dir_to_square(d)
    node = root
    while t.d_child[node] >= 0:
        q, s = quadrant(s)
        node = t.d_child[node] + q
    return node


@wp.func(inline=True)
def record_energy(value: float) -> wp.int64:
    """One record's radiance / pdf in fixed point (negative and non-finite values record nothing)."""
    if not wp.isfinite(value) or value <= 0.0:
        return wp.int64(0)
    return wp.int64(wp.min(value, ENERGY_MAX_W) * ENERGY_SCALE_W)


def upload_tree(tree, alpha: float, device: str) -> GuideTree:
    """A :class:`GuideTree` of the host tree ``tree`` (``guiding_tree.SDTree``) on ``device``."""
    g = GuideTree()
    g.lo = wp.vec3(*[float(x) for x in tree.lo])
    g.hi = wp.vec3(*[float(x) for x in tree.hi])
    g.s_axis = wp.array(tree.s_axis.astype(np.int32), dtype=wp.int32, device=device)
    g.s_child = wp.array(tree.s_child.astype(np.int32), dtype=wp.int32, device=device)
    g.d_root = wp.array(tree.d_root.astype(np.int32), dtype=wp.int32, device=device)
    g.d_child = wp.array(tree.d_child.astype(np.int32), dtype=wp.int32, device=device)
    g.d_energy = wp.array(tree.d_energy.astype(np.float32), dtype=wp.float32, device=device)
    g.alpha = float(alpha)
    return g


def new_record(tree: GuideTree, nodes: int, on: bool, threads: int, slots: int, device: str) -> GuideRecord:
    """A :class:`GuideRecord` into ``tree`` with zeroed sums for its ``nodes`` directional nodes, for
    launches of at most ``threads`` threads recording at most ``slots`` vertices per path."""
    r = GuideRecord()
    shape = (threads, slots) if on else (1, 1)
    r.slot_node = wp.zeros(shape, dtype=wp.vec2i, device=device)
    r.slot_value = wp.zeros(shape, dtype=wp.vec2, device=device)
    r.tree = tree
    r.energy = wp.zeros(max(nodes, 1), dtype=wp.int64, device=device)
    r.hits = wp.zeros(max(nodes, 1), dtype=wp.int64, device=device)
    r.on = 1 if on else 0
    return r
