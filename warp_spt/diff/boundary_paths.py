"""The one kernel of the boundary terms (``diff.boundary``, ``diff.secondary``, ``diff.shadows``): paths
and hits from given rays with the integrator's own step. One kernel kind, ``boundary``, with four
stages, so that a scene compiles one module for the three terms (each of its kernels holds the whole path step: two kinds took two
compiles of it, 20-40 s each on 2 cores)."""

from __future__ import annotations

import warp as wp

from warp_spt.accel.surface import Surface, make_surface, offset_origin
from warp_spt.bsdfs import make_materials
from warp_spt.bsdfs.cutout import make_hit
from warp_spt.device.camera_rays import CameraParams
from warp_spt.device.structs import Features, Geometry, Materials, Textures
from warp_spt.emitters import Lights
from warp_spt.integrators import RenderParams, get_step
from warp_spt.rendering.setup import KernelKind, register_kind, render_features
from warp_spt.runtime import kernel_cache

STAGE_RECEIVERS, STAGE_LIGHTING, STAGE_PRIMARY, STAGE_RAYS = 0, 1, 2, 3


@wp.func
def side_origin(sf: Surface, d: wp.vec3, extent: float) -> wp.vec3:
    """Where a ray along ``d`` leaves the surface from: offset to the side ``d`` goes."""
    through = int(0)
    if wp.dot(d, sf.ng) < 0.0:
        through = 1
    return offset_origin(sf.p, sf.ng, through, extent)


def _make_kernel(features: Features, step, start_path):
    hit = make_hit(features)
    surface_at = make_surface(features)
    mat = make_materials(features)

    @wp.func
    def along(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, cam: CameraParams, rp: RenderParams,
              seed2: wp.uint32, i: int, o: wp.vec3, d: wp.vec3, depth: int) -> wp.vec3:
        """The radiance arriving at o from direction d: a path from o that has made ``depth`` hits (0: a
        camera ray), its random numbers sample i's (the same for both sides of a curve); 0 if not finite."""
        q = start_path(cam, i, rp.width, seed2, 0)
        q.o = o
        q.d = d
        q.depth = depth
        q.alive = int(rp.max_depth > depth)
        while q.alive != 0:
            q = step(geo, mats, tex, lights, rp, q)
        r = q.radiance
        if not wp.isfinite(r):
            r = wp.vec3(0.0, 0.0, 0.0)
        return r

    @wp.kernel(enable_backward=False, module="unique")
    def boundary_paths(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, cam: CameraParams,
                  rp: RenderParams, stage: int, seed2: wp.uint32, pix: wp.array(dtype=wp.int32),
                  sample: wp.array(dtype=wp.int32), steps: wp.array(dtype=wp.int32), dirs: wp.array(dtype=wp.vec3),
                  rec: wp.array(dtype=wp.vec3), info: wp.array(dtype=wp.vec4i), bary: wp.array(dtype=wp.vec2),
                  dirs_apex: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
        """The boundary terms' paths. Stage 2 (diff.boundary): ray i from the eye ``rec[0]`` along
        dirs[i], the pairs (2k, 2k + 1) with the random numbers of sample k. Stage 0 (diff.secondary):
        receiver i: the vertex its path reaches after ``steps[i]`` bounces (0: the camera ray's hit),
        its incoming ray (rec 5i, 5i + 1), its hit point and geometric normal (5i + 2, 5i + 3), the
        path's throughput up to it (5i + 4), its primitive (kind, index, face, placed; kind -1: the
        ray escaped or the path ended), barycentrics and the origin of the rays it reflects
        (``dirs_apex``).
        Stage 1: the same vertex's throughput x f cos towards dirs[3i] (out[3i]) and the radiance
        along dirs[3i + 1] and dirs[3i + 2] (out[3i + 1], out[3i + 2]), two paths of the same random
        numbers. Stage 3 (diff.shadows): the first hit of the ray from rec[i] along dirs[i], its
        point (``dirs_apex[i]``), geometric normal (out[i]) and primitive (info[i], kind -1: none)."""
        i = wp.tid()
        if stage == 2:
            out[i] = along(geo, mats, tex, lights, cam, rp, rp.seed, i // 2, rec[0], dirs[i], 0)
            return
        if stage == 3:
            r = hit(geo, mats, tex, rec[i], dirs[i])
            if r.kind < 0:
                info[i] = wp.vec4i(-1, 0, 0, 0)
                return
            hs = surface_at(geo, r, rec[i], dirs[i])
            dirs_apex[i] = hs.p
            out[i] = hs.ng
            info[i] = wp.vec4i(r.kind, r.index, r.face, r.placed)
            return
        p = start_path(cam, pix[i], rp.width, rp.seed, sample[i])
        # the bounces before the receiver, with the integrator's own step (the same in both stages)
        s = int(0)
        while s < steps[i]:
            if p.alive != 0:
                p = step(geo, mats, tex, lights, rp, p)
            s += 1
        h = hit(geo, mats, tex, p.o, p.d)
        if p.alive == 0 or h.kind < 0:
            if stage == 0:
                info[i] = wp.vec4i(-1, 0, 0, 0)
            return
        sf = mat.shade(mats, tex, surface_at(geo, h, p.o, p.d))
        if stage == 0:
            rec[5 * i] = p.o
            rec[5 * i + 1] = p.d
            rec[5 * i + 2] = sf.p
            rec[5 * i + 3] = sf.ng
            rec[5 * i + 4] = p.throughput
            # where its reflected rays start: the apex of the directions they see (offset_eps: 1e-5 of
            # the scene's extent, which curves seen from sf.p itself would miss by as much)
            dirs_apex[i] = offset_origin(sf.p, sf.ng, 0, geo.extent)
            info[i] = wp.vec4i(h.kind, h.index, h.face, h.placed)
            bary[i] = wp.vec2(h.u, h.v)
            return
        out[3 * i] = wp.cw_mul(p.throughput, mat.eval(mats, tex, sf, dirs[3 * i]))
        # two calls, not a loop of two: in a loop Warp unrolled, both sides came out as one
        for_side = dirs[3 * i + 1]
        out[3 * i + 1] = along(geo, mats, tex, lights, cam, rp, seed2, i, side_origin(sf, for_side, geo.extent),
                               for_side, steps[i] + 1)
        for_side = dirs[3 * i + 2]
        out[3 * i + 2] = along(geo, mats, tex, lights, cam, rp, seed2, i, side_origin(sf, for_side, geo.extent),
                               for_side, steps[i] + 1)

    return boundary_paths


def get_boundary_kernel(features: Features, integrator: str, sampler: str, device: str = "cpu") -> wp.Kernel:
    k = kernel_cache.cached("boundary", (integrator, sampler, features),
                            lambda: _make_kernel(features, *get_step(integrator, sampler, features)))
    return kernel_cache.load(k, device)


BOUNDARY = register_kind(KernelKind("boundary", lambda b: get_boundary_kernel(
    b.features, b.integrator.name, b.settings.sampler, b.dev.device), render_features))
