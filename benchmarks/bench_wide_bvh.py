"""Issue 24 prototype: can our own BVH traversal, written in Warp's Python DSL, beat wp.mesh_query_ray?

Go/no-go experiment (not used by the renderer). Triangles are put in a binned-SAH binary BVH built in
numpy (warp_spt.accel.tlas.build_tlas over the triangles' boxes), which is then used either as it is
(binary variants) or collapsed into 4- or 8-wide nodes whose child boxes are stored SoA, one
``vector(length=W)`` per coordinate, so that one node's W slab tests are a few vector operations
(Clang may turn them into AVX instructions: see --asm).

Every variant uses the renderer's triangle test (``accel.wide_traversal.triangle_hit``: Warp's
watertight ``intersect_ray_tri_woop`` in the DSL, the per-ray part hoisted out of the leaf loop), so
that t, u, v come out bit-identical to ``wp.mesh_query_ray``'s. Triangle vertices are copied
into leaf order (three vec3 arrays), so a leaf reads them without the index indirection.

Variants (rows):
    warp            wp.mesh_query_ray / wp.mesh_query_ray_anyhit on a wp.Mesh (sah, leaf size 2):
                    the reference, as in device_scene.py
    bin2            our binary tree, leaf size 2, near-far traversal (stack of node + entry distance)
    wide4 / wide8   the binary tree (leaf size 2 or 4) collapsed to 4 / 8 children per node

Rays: camera rays (warp_spt's Camera, sample 0 of each pixel, as bench_rays.camera_rays) and random
rays (origins in the middle 80% of the scene box, uniform directions), on the 46-triangle Cornell
box of bench_vs_mitsuba and on all triangles of the built-in demo (51,242: sculpture + room; its
spheres left out). Any-hit rays are the same rays with t_max = (closest t) * s, s uniform in
[0.5, 1.5) (about half occluded; t_max = 1e30 where the ray misses).

For closest hits the table counts rays whose face differs from Warp's, and how many of those are
ties (both hit, t within ~3 ulps): on these scenes every one is a pair of coincident coplanar
triangles (the Cornell boxes' bottoms lie in the floor), where the order of visits decides; t, u, v
are compared bit for bit on every ray with the same face. "wide4 leaf2 leaves at once" changes the
any-hit kernel only: its closest-hit row times the same kernel as "wide4 leaf2" again (a noise check).

Times: CPU time of the launching thread (time.thread_time) of one single-threaded launch, variants
interleaved, median of --repeat. Ratios compare rows of the same run only.

Measured 2026-11-24 (--size 256 --repeat 7 --asm, 2 shared cores, AVX2), ratio to Warp's rays/s:
closest hit: wide8 leaf2 1.82 / 1.77 / 1.81 / 1.86 (Cornell camera / random, demo camera / random),
wide4 leaf2 1.71 / 1.58 / 1.64 / 1.71; any hit: wide4 leaf2 1.49 / 1.84 / 1.51 / 1.95, wide8 leaf2
1.36 / 1.87 / 1.34 / 1.90. Our binary tree with the same code 0.82-0.94 (fminf slab test) and
1.09-1.28 (branch-free min/max). Leaves of 4, unsorted pushes, leaves tested at once: no better.

    python benchmarks/bench_wide_bvh.py                 # 256x256 camera rays, 65,536 random rays
    python benchmarks/bench_wide_bvh.py --size 128 --repeat 3
    python benchmarks/bench_wide_bvh.py --asm           # also: do the wide box tests vectorise?
"""

import argparse
import glob
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

import warp as wp

wp.config.log_level = wp.LOG_WARNING   # no banner or module-load lines (Warp 1.19 dropped config.quiet)

from warp_spt.accel.tlas import build_tlas
from warp_spt.upload.device_scene import MESH_LEAF_SIZE
from warp_spt.accel.wide_bvh import build_wide
from warp_spt.accel.wide_traversal import MeshRay as Ray
from warp_spt.accel.wide_traversal import mesh_ray as make_ray
from warp_spt.accel.wide_traversal import triangle_hit as tri_test

NO_HIT = 3.0e38
STACK = 64
OPTIONS = {"cpu_compiler_flags": "-march=native -mllvm=-inline-threshold=2000 -mllvm=-slp-recursion-max-depth=4"}
vec_stack_i = wp.types.vector(length=STACK, dtype=wp.int32)
vec_stack_f = wp.types.vector(length=STACK, dtype=wp.float32)


# --------------------------------------------------------------------------------------------
# Host build


