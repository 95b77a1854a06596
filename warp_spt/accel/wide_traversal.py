"""Ray queries inside a mesh: our own traversal of its wide BVH (``accel.wide_bvh``), in Warp.

Why not ``wp.mesh_query_ray``: Warp's query walks a binary tree one box at a time; a node of ours
holds eight child boxes stored lane by lane, so its eight slab tests are a handful of AVX
instructions. On the same rays this traverses 1.7-1.9x as many closest-hit rays per second and
1.35-1.95x as many shadow rays (benchmarks/bench_wide_bvh.py; docs/performance.md).

Same answers as Warp's query: the triangle test is Warp's watertight test (Woop, Benthin and Wald
2013, as ``intersect_ray_tri_woop`` in Warp's intersect.h computes it: the same operations in the
same order, with the fused multiply-adds where Warp's C++ has them), so a hit's t, u, v and normal are
bit for bit Warp's. Only the order of visits differs, which decides exact ties in t (two coincident
triangles).

The per-ray part of that test (axis permutation and shear) is computed once per ray (:class:`MeshRay`)
instead of once per triangle, and leaves read their triangles' corners from leaf-ordered copies
(``Geometry.tri_v0..2``) instead of through the index buffer.
"""

from __future__ import annotations

import warp as wp

from warp_spt.device.structs import Geometry, vec_wide_f
from warp_spt.accel.wide_bvh import WIDTH

NO_HIT = wp.constant(3.0e38)     # "no hit" distance of every query (accel.ray_queries re-exports it)
# The far side of every box test is scaled by two ulps, so rounding never rejects a grazing hit
# (the boxes are rounded outward already; this covers the slab arithmetic).
_FAR_SLACK = wp.constant(1.0000004)


@wp.func_native("return fmaf(a, b, c);")
def fmaf(a: float, b: float, c: float) -> float:
    """a * b + c with one rounding (C's fmaf): Warp's DSL has no fused multiply-add of its own."""
    ...


@wp.func
def diff_product(a: float, b: float, c: float, d: float) -> float:
    """a b - c d with Kahan's fma correction (the watertight test's 2x2 determinants)."""
    cd = c * d
    return fmaf(a, b, -cd) + fmaf(-c, d, cd)


@wp.struct
class MeshRay:
    """A ray set up for mesh queries: its slab-test inverse, the near planes' rows and the shear."""

    o: wp.vec3
    d: wp.vec3
    inv: wp.vec3        # 1 / d, zero components replaced by 1e-20 first (as Warp's query does)
    near: wp.vec3i      # per axis, the box row of the plane the ray enters by (lower 0-2 or upper 3-5)
    kx: int             # the watertight test's axes: kz the largest |d| component
    ky: int
    kz: int
    sx: float           # shear constants
    sy: float
    sz: float


@wp.func
def mesh_ray(o: wp.vec3, d: wp.vec3) -> MeshRay:
    """The ray o + t d set up once for every mesh query it makes."""
    r = MeshRay()
    r.o = o
    r.d = d
    sd = d
    for a in range(3):
        if sd[a] == 0.0:
            sd[a] = 1.0e-20
    r.inv = wp.vec3(1.0 / sd[0], 1.0 / sd[1], 1.0 / sd[2])
    r.near = wp.vec3i(wp.where(r.inv[0] >= 0.0, 0, 3), wp.where(r.inv[1] >= 0.0, 1, 4),
                      wp.where(r.inv[2] >= 0.0, 2, 5))
    # the first axis of largest |d| (a later axis replaces it only when strictly larger)
    kz = int(0)
    big = wp.abs(d[0])
    if wp.abs(d[1]) > big:
        kz = 1
        big = wp.abs(d[1])
    if wp.abs(d[2]) > big:
        kz = 2
    kx = (kz + 1) % 3
    ky = (kx + 1) % 3
    if d[kz] < 0.0:         # keep the winding: swap when the major axis points backwards
        tmp = kx
        kx = ky
        ky = tmp
    r.kx = kx
    r.ky = ky
    r.kz = kz
    r.sx = d[kx] / d[kz]
    r.sy = d[ky] / d[kz]
    r.sz = 1.0 / d[kz]
    return r


