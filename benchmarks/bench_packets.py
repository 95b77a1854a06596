"""Issue 33: filling the vector lanes on the CPU. Packets or a wavefront, measured against today's
scalar traversal on the same rays (a prototype: nothing here is used by the renderer).

Ways to trace the same rays through the same 8-wide BVH (``accel.wide_bvh.build_wide``):

    scalar      today's traversal: one ray per Warp thread, ``accel.wide_traversal.make_closest_query``
                exactly as the path kernel calls it (its 8 slab tests of a node are one AVX op each)
    scalar W-wide, arrays
                the same traversal re-typed for W = 8 or 16 children per node (boxes and children
                passed as arrays: the Geometry struct's are typed 8-wide); 8 checks the copy against
                the renderer's, 16 fills an AVX-512 register with one ray's slab tests
    packet P    one Warp thread traces P = 8 or 16 coherent rays (a 4x2 or 4x4 pixel tile; for the
                bounce, the bounce rays of that tile) with one shared stack and an active mask: a
                node is fetched once for the whole packet and each child's slab test runs over the P
                rays at once (whole-vector operations on ``vector(length=P)``, loops clang may map
                onto one AVX-512 or two AVX2 registers). A stack entry carries the mask of the rays
                that hit the node and the nearest of their entry distances. Leaves test each active
                ray with the renderer's watertight triangle test (per ray, scalar), so a hit's t, u, v
                are bit for bit the scalar traversal's; only exact ties in t may pick another face.
    packet P mem
                the same, the packet's origins, inverse directions and nearest hits kept in a scratch
                row of the thread and re-read at every box test (vector loads instead of values clang
                must gather from scalar registers: the variant where clang does emit zmm arithmetic)
    wavefront   the pass split into launches over arrays: generate camera rays, intersect, shade
                (a diffuse bounce), intersect the bounce rays, shade; against the same pass as one
                "megakernel" (one thread per pixel doing all of it, as the path kernel does).
                ``wavefront+packets`` intersects the camera rays with the 16-ray packets.

Rays: pinhole camera rays, one per pixel (``--size`` squared), and one bounce: from each camera
ray's hit, a cosine-distributed direction about the face normal (a hash of the pixel index), the
origin pushed off the surface. Scenes: bench_vs_mitsuba's Cornell box (46 triangles: its light
housing and two blocks) and bench_scaling's heightfield of about 1M triangles with its camera.

Times: the launching thread's CPU time (``time.thread_time``) of single-threaded launches (with
``--device cuda``: wall time between synchronisations), rows interleaved, median of ``--repeat``. Rates are rays per second (bounce rays: those leaving a hit).
The pass rows count camera + bounce rays over the whole pass (ray generation and shading included).
Every variant's hits are compared with the scalar traversal's (faces differing, and how many of
those are exact ties in t), and each pass's film with the wavefront's (identical but where a tie
sent a bounce elsewhere).

``--asm`` disassembles each kernel's object file from Warp's kernel cache (objdump) and counts the
packed single-precision arithmetic, compare and blend instructions on zmm (16 lanes), ymm (8) and
xmm (4) registers: whether clang did vectorise (and in two small test kernels, never timed, the
16-lane slab tests alone with and without the packet kernel's branch and hit mask).

    python benchmarks/bench_packets.py                    # 256x256, Cornell and 1M triangles
    python benchmarks/bench_packets.py --size 128 --repeat 3 --triangles 100k --asm
"""

import argparse
import os
import platform
import re
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING

from warp_spt.device.structs import BVH_STACKS, Geometry, vec_wide_f, vec_wide_i  # noqa: E402
from warp_spt.accel.wide_bvh import WIDTH, build_wide  # noqa: E402
from warp_spt.accel.wide_traversal import (  # noqa: E402
    _FAR_SLACK,
    NO_HIT,
    MeshRay,
    leaf_range,
    make_closest_query,
    mesh_ray,
    triangle_hit,
)

# the path kernel's compiler flags (integrators.common.FAST_KERNEL_OPTIONS), so every variant is
# compiled as the renderer's kernel is
OPTIONS = {"cpu_compiler_flags": "-march=native -mllvm=-inline-threshold=2000 -mllvm=-slp-recursion-max-depth=4"}
ALBEDO = 0.7
TILES = {8: (4, 2), 16: (4, 4)}      # packet size -> tile (width, height) in pixels


# --------------------------------------------------------------------------------------------
# Scenes and cameras


def cornell() -> tuple[np.ndarray, np.ndarray, dict]:
    """(points, triangles, camera) of bench_vs_mitsuba's Cornell box."""
    from bench_vs_mitsuba import SCENES
    desc = SCENES["cornell"]
    pts, tris = [], []
    for shape in desc["shapes"]:
        if shape[0] != "quad":
            continue
        k = len(pts)
        pts += shape[2]
        tris += [(k, k + 1, k + 2), (k, k + 2, k + 3)]
    cam = desc["camera"]
    p = np.asarray(cam["position"], np.float64)
    return (np.asarray(pts, np.float32), np.asarray(tris, np.int32),
            dict(position=p, target=p + np.asarray(cam["direction"], np.float64), fov=cam["fov"]))