class Tree:
    """A BVH over triangles in our layout (numpy), and its Warp arrays."""

    def __init__(self, points: np.ndarray, tris: np.ndarray, leaf: int, width: int, builder: str = "sah"):
        """builder "sah": build_tlas's binned-SAH binary tree, collapsed in Python (the prototype);
        "wide": warp_spt.accel.wide_bvh.build_wide (Morton order + SAH cuts, vectorised collapse)."""
        t0 = time.perf_counter()
        p = points.astype(np.float32)
        v = p[tris]                                          # (K, 3, 3) float32
        if builder == "wide":
            wb = build_wide(points, tris, width=width, max_leaf=leaf)
            self.binary_build_s = 0.0
            order = wb.order
            self.face = order.astype(np.int32)
            self.v0, self.v1, self.v2 = (np.ascontiguousarray(v[order, k]) for k in range(3))
            self.width, self.bt = width, None
            self.box, self.child, self.depth, self.stack_bound = wb.box, wb.child, wb.depth, wb.stack_bound
            self.num_nodes = wb.num_nodes
            if self.stack_bound > STACK:
                print(f"warning: build_wide's tree may need {self.stack_bound} stack entries > {STACK}")
            self.build_s = time.perf_counter() - t0
            self.upload()
            return
        lo, hi = v.min(axis=1).astype(np.float64), v.max(axis=1).astype(np.float64)
        bt = build_tlas(lo, hi, max_leaf=leaf)
        self.binary_build_s = time.perf_counter() - t0
        order = bt.items
        self.face = order.astype(np.int32)                   # leaf-order position -> triangle id
        self.v0, self.v1, self.v2 = (np.ascontiguousarray(v[order, k]) for k in range(3))
        self.width = width
        self.bt = bt
        self.depth = bt.depth
        if width == 2:
            self.num_nodes = bt.num_nodes
        else:
            self._collapse(bt, width)
        # deepest stack a traversal can need: every level leaves at most width - 1 entries behind
        self.stack_bound = 1 + self.depth * (width - 1)
        if self.stack_bound > STACK:
            print(f"warning: a {width}-wide tree of depth {self.depth} may need {self.stack_bound} stack entries "
                  f"> {STACK}; deeper entries would be dropped (the pushes are guarded, not the results)")
        self.build_s = time.perf_counter() - t0
        self.upload()

    def _collapse(self, bt, width: int) -> None:
        """Wide nodes from the binary tree: starting from a binary node's two children, repeatedly open
        the interior child with the largest surface area until there are ``width`` children."""
        lo, hi = bt.lower.astype(np.float64), bt.upper.astype(np.float64)
        ext = np.maximum(hi - lo, 0.0)
        area = ext[:, 0] * ext[:, 1] + ext[:, 1] * ext[:, 2] + ext[:, 2] * ext[:, 0]
        left, right, first, count = bt.left, bt.right, bt.first, bt.count
        if left[0] < 0:                                      # one leaf: a root with one child
            roots = [[0]]
        else:
            roots = None
        wide_children: list[list[int]] = []
        queue = [0]
        index_of = {0: 0}
        level = {0: 0}
        while queue:
            b = queue.pop(0)
            kids = [int(left[b]), int(right[b])] if left[b] >= 0 else [b]
            while len(kids) < width:
                inner = [k for k in kids if left[k] >= 0]
                if not inner:
                    break
                k = max(inner, key=lambda n: area[n])
                kids.remove(k)
                kids += [int(left[k]), int(right[k])]
            for k in kids:
                if left[k] >= 0 and k not in index_of:
                    index_of[k] = len(index_of)
                    level[k] = level[b] + 1
                    queue.append(k)
            wide_children.append(kids)
        del roots
        self.depth = max(level.values()) + 1                 # levels of wide nodes, leaves included
        m = len(wide_children)
        box = np.empty((m, 6, width), dtype=np.float32)
        box[:] = np.inf                                      # empty slot: lo = hi = +inf, never hit
        child = np.zeros((m, width), dtype=np.int32)
        for i, kids in enumerate(wide_children):
            for j, k in enumerate(kids):
                box[i, 0:3, j] = bt.lower[k]
                box[i, 3:6, j] = bt.upper[k]
                if left[k] >= 0:
                    child[i, j] = index_of[k]
                else:
                    child[i, j] = -(int(first[k]) * 8 + int(count[k])) - 1
        self.box, self.child = box, child
        self.num_nodes = m

    def upload(self) -> None:
        self.w_v0, self.w_v1, self.w_v2 = (wp.array(a, dtype=wp.vec3) for a in (self.v0, self.v1, self.v2))
        self.w_face = wp.array(self.face, dtype=wp.int32)
        bt = self.bt
        if bt is None:                                       # built by build_wide: no binary arrays
            bt = build_tlas(np.zeros((1, 3)), np.zeros((1, 3)))
        self.w_lo = wp.array(bt.lower, dtype=wp.vec3)
        self.w_hi = wp.array(bt.upper, dtype=wp.vec3)
        self.w_left = wp.array(bt.left, dtype=wp.int32)
        self.w_right = wp.array(bt.right, dtype=wp.int32)
        self.w_first = wp.array(bt.first, dtype=wp.int32)
        self.w_count = wp.array(bt.count, dtype=wp.int32)
        if self.width > 2:
            vf = wp.types.vector(length=self.width, dtype=wp.float32)
            vi = wp.types.vector(length=self.width, dtype=wp.int32)
            self.w_box = wp.array(self.box.reshape(-1, self.width), dtype=vf)
            self.w_child = wp.array(self.child, dtype=vi)