@wp.func
def triangle_hit(r: MeshRay, a: wp.vec3, b: wp.vec3, c: wp.vec3):
    """(hit, t, u, v) of the watertight test; t may be negative (callers keep 0 <= t < t_max)."""
    pa = a - r.o
    pb = b - r.o
    pc = c - r.o
    ax = pa[r.kx] - r.sx * pa[r.kz]
    ay = pa[r.ky] - r.sy * pa[r.kz]
    bx = pb[r.kx] - r.sx * pb[r.kz]
    by = pb[r.ky] - r.sy * pb[r.kz]
    cx = pc[r.kx] - r.sx * pc[r.kz]
    cy = pc[r.ky] - r.sy * pc[r.kz]
    u = diff_product(cx, by, cy, bx)
    v = diff_product(ax, cy, ay, cx)
    w = diff_product(bx, ay, by, ax)
    if u == 0.0 or v == 0.0 or w == 0.0:
        # on an edge in float32: decide in double precision, so the edge belongs to one side only
        u = float(wp.float64(cx) * wp.float64(by) - wp.float64(cy) * wp.float64(bx))
        v = float(wp.float64(ax) * wp.float64(cy) - wp.float64(ay) * wp.float64(cx))
        w = float(wp.float64(bx) * wp.float64(ay) - wp.float64(by) * wp.float64(ax))
    if (u < 0.0 or v < 0.0 or w < 0.0) and (u > 0.0 or v > 0.0 or w > 0.0):
        return False, 0.0, 0.0, 0.0
    det = u + v + w
    if det == 0.0:
        return False, 0.0, 0.0, 0.0
    t = u * (r.sz * pa[r.kz]) + v * (r.sz * pb[r.kz]) + w * (r.sz * pc[r.kz])
    if (det > 0.0 and t < 0.0) or (det < 0.0 and t > 0.0):
        return False, 0.0, 0.0, 0.0
    rcp = 1.0 / det
    return True, t * rcp, u * rcp, v * rcp


@wp.func
def lanes_max(a: vec_wide_f, b: vec_wide_f) -> vec_wide_f:
    """Per lane a > b ? a : b (one vmaxps; wp.max is NaN-aware fmaxf, which does not vectorise)."""
    out = vec_wide_f()
    for j in range(wp.static(WIDTH)):
        out[j] = wp.where(a[j] > b[j], a[j], b[j])
    return out


@wp.func
def lanes_min(a: vec_wide_f, b: vec_wide_f) -> vec_wide_f:
    """Per lane a < b ? a : b."""
    out = vec_wide_f()
    for j in range(wp.static(WIDTH)):
        out[j] = wp.where(a[j] < b[j], a[j], b[j])
    return out


@wp.func
def child_entries(g: Geometry, node: int, r: MeshRay, t_max: float) -> vec_wide_f:
    """Per child of ``node``: the distance at which the ray enters its box, NO_HIT when it misses it
    or enters beyond ``t_max`` (empty slots always miss)."""
    b = node * 6
    ox = vec_wide_f(r.o[0])
    oy = vec_wide_f(r.o[1])
    oz = vec_wide_f(r.o[2])
    ix = vec_wide_f(r.inv[0])
    iy = vec_wide_f(r.inv[1])
    iz = vec_wide_f(r.inv[2])
    t_in = lanes_max(lanes_max(wp.cw_mul(g.bvh_box[b + r.near[0]] - ox, ix),
                               wp.cw_mul(g.bvh_box[b + r.near[1]] - oy, iy)),
                     lanes_max(wp.cw_mul(g.bvh_box[b + r.near[2]] - oz, iz), vec_wide_f(0.0)))
    t_out = lanes_min(lanes_min(wp.cw_mul(g.bvh_box[b + 3 - r.near[0]] - ox, ix),
                                wp.cw_mul(g.bvh_box[b + 5 - r.near[1]] - oy, iy)),
                      lanes_min(wp.cw_mul(g.bvh_box[b + 7 - r.near[2]] - oz, iz), vec_wide_f(t_max)))
    out = vec_wide_f()
    for j in range(wp.static(WIDTH)):
        out[j] = wp.where(t_in[j] <= t_out[j] * _FAR_SLACK, t_in[j], NO_HIT)
    return out