def heightfield(triangles: int) -> tuple[np.ndarray, np.ndarray, dict]:
    """(points, triangles, camera) of bench_scaling's heightfield."""
    from bench_scaling import CAMERA
    from bench_scaling import heightfield as make
    p, t = make(triangles)
    return p, t, dict(position=np.asarray(CAMERA["position"], np.float64),
                      target=np.asarray(CAMERA["target"], np.float64), fov=CAMERA["fov"])


@wp.struct
class Pinhole:
    origin: wp.vec3
    corner: wp.vec3      # direction through the top-left corner of the image
    du: wp.vec3          # direction step per pixel to the right
    dv: wp.vec3          # ... and down
    width: int


def pinhole(cam: dict, size: int) -> Pinhole:
    """A square image, horizontal field of view ``fov`` degrees, Z up."""
    f = cam["target"] - cam["position"]
    f /= np.linalg.norm(f)
    right = np.cross(f, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, f)
    h = np.tan(np.radians(cam["fov"]) / 2.0)
    c = Pinhole()
    c.origin = wp.vec3(*cam["position"].astype(np.float32))
    c.corner = wp.vec3(*(f - h * right + h * up).astype(np.float32))
    c.du = wp.vec3(*(2.0 * h * right / size).astype(np.float32))
    c.dv = wp.vec3(*(-2.0 * h * up / size).astype(np.float32))
    c.width = size
    return c


@wp.func
def camera_dir(cam: Pinhole, pix: int) -> wp.vec3:
    x = float(pix % cam.width) + 0.5
    y = float(pix // cam.width) + 0.5
    return wp.normalize(cam.corner + x * cam.du + y * cam.dv)


@wp.func
def hash_u32(x: wp.uint32) -> wp.uint32:
    """A 32-bit integer mix (the PCG output permutation of one step from x)."""
    s = x * wp.uint32(747796405) + wp.uint32(2891336453)
    w = ((s >> ((s >> wp.uint32(28)) + wp.uint32(4))) ^ s) * wp.uint32(277803737)
    return (w >> wp.uint32(22)) ^ w


@wp.func
def bounce(g: Geometry, o: wp.vec3, d: wp.vec3, k: int, t: float, pix: int, eps: float):
    """(origin, direction) of a diffuse bounce off leaf-order triangle k hit at distance t."""
    a = g.tri_v0[k]
    n = wp.normalize(wp.cross(g.tri_v1[k] - a, g.tri_v2[k] - a))
    if wp.dot(n, d) > 0.0:
        n = -n
    h1 = hash_u32(wp.uint32(pix) * wp.uint32(2) + wp.uint32(1))
    h2 = hash_u32(h1 ^ wp.uint32(0x9E3779B9))
    u1 = float(h1 >> wp.uint32(8)) * (1.0 / 16777216.0)
    u2 = float(h2 >> wp.uint32(8)) * (1.0 / 16777216.0)
    r = wp.sqrt(u1)
    phi = 2.0 * wp.pi * u2
    # an orthonormal frame about n (Duff et al. 2017)
    sign = wp.where(n[2] >= 0.0, 1.0, -1.0)
    aa = -1.0 / (sign + n[2])
    bb = n[0] * n[1] * aa
    b1 = wp.vec3(1.0 + sign * n[0] * n[0] * aa, sign * bb, -sign * n[0])
    b2 = wp.vec3(bb, sign + n[1] * n[1] * aa, -n[1])
    w = wp.normalize(r * wp.cos(phi) * b1 + r * wp.sin(phi) * b2 + wp.sqrt(wp.max(0.0, 1.0 - u1)) * n)
    return o + t * d + eps * n, w


# --------------------------------------------------------------------------------------------
# Kernels


def scalar_kernels(stack: int) -> dict:
    closest = make_closest_query(stack)

    @wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
    def scalar(g: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3),
               k_out: wp.array(dtype=wp.int32), t_out: wp.array(dtype=float)):
        i = wp.tid()
        if wp.length_sq(d[i]) == 0.0:        # no ray (a bounce from a miss)
            k_out[i] = -1
            t_out[i] = NO_HIT
            return
        k, t, u, v = closest(g, 0, mesh_ray(o[i], d[i]), NO_HIT)
        k_out[i] = k
        t_out[i] = t

    @wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
    def generate(cam: Pinhole, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3)):
        i = wp.tid()
        o[i] = cam.origin
        d[i] = camera_dir(cam, i)

    @wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
    def shade_bounce(g: Geometry, eps: float, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3),
                     k_in: wp.array(dtype=wp.int32), t_in: wp.array(dtype=float),
                     o2: wp.array(dtype=wp.vec3), d2: wp.array(dtype=wp.vec3)):
        i = wp.tid()
        k = k_in[i]
        if k < 0:
            o2[i] = wp.vec3(0.0)
            d2[i] = wp.vec3(0.0)
            return
        bo, bd = bounce(g, o[i], d[i], k, t_in[i], i, eps)
        o2[i] = bo
        d2[i] = bd

    @wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
    def shade_final(k1: wp.array(dtype=wp.int32), k2: wp.array(dtype=wp.int32), film: wp.array(dtype=float)):
        i = wp.tid()
        film[i] = wp.where(k1[i] < 0, 1.0, wp.where(k2[i] < 0, ALBEDO, 0.0))

    @wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
    def megakernel(g: Geometry, cam: Pinhole, eps: float, film: wp.array(dtype=float),
                   k_out: wp.array(dtype=wp.int32)):
        i = wp.tid()
        d = camera_dir(cam, i)
        k, t, u, v = closest(g, 0, mesh_ray(cam.origin, d), NO_HIT)
        if k < 0:
            film[i] = 1.0
            k_out[i] = -1
            return
        bo, bd = bounce(g, cam.origin, d, k, t, i, eps)
        k2, t2, u2, v2 = closest(g, 0, mesh_ray(bo, bd), NO_HIT)
        film[i] = wp.where(k2 < 0, ALBEDO, 0.0)
        k_out[i] = k2

    return dict(scalar=scalar, generate=generate, shade_bounce=shade_bounce, shade_final=shade_final,
                megakernel=megakernel)