# --------------------------------------------------------------------------------------------
# The ray set-up and triangle test are the renderer's (accel.wide_traversal: Warp's watertight test,
# the per-ray shear hoisted); the "indexed" variant sets the ray up again per triangle, as Warp does.


@wp.func
def fmin_(a: float, b: float) -> float:
    return wp.where(a < b, a, b)


@wp.func
def fmax_(a: float, b: float) -> float:
    return wp.where(a > b, a, b)


@wp.func
def box_entry_fast(lo: wp.vec3, hi: wp.vec3, r: Ray, t_max: float) -> float:
    l1 = wp.cw_mul(lo - r.o, r.inv)
    l2 = wp.cw_mul(hi - r.o, r.inv)
    tmin = fmax_(fmax_(fmin_(l1[0], l2[0]), fmin_(l1[1], l2[1])), fmin_(l1[2], l2[2]))
    tmax = fmin_(fmin_(fmax_(l1[0], l2[0]), fmax_(l1[1], l2[1])), fmax_(l1[2], l2[2]))
    if tmax >= 0.0 and tmax >= tmin and tmin < t_max:
        return tmin
    return NO_HIT


@wp.func
def box_entry_fminf(lo: wp.vec3, hi: wp.vec3, r: Ray, t_max: float) -> float:
    """Entry distance of the ray into the box (Warp's fast slab test), NO_HIT when missed or beyond t_max."""
    l1 = wp.cw_mul(lo - r.o, r.inv)
    l2 = wp.cw_mul(hi - r.o, r.inv)
    tmin = wp.max(wp.max(wp.min(l1[0], l2[0]), wp.min(l1[1], l2[1])), wp.min(l1[2], l2[2]))
    tmax = wp.min(wp.min(wp.max(l1[0], l2[0]), wp.max(l1[1], l2[1])), wp.max(l1[2], l2[2]))
    if tmax >= 0.0 and tmax >= tmin and tmin < t_max:
        return tmin
    return NO_HIT


@wp.struct
class TriHit:
    t: float
    u: float
    v: float
    face: int


# --------------------------------------------------------------------------------------------
# Kernels


@wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
def warp_closest(mesh: wp.uint64, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3),
                 t_out: wp.array(dtype=wp.vec3), f_out: wp.array(dtype=int)):
    i = wp.tid()
    q = wp.mesh_query_ray(mesh, o[i], d[i], NO_HIT)
    if q.result:
        t_out[i] = wp.vec3(q.t, q.u, q.v)
        f_out[i] = q.face
    else:
        t_out[i] = wp.vec3(NO_HIT, 0.0, 0.0)
        f_out[i] = -1


@wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
def warp_any(mesh: wp.uint64, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), tmax: wp.array(dtype=float),
             out: wp.array(dtype=int)):
    i = wp.tid()
    out[i] = wp.where(wp.mesh_query_ray_anyhit(mesh, o[i], d[i], tmax[i]), 1, 0)


