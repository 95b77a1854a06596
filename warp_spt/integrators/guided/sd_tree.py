"""Path guiding's device half: the SD-tree's flat arrays and its look-up, sample and pdf functions.

An SD-tree (after Müller, Gross and Novák 2017, "Practical path guiding") is a binary tree over
space whose every leaf owns a quadtree over directions. Both are flat arrays, built on the host by
``warp_spt.integrators.guided.tree`` (numpy) and uploaded by :func:`upload_tree`:

* spatial nodes ``s_axis`` (the split axis 0-2, or -1 for a leaf) and ``s_child`` (an inner node:
  its first child, the second follows it; a leaf: its leaf number). A node splits its box at the
  middle, so no split position is stored; the root box is ``lo``..``hi``.
* ``d_root``: NORMAL_BINS quadtree roots per spatial leaf, one per bin of the shading normal (its
  dominant axis and that axis's sign). This is our departure from the paper: its leaves hold
  surfaces of every orientation, so half of what their guide learns for one lies below another
  (a guided direction there is lost); split by the normal's bin, a quadtree learns the light
  above surfaces facing one way (in the rooms here: exactly one wall).
* directional nodes ``d_child`` (the first of 4 consecutive children, or -1 for a leaf) and, per
  inner node, ``d_cond``: its children's probabilities as (P(column 0), P(row 0 | column 0),
  P(row 0 | column 1)), normalised on the host from the learnt energies
  (``tree.SDTree.d_energy``, each node's the sum of its children's), so a walk needs no sums.
  Child ``ix + 2 * iy`` covers the quarter ``[ix/2, (ix+1)/2) x [iy/2, (iy+1)/2)`` of its parent.
* ``q_alpha``: per quadtree, the probability of sampling it (learnt, ``tree.quadtree_alpha``).

Directions map to the square by (cos theta + 1) / 2 and a "diamond angle" for the azimuth (the
quadrant and b / (a + b) of the direction's (x, y) turned into the first quadrant), in world axes:
no trigonometry either way. The map is not equal-area: the solid-angle density is the square's times
:func:`square_jacobian` ((a^2 + b^2) / 8, between 1/16 and 1/8). Sampling walks down the quadtree
once, choosing children by their probabilities (hierarchical sample warping: one uniform 2D point
is rescaled at every level), and takes a uniform point in the leaf; the same walk multiplies the
density, ``prod(4 P(child)) x jacobian``, which :func:`guide_pdf` computes for any direction.

Training records (:class:`GuideRecord`) go to integer arrays (fixed point, ``ENERGY_SCALE``) by
``wp.atomic_add``: integer sums are exact and do not depend on the order of the additions, so the
trained tree, and the image, are the same bit for bit whatever the threads. Within a launch the
adds are atomic on CUDA (a launch's threads run at once there); Warp's CPU ``atomic_add`` is a plain
read-modify-write (a CPU launch runs on one thread), so every concurrently running CPU launch
records into its own arrays, which the host adds up.
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
    """An SD-tree on the device (see the module docs). ``d_cond`` per inner directional node: the
    probabilities (column 0, row 0 given column 0, row 0 given column 1, unused) of its children;
    ``q_alpha`` per quadtree (index into ``d_root``): the probability of sampling the guide there
    (0 where it learnt nothing or would not help); ``alpha``: the largest of them (0: a tree that
    only records, or none at all: no look-up)."""

    lo: wp.vec3
    hi: wp.vec3
    s_axis: wp.array(dtype=wp.int32)
    s_child: wp.array(dtype=wp.int32)
    d_root: wp.array(dtype=wp.int32)
    d_child: wp.array(dtype=wp.int32)
    d_cond: wp.array(dtype=wp.vec4)
    q_alpha: wp.array(dtype=wp.float32)
    alpha: float


@wp.struct
class GuideRecord:
    """Where a training pass records: the tree whose leaves collect (its ``d_cond`` and ``q_alpha``
    unused), the fixed-point sums of radiance x cos / pdf and the record counts per directional
    leaf (the host sums them up the quadtrees); ``on`` 0: record nothing (the render's last pass).
    One per concurrently running launch."""

    tree: GuideTree
    energy: wp.array(dtype=wp.int64)
    hits: wp.array(dtype=wp.int64)
    on: int
    # per launch thread, the path being traced: its recording vertices' (leaf and root of their
    # quadtree, radiance gathered so far, 1 / (throughput x pdf)) until the path's radiance is known
    slot_node: wp.array2d(dtype=wp.vec2i)
    slot_value: wp.array2d(dtype=wp.vec2)
    # per quadtree of ``tree``: the sampling tree's quadtree it refines (``tree.sampling_quadtrees``)
    to_sampling: wp.array(dtype=wp.int32)


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
def bin_cos(n: wp.vec3, d: wp.vec3) -> float:
    """The cosine of ``d`` to the axis of the normal bin of ``n`` (:func:`normal_bin`)."""
    b = normal_bin(n)
    return wp.where(b % 2 == 0, 1.0, -1.0) * d[b / 2]


@wp.func(inline=True)
def guide_quadtree(t: GuideTree, p: wp.vec3, n: wp.vec3) -> int:
    """The quadtree for point ``p`` with shading normal ``n``: its index into ``d_root`` and ``q_alpha``."""
    return NORMAL_BINS * spatial_leaf(t, p) + normal_bin(n)


@wp.func(inline=True)
def guide_root(t: GuideTree, p: wp.vec3, n: wp.vec3) -> int:
    """The root of the quadtree for point ``p`` with shading normal ``n``."""
    return t.d_root[guide_quadtree(t, p, n)]


@wp.func(inline=True)
def dir_to_square(d: wp.vec3) -> wp.vec2:
    """The map of a unit direction to the square: (cos theta + 1) / 2, and the azimuth as a "diamond
    angle", (quadrant + b / (a + b)) / 4 with (a, b) the direction's (x, y) turned into the first
    quadrant: no trigonometry. Its inverse is :func:`square_to_dir`."""
    u = wp.clamp(0.5 * (d[2] + 1.0), 0.0, 0.99999994)
    x = d[0]
    y = d[1]
    q = float(3.0)
    a = -y
    b = x
    if x > 0.0 and y >= 0.0:
        q = 0.0
        a = x
        b = y
    elif x <= 0.0 and y > 0.0:
        q = 1.0
        a = y
        b = -x
    elif x < 0.0 and y <= 0.0:
        q = 2.0
        a = -x
        b = -y
    s = a + b
    tq = float(0.0)
    if s > 0.0:
        tq = b / s
    return wp.vec2(u, wp.clamp(0.25 * (q + tq), 0.0, 0.99999994))


@wp.func(inline=True)
def square_jacobian(v: float) -> float:
    """dA(square) / d omega at azimuth coordinate ``v``: (a^2 + b^2) / 8 with (a, b) = (1 - t, t), t
    the fraction of 4 v (the square's density times this is the solid-angle density)."""
    w = 4.0 * v
    t = w - wp.floor(w)
    return 0.125 * ((1.0 - t) * (1.0 - t) + t * t)


@wp.func(inline=True)
def square_to_dir(s: wp.vec2):
    """(the direction of point ``s`` of the square (:func:`dir_to_square`'s inverse), the map's
    :func:`square_jacobian` there)."""
    z = 2.0 * s[0] - 1.0
    r = wp.sqrt(wp.max(0.0, 1.0 - z * z))
    w = 4.0 * s[1]
    qf = wp.min(wp.floor(w), 3.0)
    t = w - qf
    a = 1.0 - t
    m = a * a + t * t
    k = r / wp.sqrt(m)
    x = a
    y = t
    if qf == 1.0:
        x = -t
        y = a
    elif qf == 2.0:
        x = -a
        y = -t
    elif qf == 3.0:
        x = t
        y = -a
    return wp.vec3(k * x, k * y, z), 0.125 * m


@wp.func(inline=True)
def quadrant(s: wp.vec2):
    """(column ``ix`` and row ``iy`` of the child of a quadtree node holding point ``s`` of its square,
    ``s`` in that child's square); the child is node ``ix + 2 iy`` of the four."""
    ix = int(0)
    iy = int(0)
    if s[0] >= 0.5:
        ix = 1
    if s[1] >= 0.5:
        iy = 1
    return ix, iy, wp.vec2(2.0 * s[0] - float(ix), 2.0 * s[1] - float(iy))


@wp.func(inline=True)
def pick(r: float, p: float):
    """(0 with probability ``p``, else 1; ``r`` rescaled to a fresh uniform number): one step of
    hierarchical sample warping."""
    if r < p:
        return 0, r / p
    return 1, (r - p) / wp.max(1.0 - p, 1.0e-12)


@wp.func(inline=True)
def child_factor(c: wp.vec4, ix: int, iy: int) -> float:
    """4 x the probability of child (``ix``, ``iy``) of a node whose conditionals are ``c``: the
    factor by which the square's density grows going down to it."""
    px = wp.where(ix == 0, c[0], 1.0 - c[0])
    py = wp.where(ix == 0, c[1], c[2])
    return 4.0 * px * wp.where(iy == 0, py, 1.0 - py)


@wp.func(inline=True)
def guide_pdf(t: GuideTree, root: int, d: wp.vec3) -> float:
    """Solid-angle density of :func:`guide_sample` producing ``d`` from the quadtree at ``root``."""
    s = dir_to_square(d)
    pdf = square_jacobian(s[1])
    node = root
    while t.d_child[node] >= 0:
        ix, iy, s = quadrant(s)
        pdf = pdf * child_factor(t.d_cond[node], ix, iy)
        node = t.d_child[node] + ix + 2 * iy
    return pdf


@wp.func(inline=True)
def guide_sample(t: GuideTree, root: int, u: wp.vec2):
    """(direction, its density) from the quadtree at ``root``, from one uniform 2D point rescaled at
    every level (first the column, ix, then the row, iy), in one walk; the density is
    :func:`guide_pdf`'s (the same products)."""
    node = root
    pdf = float(1.0)
    r = u
    origin = wp.vec2(0.0, 0.0)
    size = float(1.0)
    while t.d_child[node] >= 0:
        c = t.d_cond[node]
        ix, rx = pick(r[0], c[0])
        iy, ry = pick(r[1], wp.where(ix == 0, c[1], c[2]))
        r = wp.vec2(wp.min(rx, 0.99999994), wp.min(ry, 0.99999994))
        size = 0.5 * size
        origin = origin + wp.vec2(float(ix) * size, float(iy) * size)
        pdf = pdf * child_factor(c, ix, iy)
        node = t.d_child[node] + ix + 2 * iy
    d, jac = square_to_dir(origin + r * size)
    return d, pdf * jac


@wp.func(inline=True)
def dir_leaf(t: GuideTree, root: int, d: wp.vec3) -> int:
    """The leaf of the quadtree at ``root`` whose square holds ``d``."""
    s = dir_to_square(d)
    node = root
    while t.d_child[node] >= 0:
        ix, iy, s = quadrant(s)
        node = t.d_child[node] + ix + 2 * iy
    return node


@wp.func(inline=True)
def record_energy(value: float) -> wp.int64:
    """One record's radiance / pdf in fixed point (negative and non-finite values record nothing)."""
    if not wp.isfinite(value) or value <= 0.0:
        return wp.int64(0)
    return wp.int64(wp.min(value, ENERGY_MAX_W) * ENERGY_SCALE_W)


def square_to_dir_np(s: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """numpy twin of :func:`square_to_dir` for (..., 2) points: (directions, square_jacobian)."""
    s = np.asarray(s, np.float64)
    z = 2.0 * s[..., 0] - 1.0
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    w = 4.0 * s[..., 1]
    q = np.minimum(np.floor(w), 3.0)
    t = w - q
    a = 1.0 - t
    m = a * a + t * t
    k = r / np.sqrt(m)
    x = np.select([q == 0, q == 1, q == 2], [a, -t, -a], t)
    y = np.select([q == 0, q == 1, q == 2], [t, a, -t], -a)
    return np.stack([k * x, k * y, z], axis=-1), 0.125 * m


def dir_to_square_np(d: np.ndarray) -> np.ndarray:
    """numpy twin of :func:`dir_to_square` for (..., 3) unit directions."""
    d = np.asarray(d, np.float64)
    x, y = d[..., 0], d[..., 1]
    conds = [(x > 0) & (y >= 0), (x <= 0) & (y > 0), (x < 0) & (y <= 0)]
    q = np.select(conds, [0.0, 1.0, 2.0], 3.0)
    a = np.select(conds, [x, y, -x], -y)
    b = np.select(conds, [y, -x, -y], x)
    with np.errstate(invalid="ignore", divide="ignore"):
        t = np.where(a + b > 0, b / (a + b), 0.0)
    return np.stack([np.clip(0.5 * (d[..., 2] + 1.0), 0.0, 0.99999994),
                     np.clip(0.25 * (q + t), 0.0, 0.99999994)], axis=-1)


def conditionals(d_child: np.ndarray, d_energy: np.ndarray) -> np.ndarray:
    """Per directional node, :class:`GuideTree`'s ``d_cond`` from the energies: (P(column 0),
    P(row 0 | column 0), P(row 0 | column 1), 0) of its children, one half where there is no energy."""
    cond = np.full((d_child.size, 4), 0.5, np.float64)
    cond[:, 3] = 0.0
    inner = np.flatnonzero(d_child >= 0)
    c = d_child[inner].astype(np.int64)
    e = np.maximum(np.asarray(d_energy, np.float64), 0.0)
    e00, e10, e01, e11 = e[c], e[c + 1], e[c + 2], e[c + 3]
    with np.errstate(invalid="ignore", divide="ignore"):
        for col, num, den in ((0, e00 + e01, e00 + e01 + e10 + e11), (1, e00, e00 + e01), (2, e10, e10 + e11)):
            cond[inner, col] = np.where(den > 0.0, num / den, 0.5)
    return cond.astype(np.float32)


def upload_tree(tree, alpha, device: str, structure: GuideTree | None = None, sampling: bool = True) -> GuideTree:
    """A :class:`GuideTree` of the host tree ``tree`` (``tree.SDTree``) on ``device``;
    ``alpha``: one probability of sampling the guide for every quadtree that learnt some energy, or an
    array of one per quadtree (0 where it learnt none is forced). ``structure``: a device tree of the
    same structure (the recording tree ``tree`` was trained in) whose arrays are shared, not copied;
    ``sampling`` False: a tree that only records (no probabilities uploaded)."""
    g = GuideTree()
    g.lo = wp.vec3(*[float(x) for x in tree.lo])
    g.hi = wp.vec3(*[float(x) for x in tree.hi])
    if structure is not None:
        g.s_axis, g.s_child, g.d_root, g.d_child = structure.s_axis, structure.s_child, structure.d_root, structure.d_child
    else:
        g.s_axis = wp.array(tree.s_axis.astype(np.int32), dtype=wp.int32, device=device)
        g.s_child = wp.array(tree.s_child.astype(np.int32), dtype=wp.int32, device=device)
        g.d_root = wp.array(tree.d_root.astype(np.int32), dtype=wp.int32, device=device)
        g.d_child = wp.array(tree.d_child.astype(np.int32), dtype=wp.int32, device=device)
    if not sampling:
        g.d_cond = wp.zeros(1, dtype=wp.vec4, device=device)
        g.q_alpha = wp.zeros(1, dtype=wp.float32, device=device)
        g.alpha = 0.0
        return g
    g.d_cond = wp.array(conditionals(tree.d_child, tree.d_energy), dtype=wp.vec4, device=device)
    learnt = np.asarray(tree.d_energy, np.float64)[tree.d_root] > 0.0
    a = np.where(learnt, np.broadcast_to(np.asarray(alpha, np.float64), learnt.shape), 0.0).astype(np.float32)
    g.q_alpha = wp.array(a, dtype=wp.float32, device=device)
    g.alpha = float(a.max()) if a.size else 0.0
    return g


def new_record(tree: GuideTree, nodes: int, on: bool, threads: int, slots: int, device: str,
               to_sampling: np.ndarray | None = None) -> GuideRecord:
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
    r.to_sampling = wp.array(np.zeros(1, np.int32) if to_sampling is None else to_sampling.astype(np.int32),
                             dtype=wp.int32, device=device)
    return r