def packet_kernel(size: int, stack: int, options: dict = OPTIONS, in_memory: bool = False) -> wp.Kernel:
    """One thread per ``size`` rays (indices ``order[tid * size:(tid + 1) * size]``). ``in_memory``:
    the packet's rays (origin, inverse direction, nearest hit; one vector of lanes each) are kept in
    a scratch array row of the thread and re-read at every box test instead of in local vectors, so
    clang sees vector loads rather than scalars it must gather."""
    vp = wp.types.vector(length=size, dtype=wp.float32)
    vpi = wp.types.vector(length=size, dtype=wp.int32)
    vs_i = wp.types.vector(length=stack, dtype=wp.int32)
    vs_f = wp.types.vector(length=stack, dtype=wp.float32)

    @wp.func
    def vmax(a: vp, b: vp) -> vp:
        out = vp()
        for j in range(wp.static(size)):
            out[j] = wp.where(a[j] > b[j], a[j], b[j])
        return out

    @wp.func
    def vmin(a: vp, b: vp) -> vp:
        out = vp()
        for j in range(wp.static(size)):
            out[j] = wp.where(a[j] < b[j], a[j], b[j])
        return out

    @wp.func
    def entry(tn: vp, tf: vp, mask: int):
        """(lanes of ``mask`` whose ray enters the box, the nearest of their entry distances)."""
        hit = int(0)
        dist = float(NO_HIT)
        for j in range(wp.static(size)):
            ok = tn[j] <= tf[j] * _FAR_SLACK and (mask & (1 << j)) != 0
            hit = hit | wp.where(ok, 1 << j, 0)
            dist = wp.where(ok and tn[j] < dist, tn[j], dist)
        return hit, dist

    @wp.kernel(enable_backward=False, module="unique", module_options=options)
    def packet(g: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), order: wp.array(dtype=wp.int32),
               rays: wp.array(dtype=MeshRay), lanes: wp.array(dtype=vp), k_out: wp.array(dtype=wp.int32),
               t_out: wp.array(dtype=float)):
        base = wp.tid() * wp.static(size)
        row7 = wp.tid() * 7
        ox = vp()
        oy = vp()
        oz = vp()
        ix = vp()
        iy = vp()
        iz = vp()
        best_t = vp()
        best_k = vpi()
        live = int(0)
        for j in range(wp.static(size)):
            i = order[base + j]
            r = mesh_ray(o[i], d[i])
            rays[base + j] = r        # the leaves' per-ray set-up, kept hot in this thread's cache
            ox[j] = r.o[0]
            oy[j] = r.o[1]
            oz[j] = r.o[2]
            ix[j] = r.inv[0]
            iy[j] = r.inv[1]
            iz[j] = r.inv[2]
            best_t[j] = NO_HIT
            best_k[j] = -1
            if wp.length_sq(d[i]) > 0.0:
                live = live | (1 << j)
        if wp.static(in_memory):
            lanes[row7 + 0] = ox
            lanes[row7 + 1] = oy
            lanes[row7 + 2] = oz
            lanes[row7 + 3] = ix
            lanes[row7 + 4] = iy
            lanes[row7 + 5] = iz
            lanes[row7 + 6] = best_t
        nodes = vs_i()
        entries = vs_f()
        masks = vs_i()
        nodes[0] = g.mesh_root[0]
        entries[0] = 0.0
        masks[0] = live
        sp = int(wp.where(live != 0, 1, 0))
        while sp > 0:
            sp -= 1
            node = nodes[sp]
            mask = masks[sp]
            near = entries[sp]
            # lanes of the mask whose current hit is still beyond the node's nearest entry
            alive = int(0)
            for j in range(wp.static(size)):
                alive = alive | wp.where(best_t[j] > near, 1 << j, 0)
            mask = mask & alive
            if mask == 0:
                continue
            if node < 0:
                first, end = leaf_range(node)
                for k in range(first, end):
                    va = g.tri_v0[k]
                    vb = g.tri_v1[k]
                    vc = g.tri_v2[k]
                    m = mask
                    while m != 0:
                        j = wp.bit_count((m & (-m)) - 1)      # the lowest set bit: lanes in order
                        m = m & (m - 1)
                        h, t, u, v = triangle_hit(rays[base + j], va, vb, vc)
                        if h and t < best_t[j] and t >= 0.0:
                            best_t[j] = t
                            best_k[j] = k
                            if wp.static(in_memory):
                                lanes[row7 + 6] = best_t
            else:
                kids = g.bvh_child[node]
                row = node * 6
                lo_x = g.bvh_box[row + 0]
                lo_y = g.bvh_box[row + 1]
                lo_z = g.bvh_box[row + 2]
                hi_x = g.bvh_box[row + 3]
                hi_y = g.bvh_box[row + 4]
                hi_z = g.bvh_box[row + 5]
                top = sp
                for c in range(wp.static(WIDTH)):
                    if c > 0 and kids[c] == 0:      # empty slots come last (node 0 is nobody's child)
                        break
                    # whole-vector operations over the packet's rays (loops clang may vectorise: see --asm);
                    # min/max of the two planes picks the near one as the scalar test's sign rule
                    # does (the same float values: the slot is not empty)
                    if wp.static(in_memory):
                        x0 = wp.cw_mul(vp(lo_x[c]) - lanes[row7 + 0], lanes[row7 + 3])
                        x1 = wp.cw_mul(vp(hi_x[c]) - lanes[row7 + 0], lanes[row7 + 3])
                        y0 = wp.cw_mul(vp(lo_y[c]) - lanes[row7 + 1], lanes[row7 + 4])
                        y1 = wp.cw_mul(vp(hi_y[c]) - lanes[row7 + 1], lanes[row7 + 4])
                        z0 = wp.cw_mul(vp(lo_z[c]) - lanes[row7 + 2], lanes[row7 + 5])
                        z1 = wp.cw_mul(vp(hi_z[c]) - lanes[row7 + 2], lanes[row7 + 5])
                        far = lanes[row7 + 6]
                    else:
                        x0 = wp.cw_mul(vp(lo_x[c]) - ox, ix)
                        x1 = wp.cw_mul(vp(hi_x[c]) - ox, ix)
                        y0 = wp.cw_mul(vp(lo_y[c]) - oy, iy)
                        y1 = wp.cw_mul(vp(hi_y[c]) - oy, iy)
                        z0 = wp.cw_mul(vp(lo_z[c]) - oz, iz)
                        z1 = wp.cw_mul(vp(hi_z[c]) - oz, iz)
                        far = best_t
                    tn = vmax(vmax(vmin(x0, x1), vmin(y0, y1)), vmax(vmin(z0, z1), vp(0.0)))
                    tf = vmin(vmin(vmax(x0, x1), vmax(y0, y1)), vmin(vmax(z0, z1), far))
                    hit, dist = entry(tn, tf, mask)
                    if hit != 0:
                        # insert, keeping entries[top:sp] in decreasing order (the nearest child on top)
                        b = sp - 1
                        while b >= top and entries[b] < dist:
                            nodes[b + 1] = nodes[b]
                            entries[b + 1] = entries[b]
                            masks[b + 1] = masks[b]
                            b -= 1
                        nodes[b + 1] = kids[c]
                        entries[b + 1] = dist
                        masks[b + 1] = hit
                        sp += 1
        for j in range(wp.static(size)):
            i = order[base + j]
            k_out[i] = best_k[j]
            t_out[i] = best_t[j]

    return packet