def binary_kernels(fast_minmax: bool = False):
    """Closest- and any-hit kernels over the binary tree (near-far order, entry distances on the stack).
    fast_minmax: the slab test's min/max as a < b ? a : b rather than wp.min/wp.max (fminf)."""

    @wp.func
    def box_entry(lo: wp.vec3, hi: wp.vec3, r: Ray, t_max: float) -> float:
        if wp.static(fast_minmax):
            return box_entry_fast(lo, hi, r, t_max)
        return box_entry_fminf(lo, hi, r, t_max)

    @wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
    def closest(lo: wp.array(dtype=wp.vec3), hi: wp.array(dtype=wp.vec3), left: wp.array(dtype=int),
                right: wp.array(dtype=int), first: wp.array(dtype=int), count: wp.array(dtype=int),
                v0: wp.array(dtype=wp.vec3), v1: wp.array(dtype=wp.vec3), v2: wp.array(dtype=wp.vec3),
                face: wp.array(dtype=int), o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3),
                t_out: wp.array(dtype=wp.vec3), f_out: wp.array(dtype=int)):
        i = wp.tid()
        r = make_ray(o[i], d[i])
        best = TriHit()
        best.t = NO_HIT
        best.face = -1
        nodes = vec_stack_i()
        entries = vec_stack_f()
        sp = int(0)
        t_root = box_entry(lo[0], hi[0], r, best.t)
        if t_root < NO_HIT:
            nodes[0] = 0
            entries[0] = t_root
            sp = 1
        while sp > 0:
            sp -= 1
            node = nodes[sp]
            if entries[sp] >= best.t:
                continue
            le = left[node]
            if le < 0:
                f0 = first[node]
                for k in range(f0, f0 + count[node]):
                    h, t, u, v = tri_test(r, v0[k], v1[k], v2[k])
                    if h and t < best.t and t >= 0.0:
                        best.t = t
                        best.u = u
                        best.v = v
                        best.face = face[k]
            else:
                ri = right[node]
                tl = box_entry(lo[le], hi[le], r, best.t)
                tr = box_entry(lo[ri], hi[ri], r, best.t)
                near_node = le
                near_t = tl
                far_node = ri
                far_t = tr
                if tr < tl:
                    near_node = ri
                    near_t = tr
                    far_node = le
                    far_t = tl
                if far_t < NO_HIT:
                    nodes[sp] = far_node
                    entries[sp] = far_t
                    sp += 1
                if near_t < NO_HIT:
                    nodes[sp] = near_node
                    entries[sp] = near_t
                    sp += 1
        t_out[i] = wp.vec3(best.t, best.u, best.v)
        f_out[i] = best.face

    @wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
    def anyhit(lo: wp.array(dtype=wp.vec3), hi: wp.array(dtype=wp.vec3), left: wp.array(dtype=int),
               right: wp.array(dtype=int), first: wp.array(dtype=int), count: wp.array(dtype=int),
               v0: wp.array(dtype=wp.vec3), v1: wp.array(dtype=wp.vec3), v2: wp.array(dtype=wp.vec3),
               face: wp.array(dtype=int), o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), tmax: wp.array(dtype=float),
               out: wp.array(dtype=int)):
        i = wp.tid()
        r = make_ray(o[i], d[i])
        t_max = tmax[i]
        nodes = vec_stack_i()
        sp = int(0)
        if box_entry(lo[0], hi[0], r, t_max) < NO_HIT:
            nodes[0] = 0
            sp = 1
        found = int(0)
        while sp > 0:
            sp -= 1
            node = nodes[sp]
            le = left[node]
            if le < 0:
                f0 = first[node]
                for k in range(f0, f0 + count[node]):
                    h, t, u, v = tri_test(r, v0[k], v1[k], v2[k])
                    if h and t < t_max and t >= 0.0:
                        found = 1
                if found == 1:
                    break
            else:
                ri = right[node]
                if box_entry(lo[ri], hi[ri], r, t_max) < NO_HIT:
                    nodes[sp] = ri
                    sp += 1
                if box_entry(lo[le], hi[le], r, t_max) < NO_HIT:
                    nodes[sp] = le
                    sp += 1
        out[i] = found

    return closest, anyhit