@wp.func
def leaf_range(node: int):
    """(first, end): the leaf-order triangles of a leaf child ``node`` < 0, -(first * 8 + count) - 1
    (accel.wide_bvh's encoding)."""
    code = -node - 1
    first = code >> 3
    return first, first + (code & 7)


def make_closest_query(stack: int):
    """``closest(g, mesh, r, t_max) -> (k, t, u, v)`` over the meshes' wide BVHs with a traversal stack
    of ``stack`` entries (``Features.bvh_stack``: enough for every mesh of the scene, see
    ``WideBvh.stack_bound``; a short stack is cheaper, as each query zeroes it)."""
    vec_stack_i = wp.types.vector(length=stack, dtype=wp.int32)
    vec_stack_f = wp.types.vector(length=stack, dtype=wp.float32)

    @wp.func(inline=True)
    def closest(g: Geometry, mesh: int, r: MeshRay, t_max: float):
        """(k, t, u, v): the nearest hit with 0 <= t < t_max in ``mesh`` (k its leaf-order position,
        -1 if none), children visited nearest first."""
        best_k = int(-1)
        best_t = t_max
        best_u = float(0.0)
        best_v = float(0.0)
        nodes = vec_stack_i()
        entries = vec_stack_f()
        nodes[0] = g.mesh_root[mesh]
        entries[0] = 0.0
        sp = int(1)
        while sp > 0:
            sp -= 1
            if entries[sp] >= best_t:
                continue
            node = nodes[sp]
            if node < 0:
                first, end = leaf_range(node)
                for k in range(first, end):
                    h, t, u, v = triangle_hit(r, g.tri_v0[k], g.tri_v1[k], g.tri_v2[k])
                    if h and t < best_t and t >= 0.0:
                        best_k = k
                        best_t = t
                        best_u = u
                        best_v = v
            else:
                dist = child_entries(g, node, r, best_t)
                kids = g.bvh_child[node]
                base = sp
                for j in range(wp.static(WIDTH)):
                    if dist[j] < NO_HIT:
                        nodes[sp] = kids[j]
                        entries[sp] = dist[j]
                        sp += 1
                # the nearest child on top: entries[base:sp] sorted in decreasing order
                for a in range(base + 1, sp):
                    kn = nodes[a]
                    kd = entries[a]
                    b = a - 1
                    while b >= base and entries[b] < kd:
                        nodes[b + 1] = nodes[b]
                        entries[b + 1] = entries[b]
                        b -= 1
                    nodes[b + 1] = kn
                    entries[b + 1] = kd
        return best_k, best_t, best_u, best_v

    return closest


def make_any_hit_query(stack: int):
    """``any_hit(g, mesh, r, t_max) -> bool`` over the meshes' wide BVHs, stack as
    :func:`make_closest_query`'s."""
    vec_stack_i = wp.types.vector(length=stack, dtype=wp.int32)

    @wp.func(inline=True)
    def any_hit(g: Geometry, mesh: int, r: MeshRay, t_max: float) -> bool:
        """True when some triangle of ``mesh`` lies on the ray at 0 <= t < t_max (stops at the first)."""
        nodes = vec_stack_i()
        nodes[0] = g.mesh_root[mesh]
        sp = int(1)
        while sp > 0:
            sp -= 1
            node = nodes[sp]
            if node < 0:
                first, end = leaf_range(node)
                for k in range(first, end):
                    h, t, u, v = triangle_hit(r, g.tri_v0[k], g.tri_v1[k], g.tri_v2[k])
                    if h and t < t_max and t >= 0.0:
                        return True
            else:
                dist = child_entries(g, node, r, t_max)
                kids = g.bvh_child[node]
                for j in range(wp.static(WIDTH)):
                    if dist[j] < NO_HIT:
                        nodes[sp] = kids[j]
                        sp += 1
        return False

    return any_hit