def wide_kernel(width: int, stack: int) -> wp.Kernel:
    """Today's scalar traversal (one ray per thread, the renderer's code path re-typed) over a tree of
    ``width`` children per node, its boxes and children passed as arrays (the Geometry struct's are
    typed 8-wide): width 16 tests a node's children in one AVX-512 register's lanes."""
    vw = wp.types.vector(length=width, dtype=wp.float32)
    vwi = wp.types.vector(length=width, dtype=wp.int32)
    vs_i = wp.types.vector(length=stack, dtype=wp.int32)
    vs_f = wp.types.vector(length=stack, dtype=wp.float32)

    @wp.func
    def wmax(a: vw, b: vw) -> vw:
        out = vw()
        for j in range(wp.static(width)):
            out[j] = wp.where(a[j] > b[j], a[j], b[j])
        return out

    @wp.func
    def wmin(a: vw, b: vw) -> vw:
        out = vw()
        for j in range(wp.static(width)):
            out[j] = wp.where(a[j] < b[j], a[j], b[j])
        return out

    @wp.func
    def entries_of(box: wp.array(dtype=vw), node: int, r: MeshRay, t_max: float) -> vw:
        b = node * 6
        t_in = wmax(wmax(wp.cw_mul(box[b + r.near[0]] - vw(r.o[0]), vw(r.inv[0])),
                         wp.cw_mul(box[b + r.near[1]] - vw(r.o[1]), vw(r.inv[1]))),
                    wmax(wp.cw_mul(box[b + r.near[2]] - vw(r.o[2]), vw(r.inv[2])), vw(0.0)))
        t_out = wmin(wmin(wp.cw_mul(box[b + 3 - r.near[0]] - vw(r.o[0]), vw(r.inv[0])),
                          wp.cw_mul(box[b + 5 - r.near[1]] - vw(r.o[1]), vw(r.inv[1]))),
                     wmin(wp.cw_mul(box[b + 7 - r.near[2]] - vw(r.o[2]), vw(r.inv[2])), vw(t_max)))
        out = vw()
        for j in range(wp.static(width)):
            out[j] = wp.where(t_in[j] <= t_out[j] * _FAR_SLACK, t_in[j], NO_HIT)
        return out

    @wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
    def wide(box: wp.array(dtype=vw), child: wp.array(dtype=vwi), v0: wp.array(dtype=wp.vec3),
             v1: wp.array(dtype=wp.vec3), v2: wp.array(dtype=wp.vec3), o: wp.array(dtype=wp.vec3),
             d: wp.array(dtype=wp.vec3), k_out: wp.array(dtype=wp.int32), t_out: wp.array(dtype=float)):
        i = wp.tid()
        if wp.length_sq(d[i]) == 0.0:
            k_out[i] = -1
            t_out[i] = NO_HIT
            return
        r = mesh_ray(o[i], d[i])
        best_k = int(-1)
        best_t = float(NO_HIT)
        nodes = vs_i()
        entries = vs_f()
        nodes[0] = 0
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
                    h, t, u, v = triangle_hit(r, v0[k], v1[k], v2[k])
                    if h and t < best_t and t >= 0.0:
                        best_k = k
                        best_t = t
            else:
                dist = entries_of(box, node, r, best_t)
                kids = child[node]
                base = sp
                for j in range(wp.static(width)):
                    if dist[j] < NO_HIT:
                        nodes[sp] = kids[j]
                        entries[sp] = dist[j]
                        sp += 1
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
        k_out[i] = best_k
        t_out[i] = best_t

    return wide