def wide_kernels(width: int, sort: bool = True, fast_minmax: bool = True, indexed: bool = False,
                 leaf_now: bool = False):
    """Closest- and any-hit kernels over ``width``-wide nodes. A node is 6 consecutive vectors of the box
    array (lower x, y, z, upper x, y, z of its children) and one vector of children: >= 0 an interior
    node, < 0 a leaf -(first * 8 + count) - 1. The ray picks each axis' near plane once (lower where
    1/d >= 0), so a node's test is 6 vector subtract-multiplies and 4 min/max, no per-child branches
    until the pushes. sort: the closest-hit pushes its hit children nearest on top (insertion sort).
    fast_minmax: per-lane a < b ? a : b instead of wp.min/wp.max (fminf). indexed: triangles read as
    Warp does (face -> 3 indices -> points) with the shear set up again per triangle, instead of the
    leaf-ordered vertex copies and the hoisted per-ray setup. leaf_now (any-hit only): a node's leaf
    children are tested at once, in child order, instead of pushed."""

    @wp.func
    def leaf_test(r: Ray, k: int, v0: wp.array(dtype=wp.vec3), v1: wp.array(dtype=wp.vec3),
                  v2: wp.array(dtype=wp.vec3), face: wp.array(dtype=int), pts: wp.array(dtype=wp.vec3),
                  idx: wp.array(dtype=int)):
        if wp.static(indexed):
            f = face[k]
            return tri_test(make_ray(r.o, r.d), pts[idx[3 * f]], pts[idx[3 * f + 1]], pts[idx[3 * f + 2]])
        return tri_test(r, v0[k], v1[k], v2[k])
    vf = wp.types.vector(length=width, dtype=wp.float32)
    vi = wp.types.vector(length=width, dtype=wp.int32)

    @wp.func
    def vmin(a: vf, b: vf) -> vf:
        # a < b ? a : b per lane (one vminps); wp.min is fminf (NaN-aware), which does not vectorise
        out = vf()
        for j in range(wp.static(width)):
            out[j] = wp.where(a[j] < b[j], a[j], b[j])
        return out

    @wp.func
    def vmax(a: vf, b: vf) -> vf:
        out = vf()
        for j in range(wp.static(width)):
            out[j] = wp.where(a[j] > b[j], a[j], b[j])
        return out

    @wp.func
    def node_dist(box: wp.array(dtype=vf), node: int, nx: int, ny: int, nz: int, ox: vf, oy: vf, oz: vf,
                  ix: vf, iy: vf, iz: vf, t_max: float) -> vf:
        b = node * 6
        if wp.static(fast_minmax):
            tn = vmax(vmax(wp.cw_mul(box[b + nx] - ox, ix), wp.cw_mul(box[b + ny] - oy, iy)),
                      vmax(wp.cw_mul(box[b + nz] - oz, iz), vf(0.0)))
            tf = vmin(vmin(wp.cw_mul(box[b + 3 - nx] - ox, ix), wp.cw_mul(box[b + 5 - ny] - oy, iy)),
                      vmin(wp.cw_mul(box[b + 7 - nz] - oz, iz), vf(t_max)))
        else:
            tn = wp.max(wp.max(wp.cw_mul(box[b + nx] - ox, ix), wp.cw_mul(box[b + ny] - oy, iy)),
                        wp.max(wp.cw_mul(box[b + nz] - oz, iz), vf(0.0)))
            tf = wp.min(wp.min(wp.cw_mul(box[b + 3 - nx] - ox, ix), wp.cw_mul(box[b + 5 - ny] - oy, iy)),
                        wp.min(wp.cw_mul(box[b + 7 - nz] - oz, iz), vf(t_max)))
        out = vf()
        for j in range(wp.static(width)):
            out[j] = wp.where(tn[j] <= tf[j], tn[j], NO_HIT)
        return out

    @wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
    def closest(box: wp.array(dtype=vf), child: wp.array(dtype=vi),
                v0: wp.array(dtype=wp.vec3), v1: wp.array(dtype=wp.vec3), v2: wp.array(dtype=wp.vec3),
                face: wp.array(dtype=int), pts: wp.array(dtype=wp.vec3), idx: wp.array(dtype=int),
                o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3),
                t_out: wp.array(dtype=wp.vec3), f_out: wp.array(dtype=int)):
        i = wp.tid()
        r = make_ray(o[i], d[i])
        nx = wp.where(r.inv[0] >= 0.0, 0, 3)
        ny = wp.where(r.inv[1] >= 0.0, 1, 4)
        nz = wp.where(r.inv[2] >= 0.0, 2, 5)
        ox = vf(r.o[0])
        oy = vf(r.o[1])
        oz = vf(r.o[2])
        ix = vf(r.inv[0])
        iy = vf(r.inv[1])
        iz = vf(r.inv[2])
        best = TriHit()
        best.t = NO_HIT
        best.face = -1
        nodes = vec_stack_i()
        entries = vec_stack_f()
        nodes[0] = 0
        entries[0] = 0.0
        sp = int(1)
        while sp > 0:
            sp -= 1
            if entries[sp] >= best.t:
                continue
            node = nodes[sp]
            if node < 0:
                e = -node - 1
                f0 = e >> 3
                for k in range(f0, f0 + (e & 7)):
                    h, t, u, v = leaf_test(r, k, v0, v1, v2, face, pts, idx)
                    if h and t < best.t and t >= 0.0:
                        best.t = t
                        best.u = u
                        best.v = v
                        best.face = face[k]
            else:
                dist = node_dist(box, node, nx, ny, nz, ox, oy, oz, ix, iy, iz, best.t)
                ch = child[node]
                base = sp
                for j in range(wp.static(width)):
                    if dist[j] < NO_HIT and sp < wp.static(STACK):
                        nodes[sp] = ch[j]
                        entries[sp] = dist[j]
                        sp += 1
                if wp.static(sort):
                    # nearest on top: entries[base:sp] descending
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
        t_out[i] = wp.vec3(best.t, best.u, best.v)
        f_out[i] = best.face

    @wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
    def anyhit(box: wp.array(dtype=vf), child: wp.array(dtype=vi),
               v0: wp.array(dtype=wp.vec3), v1: wp.array(dtype=wp.vec3), v2: wp.array(dtype=wp.vec3),
               face: wp.array(dtype=int), pts: wp.array(dtype=wp.vec3), idx: wp.array(dtype=int),
               o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3),
               tmax: wp.array(dtype=float), out: wp.array(dtype=int)):
        i = wp.tid()
        r = make_ray(o[i], d[i])
        t_max = tmax[i]
        nx = wp.where(r.inv[0] >= 0.0, 0, 3)
        ny = wp.where(r.inv[1] >= 0.0, 1, 4)
        nz = wp.where(r.inv[2] >= 0.0, 2, 5)
        ox = vf(r.o[0])
        oy = vf(r.o[1])
        oz = vf(r.o[2])
        ix = vf(r.inv[0])
        iy = vf(r.inv[1])
        iz = vf(r.inv[2])
        nodes = vec_stack_i()
        nodes[0] = 0
        sp = int(1)
        found = int(0)
        while sp > 0:
            sp -= 1
            node = nodes[sp]
            if node < 0:
                e = -node - 1
                f0 = e >> 3
                for k in range(f0, f0 + (e & 7)):
                    h, t, u, v = leaf_test(r, k, v0, v1, v2, face, pts, idx)
                    if h and t < t_max and t >= 0.0:
                        found = 1
                if found == 1:
                    break
            else:
                dist = node_dist(box, node, nx, ny, nz, ox, oy, oz, ix, iy, iz, t_max)
                ch = child[node]
                for j in range(wp.static(width)):
                    if dist[j] < NO_HIT and sp < wp.static(STACK):
                        c = ch[j]
                        if wp.static(leaf_now) and c < 0:
                            if found == 0:
                                e = -c - 1
                                f0 = e >> 3
                                for k in range(f0, f0 + (e & 7)):
                                    h, t, u, v = leaf_test(r, k, v0, v1, v2, face, pts, idx)
                                    if h and t < t_max and t >= 0.0:
                                        found = 1
                        else:
                            nodes[sp] = c
                            sp += 1
                if wp.static(leaf_now):
                    if found == 1:
                        break
        out[i] = found

    return closest, anyhit


# --------------------------------------------------------------------------------------------
# Scenes and rays


def scene_data(tmp: Path):
    """[(name, points, tris (K, 3), camera rays (o, d) as wp arrays, scene box)]."""
    import bench_rays as br

    from warp_spt.upload.device_scene import DeviceScene
    from warp_spt.demo import demo_files
    from warp_spt.io.loader import load_scene
    from warp_spt.scene.camera import Camera

    _name, dev, cam, _sky = br.mitsuba_cornell(tmp)
    yield "cornell (bench_vs_mitsuba)", dev, cam
    objs, mtls = demo_files()
    dev = DeviceScene(load_scene(objs, mtls, warn=lambda m: None))
    yield "built-in demo (triangles)", dev, Camera()


def merged(dev) -> tuple[np.ndarray, np.ndarray]:
    pts, idx, base = [], [], 0
    for m in dev.scene.meshes:
        pts.append(np.asarray(m.positions, dtype=np.float32))
        idx.append(np.asarray(m.indices, dtype=np.int64).reshape(-1, 3) + base)
        base += len(m.positions)
    return np.concatenate(pts), np.concatenate(idx)


def interleaved(runs: dict, repeat: int) -> dict[str, float]:
    for fn in runs.values():
        fn()
    times = {k: [] for k in runs}
    for _ in range(repeat):
        for k, fn in runs.items():
            t = time.thread_time()
            fn()
            wp.synchronize()
            times[k].append(time.thread_time() - t)
    return {k: float(np.median(v)) for k, v in times.items()}