class WideTree:
    """A ``width``-wide tree's arrays for :func:`wide_kernel` (leaf order: positions in its own order)."""

    def __init__(self, points: np.ndarray, tris: np.ndarray, width: int):
        wb = build_wide(points, tris, width=width)
        v = points[tris[wb.order]].astype(np.float32)
        vw = wp.types.vector(length=width, dtype=wp.float32)
        vwi = wp.types.vector(length=width, dtype=wp.int32)
        self.order = wb.order
        self.arrays = [wp.array(wb.box.reshape(-1, width), dtype=vw), wp.array(wb.child, dtype=vwi)] + \
            [wp.array(np.ascontiguousarray(v[:, c]), dtype=wp.vec3) for c in range(3)]
        self.stack = -(-wb.stack_bound // 16) * 16
        self.num_nodes = wb.num_nodes


def tile_order(size: int, packet: int) -> np.ndarray:
    """Pixel indices grouped by tile: packet-sized runs of a ``TILES[packet]`` tile each."""
    tw, th = TILES[packet]
    if size % tw or size % th:
        raise SystemExit(f"--size must be a multiple of {tw} and {th}")
    y, x = np.mgrid[0:size, 0:size]
    tile = (y // th) * (size // tw) + x // tw
    within = (y % th) * tw + x % tw
    return np.argsort((tile * packet + within).reshape(-1), kind="stable").astype(np.int32)


# --------------------------------------------------------------------------------------------
# Measurement


def geometry(points: np.ndarray, tris: np.ndarray) -> tuple[Geometry, int, int, np.ndarray]:
    """(the Geometry struct with one mesh's wide BVH, the traversal stack it needs, its node count,
    its leaf order: triangle ids by leaf-order position)."""
    wb = build_wide(points, tris)
    v = points[tris[wb.order]].astype(np.float32)
    g = Geometry()
    g.bvh_box = wp.array(wb.box.reshape(-1, WIDTH), dtype=vec_wide_f)
    g.bvh_child = wp.array(wb.child, dtype=vec_wide_i)
    g.mesh_root = wp.array([0], dtype=wp.int32)
    g.tri_v0, g.tri_v1, g.tri_v2 = (wp.array(np.ascontiguousarray(v[:, c]), dtype=wp.vec3) for c in range(3))
    g.num_meshes = 1
    stack = next(n for n in BVH_STACKS if n >= wb.stack_bound)
    return g, stack, wb.num_nodes, wb.order


def timed(fn, rows: dict, label: str) -> None:
    """One run of fn: on the CPU its launching thread's CPU seconds (CPU launches are synchronous),
    on a GPU its wall seconds between two synchronisations; appended to rows[label]."""
    rows.setdefault(label, [])
    if wp.get_device().is_cuda:
        wp.synchronize_device()
        t = time.perf_counter()
        fn()
        wp.synchronize_device()
        rows[label].append(time.perf_counter() - t)
        return
    t = time.thread_time()
    fn()
    rows[label].append(time.thread_time() - t)


def run_scene(name: str, points, tris, cam_desc, size: int, repeat: int, asm: bool, packet_options: dict) -> list:
    t0 = time.perf_counter()
    g, stack, num_nodes, ref_order = geometry(points, tris)
    trees = {w: WideTree(points, tris, w) for w in (8, 16)}
    build_s = time.perf_counter() - t0
    lo, hi = points.min(axis=0), points.max(axis=0)
    eps = float(1e-4 * np.max(hi - lo))
    n = size * size
    cam = pinhole(cam_desc, size)
    ks = scalar_kernels(stack)
    wides = {f"scalar {w}-wide, arrays": wide_kernel(w, tree.stack) for w, tree in trees.items()}
    packets = {f"packet {p}": packet_kernel(p, stack, packet_options) for p in (8, 16)}
    packets.update({f"packet {p} mem": packet_kernel(p, stack, packet_options, True) for p in (8, 16)})
    psize = {pname: int(pname.split()[1]) for pname in packets}
    lanes = {p: wp.empty(n // p * 7, dtype=wp.types.vector(length=p, dtype=wp.float32)) for p in (8, 16)}
    orders = {p: wp.array(tile_order(size, p), dtype=wp.int32) for p in (8, 16)}
    arr = lambda dt: wp.zeros(n, dtype=dt)    # noqa: E731
    o1, d1, o2, d2 = arr(wp.vec3), arr(wp.vec3), arr(wp.vec3), arr(wp.vec3)
    k1, t1, k2, t2 = arr(wp.int32), arr(float), arr(wp.int32), arr(float)
    kp, tp = arr(wp.int32), arr(float)
    film_w, film_m, k_m = arr(float), arr(float), arr(wp.int32)
    rays = wp.empty(n, dtype=MeshRay)
    c0 = time.perf_counter()
    for k in list(ks.values()) + list(packets.values()) + list(wides.values()):
        wp.load_module(k.module, device=wp.get_device())
    compile_s = time.perf_counter() - c0

    def wavefront(packet_primary: bool = False):
        wp.launch(ks["generate"], dim=n, inputs=[cam, o1, d1])
        if packet_primary:
            wp.launch(packets["packet 16"], dim=n // 16, inputs=[g, o1, d1, orders[16], rays, lanes[16], k1, t1])
        else:
            wp.launch(ks["scalar"], dim=n, inputs=[g, o1, d1, k1, t1])
        wp.launch(ks["shade_bounce"], dim=n, inputs=[g, eps, o1, d1, k1, t1, o2, d2])
        wp.launch(ks["scalar"], dim=n, inputs=[g, o2, d2, k2, t2])
        wp.launch(ks["shade_final"], dim=n, inputs=[k1, k2, film_w])

    # the rays every row traces: camera rays and their bounce rays
    wavefront()
    wp.synchronize()
    ref = {"camera": (k1.numpy().copy(), t1.numpy().copy()), "bounce": (k2.numpy().copy(), t2.numpy().copy())}
    sources = {"camera": (wp.clone(o1), wp.clone(d1)), "bounce": (wp.clone(o2), wp.clone(d2))}
    counts = {"camera": n, "bounce": int((ref["camera"][0] >= 0).sum())}
    film_ref = film_w.numpy().copy()

    runs = {}
    for kind, (o, d) in sources.items():
        runs[(kind, "scalar")] = lambda o=o, d=d: wp.launch(ks["scalar"], dim=n, inputs=[g, o, d, kp, tp])
        for (wname, kern), tree in zip(wides.items(), trees.values()):
            runs[(kind, wname)] = (lambda o=o, d=d, kern=kern, tree=tree:
                                   wp.launch(kern, dim=n, inputs=tree.arrays + [o, d, kp, tp]))
        for pname, kern in packets.items():
            p = psize[pname]
            runs[(kind, pname)] = (lambda o=o, d=d, p=p, kern=kern:
                                  wp.launch(kern, dim=n // p, inputs=[g, o, d, orders[p], rays, lanes[p], kp, tp]))
    runs[("pass", "megakernel")] = lambda: wp.launch(ks["megakernel"], dim=n, inputs=[g, cam, eps, film_m, k_m])
    runs[("pass", "wavefront")] = wavefront
    runs[("pass", "wavefront+packets")] = lambda: wavefront(True)

    # correctness, once per variant: hits against the scalar traversal's, films identical
    agree = {}
    for key, fn in runs.items():
        fn()
        wp.synchronize()
        if key[0] == "pass":
            film = (film_m if key[1] == "megakernel" else film_w).numpy()
            agree[key] = "film identical" if np.array_equal(film, film_ref) else \
                f"film differs at {int((film != film_ref).sum())} pixels"
            continue
        rk, rt = ref[key[0]]
        fk, ft = kp.numpy(), tp.numpy()
        order = trees[16].order if "16-wide" in key[1] else ref_order     # leaf positions -> triangle ids
        diff = np.where(fk >= 0, order[fk], -1) != np.where(rk >= 0, ref_order[rk], -1)
        same_t = np.array_equal(ft[~diff], rt[~diff])
        ties = int((diff & (np.abs(ft - rt) <= 4e-7 * np.maximum(np.abs(rt), 1e-30))).sum())
        agree[key] = f"{int(diff.sum())} faces differ ({ties} ties), t {'bit-identical' if same_t else 'DIFFERS'}"

    times: dict = {}
    for _ in range(repeat):
        for key, fn in runs.items():
            timed(fn, times, key)
    rows = []
    for key, ts in times.items():
        med = statistics.median(ts)
        rays_n = counts["camera"] + counts["bounce"] if key[0] == "pass" else counts[key[0]]
        rows.append((name, key[0], key[1], med, rays_n / med, agree[key]))
    print(f"\n{name}: {len(tris):,} triangles, {num_nodes:,} wide nodes ({trees[16].num_nodes:,} 16-wide), "
          f"stack {stack}; build {build_s:.2f} s, "
          f"kernels compiled/loaded in {compile_s:.1f} s; {n:,} camera rays, {counts['bounce']:,} bounce rays")
    if asm and wp.get_device().is_cpu:
        report_asm({"scalar": ks["scalar"], "megakernel": ks["megakernel"], **wides, **packets,
                    **shape_kernels()})
    return rows


def shape_kernels() -> dict:
    """Two small kernels for ``--asm`` alone (never timed): the packet's slab tests of eight children
    over 16 lanes, once straight-line and once with the packet kernel's branch and hit-mask
    reduction in the child loop: what the code's shape does to clang's vectorisation."""
    vp = wp.types.vector(length=16, dtype=wp.float32)

    @wp.func
    def vmax(a: vp, b: vp) -> vp:
        out = vp()
        for j in range(16):
            out[j] = wp.where(a[j] > b[j], a[j], b[j])
        return out

    @wp.func
    def vmin(a: vp, b: vp) -> vp:
        out = vp()
        for j in range(16):
            out[j] = wp.where(a[j] < b[j], a[j], b[j])
        return out

    @wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
    def straight(ox: wp.array(dtype=vp), ix: wp.array(dtype=vp), lo: wp.array(dtype=float),
                 hi: wp.array(dtype=float), out: wp.array(dtype=vp)):
        i = wp.tid()
        o = ox[i]
        inv = ix[i]
        acc = vp(0.0)
        for c in range(8):
            acc = vmax(acc, vmin(wp.cw_mul(vp(lo[c]) - o, inv), wp.cw_mul(vp(hi[c]) - o, inv)))
        out[i] = acc

    @wp.kernel(enable_backward=False, module="unique", module_options=OPTIONS)
    def branchy(ox: wp.array(dtype=vp), ix: wp.array(dtype=vp), lo: wp.array(dtype=float),
                hi: wp.array(dtype=float), out: wp.array(dtype=int)):
        i = wp.tid()
        o = ox[i]
        inv = ix[i]
        total = int(0)
        for c in range(8):
            if lo[c] > hi[c]:
                break
            x0 = wp.cw_mul(vp(lo[c]) - o, inv)
            x1 = wp.cw_mul(vp(hi[c]) - o, inv)
            tn = vmin(x0, x1)
            tf = vmax(x0, x1)
            hit = int(0)
            for j in range(16):
                hit = hit | wp.where(tn[j] <= tf[j], 1 << j, 0)
            total += hit
        out[i] = total

    for k in (straight, branchy):
        wp.load_module(k.module, device="cpu")
    return {"shape test: 16-lane slab tests, straight-line": straight,
            "shape test: the same with a branch and a hit mask": branchy}


def report_asm(kernels: dict) -> None:
    """Packed single-precision arithmetic/compare/blend instructions per register width in each
    kernel's object file: did clang vectorise, and how wide?"""
    cache = wp.config.kernel_cache_dir
    print("\n| kernel | instructions | packed ps ops on zmm (16 lanes) | on ymm (8) | on xmm (4) | "
          "mask-register ops (k0-k7) | scalar ss ops |")
    print("|---|---|---|---|---|---|---|")
    packed = re.compile(r"\sv(add|sub|mul|div|min|max|cmp\w*|blendv|fmadd\w*|fmsub\w*|fnmadd\w*)ps\s")
    scalar = re.compile(r"\sv(add|sub|mul|div|min|max|cmp\w*|fmadd\w*|fmsub\w*|fnmadd\w*)ss\s")
    for label, k in kernels.items():
        objs = sorted(Path(cache).glob(f"wp_{k.module.name}_*/*.o"), key=os.path.getmtime)[-1:]
        if not objs:
            print(f"| {label} | no object file in {cache} | | | | | |")
            continue
        try:
            text = subprocess.run(["objdump", "-d", "--no-show-raw-insn", str(objs[0])], check=False,
                                  capture_output=True, text=True).stdout.splitlines()
        except FileNotFoundError:
            print("objdump not found: no disassembly")
            return
        ps = [ln for ln in text if packed.search(ln)]
        print(f"| {label} | {len(text)} | {sum('zmm' in ln for ln in ps)} | "
              f"{sum('ymm' in ln and 'zmm' not in ln for ln in ps)} | "
              f"{sum('xmm' in ln and 'ymm' not in ln and 'zmm' not in ln for ln in ps)} | "
              f"{sum(re.search(r'%k[0-7]', ln) is not None for ln in text)} | "
              f"{sum(scalar.search(ln) is not None for ln in text)} |")
        print(f"|   ({objs[0]}) | | | | | | |")


def cpu_name() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                name = line.split(":", 1)[1].strip()
                flags = open("/proc/cpuinfo").read()
                isa = "AVX-512" if " avx512f" in flags else ("AVX2" if " avx2" in flags else "no AVX2")
                return f"{name} ({isa}, {os.cpu_count()} CPUs)"
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def parse_count(text: str) -> int:
    t = text.strip().lower()
    scale = {"k": 1_000, "m": 1_000_000}.get(t[-1:], 1)
    return int(float(t[:-1] if scale > 1 else t) * scale)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=256, help="image side in pixels (a multiple of 4)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--triangles", type=parse_count, default=1_000_000, help="the heightfield's size (e.g. 100k, 1M)")
    ap.add_argument("--scenes", nargs="+", default=["cornell", "heightfield"], choices=["cornell", "heightfield"])
    ap.add_argument("--packet-flags", default=OPTIONS["cpu_compiler_flags"],
                    help="clang flags of the packet kernels (default: the path kernel's)")
    ap.add_argument("--asm", action="store_true", help="count vector instructions in the kernels' object code")
    ap.add_argument("--device", default="cpu",
                    help="cpu (default) or cuda[:N]: on a GPU, wall time between synchronisations (the trees "
                         "are built on the CPU and copied); the packet kernels then run one packet per GPU thread")
    args = ap.parse_args()
    wp.init()
    if args.device != "cpu" and not wp.is_cuda_available():
        raise SystemExit(f"--device {args.device}: no CUDA device here")
    where = cpu_name() if args.device == "cpu" else f"{wp.get_device(args.device).name} ({args.device})"
    clock = "one thread, CPU s" if args.device == "cpu" else "wall s between synchronisations"
    print(f"Device: {where}; Warp {wp.config.version}; {clock}, median of {args.repeat}, "
          f"{args.size}x{args.size} pixels; packet kernels' flags: {args.packet_flags}")
    rows = []
    with wp.ScopedDevice(args.device):
        for name in args.scenes:
            pts, tris, cam = cornell() if name == "cornell" else heightfield(args.triangles)
            label = "Cornell box" if name == "cornell" else f"heightfield {len(tris) / 1e6:.2g}M"
            rows += run_scene(label, pts, tris, cam, args.size, args.repeat, args.asm,
                              {"cpu_compiler_flags": args.packet_flags})
    print(f"\nDevice: {where}")
    print(f"| scene | rays | variant | {'CPU s' if args.device == 'cpu' else 'wall s'} | Mrays/s | over scalar | hits |")
    print("|---|---|---|---|---|---|---|")
    base = {}
    for scene, kind, variant, sec, rate, agree in rows:
        if variant in ("scalar", "megakernel"):
            base[(scene, kind)] = rate
        print(f"| {scene} | {kind} | {variant} | {sec:.4f} | {rate / 1e6:.2f} | "
              f"{rate / base[(scene, kind)]:.2f} | {agree} |")


if __name__ == "__main__":
    main()