def compare_closest(ref_t: np.ndarray, ref_f: np.ndarray, t: np.ndarray, f: np.ndarray) -> tuple[int, int, float, bool]:
    """(face disagreements, of which ties, max |t - t_ref| over rays hit by both, t/u/v bit-identical
    on the rays with the same face)."""
    hit = (ref_f >= 0) & (f >= 0)
    diff = ref_f != f
    dt = np.abs(t[:, 0].astype(np.float64) - ref_t[:, 0])
    # a tie: both hit, different faces, same t to ~1 ulp (an edge or vertex shared by two triangles)
    ties = int(np.sum(diff & hit & (dt <= 4e-7 * np.maximum(1.0, np.abs(ref_t[:, 0])))))
    same = ~diff
    bits = bool(np.array_equal(t[same].view(np.uint32), ref_t[same].view(np.uint32)))
    return int(diff.sum()), ties, float(dt[hit].max()) if hit.any() else 0.0, bits


VARIANTS = [  # label, width, leaf size, options of wide_kernels
    ("bin2", 2, 2, {}),
    ("bin2 fast min/max", 2, 2, dict(fast_minmax=True)),
    ("wide4 leaf2 fminf", 4, 2, dict(fast_minmax=False)),
    ("wide4 leaf2", 4, 2, {}),
    ("wide4 leaf4", 4, 4, {}),
    ("wide8 leaf2", 8, 2, {}),
    ("wide8 leaf4", 8, 4, {}),
    ("wide4 leaf2 unsorted", 4, 2, dict(sort=False)),
    ("wide4 leaf2 indexed tris", 4, 2, dict(indexed=True)),
    ("wide8 leaf2 unsorted", 8, 2, dict(sort=False)),
    ("wide4 leaf2 leaves at once", 4, 2, dict(leaf_now=True)),
    ("wide8 leaf2 build_wide", 8, 2, dict(builder="wide")),
    ("wide4 leaf2 build_wide", 4, 2, dict(builder="wide")),
]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=256, help="camera rays: size x size; random rays: as many")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--scene", default="")
    ap.add_argument("--variants", default="", help="comma-separated labels (default: all)")
    ap.add_argument("--asm", action="store_true", help="report vector instructions in the wide kernels' object code")
    args = ap.parse_args()
    wp.init()
    import bench_rays as br
    wanted = [v for v in VARIANTS if not args.variants or v[0] in args.variants.split(",")]
    kernels, by_code = {}, {}
    for label, width, _leaf, opts in wanted:
        # variants that differ only in the tree builder share one compiled kernel pair
        kopts = {k: v for k, v in opts.items() if k != "builder"}
        key = (width, tuple(sorted(kopts.items())))
        if key not in by_code:
            by_code[key] = binary_kernels(**kopts) if width == 2 else wide_kernels(width, **kopts)
        kernels[label] = by_code[key]
    for k in [warp_closest, warp_any] + [k for pair in by_code.values() for k in pair]:
        wp.load_module(k.module, device="cpu")
    print(f"# bench_wide_bvh: {os.cpu_count()} cores, load {os.getloadavg()[0]:.2f}, one thread, CPU s median of "
          f"{args.repeat}, camera rays {args.size}x{args.size}, random rays {args.size * args.size}")
    print("| scene | tris | rays | query | variant | nodes (depth) | build s | Mrays/s | ratio to warp | "
          "face diffs (ties) / any-hit diffs | max abs dt | t,u,v bit-identical |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, dev, cam in scene_data(Path(tmp)):
            if args.scene not in name:
                continue
            pts, tris = merged(dev)
            t0 = time.perf_counter()
            mesh = wp.Mesh(points=wp.array(pts, dtype=wp.vec3), indices=wp.array(tris.reshape(-1).astype(np.int32),
                           dtype=wp.int32), bvh_constructor="sah", bvh_leaf_size=MESH_LEAF_SIZE)
            warp_build = time.perf_counter() - t0
            mesh_idx = wp.array(tris.reshape(-1).astype(np.int32), dtype=wp.int32)
            trees = {}
            for label, width, leaf, opts in wanted:
                trees[label] = Tree(pts, tris, leaf, width, builder=opts.get("builder", "sah"))
            for ray_kind in ("camera", "random"):
                if ray_kind == "camera":
                    o, d = br.camera_rays(dev, cam, args.size)
                else:
                    o, d = br.random_rays(dev.scene.bounds, args.size * args.size)
                n = o.shape[0]
                ref_t, ref_f = wp.zeros(n, dtype=wp.vec3), wp.zeros(n, dtype=int)
                wp.launch(warp_closest, dim=n, inputs=[mesh.id, o, d, ref_t, ref_f], device="cpu")
                rt, rf = ref_t.numpy(), ref_f.numpy()
                s = np.random.default_rng(7).uniform(0.5, 1.5, n).astype(np.float32)
                tmax = wp.array(np.where(rf >= 0, np.minimum(rt[:, 0], 1e30) * s, 1e30).astype(np.float32), dtype=float)
                ref_any = wp.zeros(n, dtype=int)
                wp.launch(warp_any, dim=n, inputs=[mesh.id, o, d, tmax, ref_any], device="cpu")
                ra = ref_any.numpy()
                outs, runs = {}, {}
                runs[("closest", "warp")] = lambda: wp.launch(warp_closest, dim=n, inputs=[mesh.id, o, d, ref_t, ref_f])
                runs[("any", "warp")] = lambda: wp.launch(warp_any, dim=n, inputs=[mesh.id, o, d, tmax, ref_any])
                for label, width, leaf, _opts in wanted:
                    tr = trees[label]
                    kc, ka = kernels[label]
                    tris_args = [tr.w_v0, tr.w_v1, tr.w_v2, tr.w_face]
                    if width == 2:
                        node_args = [tr.w_lo, tr.w_hi, tr.w_left, tr.w_right, tr.w_first, tr.w_count]
                    else:
                        node_args = [tr.w_box, tr.w_child]
                        tris_args = tris_args + [mesh.points, mesh_idx]
                    ot, of, oa = wp.zeros(n, dtype=wp.vec3), wp.zeros(n, dtype=int), wp.zeros(n, dtype=int)
                    outs[label] = (ot, of, oa)
                    runs[("closest", label)] = (lambda kc=kc, a=node_args + tris_args, ot=ot, of=of:
                                                wp.launch(kc, dim=n, inputs=[*a, o, d, ot, of]))
                    runs[("any", label)] = (lambda ka=ka, a=node_args + tris_args, oa=oa:
                                            wp.launch(ka, dim=n, inputs=[*a, o, d, tmax, oa]))
                times = interleaved(runs, args.repeat)
                print(f"| {name} | {len(tris)} | {ray_kind} {n} ({np.mean(rf >= 0):.0%} hit, {np.mean(ra):.0%} "
                      f"occluded) | | warp | | {warp_build:.3f} | | | | | |")
                for query in ("closest", "any"):
                    base = times[(query, "warp")]
                    print(f"| | | | {query} | warp (mesh_query_ray{'_anyhit' if query == 'any' else ''}) | | | "
                          f"{n / base / 1e6:.2f} | 1.00 | | | |")
                    for label, width, leaf, _opts in wanted:
                        tr = trees[label]
                        ot, of, oa = outs[label]
                        if query == "closest":
                            nd, ties, dtmax, bits = compare_closest(rt, rf, ot.numpy(), of.numpy())
                            agree = f"{nd} ({ties})"
                            extra = f"{dtmax:.3g} | {'yes' if bits else 'NO'}"
                        else:
                            agree = f"{int(np.sum(oa.numpy() != ra))}"
                            extra = " | "
                        sec = times[(query, label)]
                        print(f"| | | | {query} | {label} | {tr.num_nodes} ({tr.depth}) | {tr.build_s:.3f} | {n / sec / 1e6:.2f} | "
                              f"**{base / sec:.2f}** | {agree} | {extra} |", flush=True)
    if args.asm:
        report_asm(kernels)


def report_asm(kernels: dict) -> None:
    """Packed-single AVX instructions (v...ps) on ymm (8 lanes) and xmm (4 lanes) registers, and fminf-style
    blends, in each kernel's object file in the kernel cache: did the wide box test vectorise?"""
    import re
    cache = wp.config.kernel_cache_dir
    print("\n| kernel | instructions | packed sub/mul/min/max/cmp/blend on ymm | on xmm | vminps/vmaxps | vblendvps |")
    print("|---|---|---|---|---|---|")
    for label, pair in kernels.items():
        for k in pair:
            objs = glob.glob(os.path.join(cache, f"wp_{k.module.name}_*", "*.o"))
            if not objs:
                continue
            try:
                text = subprocess.run(["objdump", "-d", "--no-show-raw-insn", max(objs, key=os.path.getmtime)],
                                      check=False, capture_output=True, text=True).stdout.splitlines()
            except FileNotFoundError:
                print("objdump not found")
                return
            ps = [ln for ln in text if re.search(r"\sv(sub|mul|min|max|cmp\w*|blendv)ps\s", ln)]
            print(f"| {label} {k.key.split('.')[-1]} | {len(text)} | {sum('ymm' in ln for ln in ps)} | "
                  f"{sum('xmm' in ln and 'ymm' not in ln for ln in ps)} | "
                  f"{sum(re.search(r'v(min|max)ps', ln) is not None for ln in ps)} | "
                  f"{sum('vblendvps' in ln for ln in ps)} |")


if __name__ == "__main__":
    main()
