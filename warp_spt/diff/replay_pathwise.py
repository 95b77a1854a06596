"""Path replay with pathwise derivatives: geometry, the camera, fuzz and light positions, any kernel
depth, no unrolled tape.

``diff.prb`` replays a path forwards and needs each vertex's derivative alone, which holds only
while the sampled directions and the hit points stay where they are (detached sampling). When the
geometry, the camera or a light's position moves, a hit point moves, and with it the next ray's
origin, and through the local frame the next direction: every later vertex depends on every earlier
one, and the adjoint must flow backwards along the path. That is what the tape's kernel does, unrolled
to ``max_depth`` (at most 8: compile time) with every vertex's state kept on the kernel's stack.

Here one forward-only kernel (a dynamic loop, one vertex's code whatever the depth) does it per
sample in two passes:

1. traces the path as the fast kernel does (closest hit + the integrator's vertex, inlined), storing
   each vertex's path state and hit in a per-thread scratch row (``max_depth + 1`` states: memory
   depends on the tile and the depth, not on spp or the image), and sums the radiance into the film;
2. walks the stored vertices backwards. At vertex k it calls ``wp.grad`` of a scalar
   ``a_r . R_{k+1} + a_T . T_{k+1} + a_o . o_{k+1} + a_d . d_{k+1}`` of that vertex, where the seeds are
   the adjoints that vertex k+1 returned for its input state (for the last vertex: the pixel's adjoint
   on the radiance, 0 elsewhere). The differentiated function re-intersects the stored hit in closed
   form (``accel.ray_queries.make_refine_hit``, as the tape's closest hit) and runs the integrator's
   pathwise vertex (``Integrator.pathwise``: the tape's vertex, whose surface point, normal, light
   sample and sampled direction move with the scene), with the light sample's visibility passed in,
   so no adjoint traces a ray. The adjoints of array reads land in the arrays' ``.grad`` (per-tile
   aliases); the adjoint of the camera ray goes through the camera's own ``wp.grad`` into the
   per-tile camera deltas, as the tape's.

Same integrand and the same samples as the tape, so the same estimator: the two agree to rounding
(``tests/diff/test_replay_pathwise.py``). Russian roulette replays its decisions and its survival
probability carries no derivative, as in both other modes. The boundary terms (visibility) are
separate estimates (``diff.boundary``, ``diff.secondary``), whichever mode gives the interior term.
"""

from __future__ import annotations

import warp as wp

from warp_spt.accel.ray_queries import Hit, make_refine_hit
from warp_spt.bsdfs.cutout import make_hit
from warp_spt.device.camera_rays import CameraParams
from warp_spt.diff.prb import is_zero, sample_adjoint
from warp_spt.device.structs import Features, Geometry, Materials, Textures
from warp_spt.emitters import Lights
from warp_spt.integrators import PathState, RenderParams, get_vertex
from warp_spt.integrators.nee import VIS_TRACE
from warp_spt.rendering.setup import KernelKind, register_kind, render_features
from warp_spt.runtime import kernel_cache

MAX_PATHWISE_DEPTH = 64     # the scratch row holds max_depth + 1 states of ~150 bytes per pixel of a tile


def _make_kernel(vertex, forward, start_path, hit, refine_hit, depth_cap: int):
    @wp.func
    def objective(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
                  path: PathState, h: Hit, vis: int, ar: wp.vec3, at: wp.vec3, ao: wp.vec3,
                  ad: wp.vec3) -> wp.float32:
        """Vertex ``path``/``h``'s output state seeded with the adjoints of what follows (constants)."""
        p = vertex(geo, mats, tex, lights, rp, path, refine_hit(geo, h, path.o, path.d), vis)
        return wp.dot(p.radiance, ar) + wp.dot(p.throughput, at) + wp.dot(p.o, ao) + wp.dot(p.d, ad)

    @wp.func
    def camera_objective(cam: CameraParams, origin: wp.vec3, to_upper_left: wp.vec3, x_step: wp.vec3,
                         y_step: wp.vec3, right: wp.vec3, up: wp.vec3, pix: int, width: int, seed: wp.uint32,
                         index: int, ao: wp.vec3, ad: wp.vec3) -> wp.float32:
        """The camera ray seeded with its adjoints; the frame's vectors are arguments of their own
        (Warp 1.19's wp.grad returns zero adjoints for a struct argument's value fields)."""
        c = cam
        c.origin = origin
        c.to_upper_left = to_upper_left
        c.x_step = x_step
        c.y_step = y_step
        c.right = right
        c.up = up
        s = start_path(c, pix, width, seed, index)
        return wp.dot(s.o, ao) + wp.dot(s.d, ad)

    @wp.kernel(enable_backward=False, module="unique")
    def replay_pathwise(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, cam: CameraParams,
                        rp: RenderParams, adj_image: wp.array(dtype=wp.vec3), want_image: int,
                        film: wp.array(dtype=wp.vec3d), camera_grad: wp.array(dtype=wp.vec3),
                        states: wp.array2d(dtype=PathState), hits: wp.array2d(dtype=Hit)):
        """Each thread replays the samples of one pixel of the tile (``states``/``hits``: its row of
        scratch); with ``want_image`` it also adds the radiance sums to ``film``; the camera ray's
        adjoints are added to ``camera_grad`` (the deltas' order)."""
        tid = wp.tid()
        a = sample_adjoint(adj_image, tid, rp.sample_count)
        replay_it = not is_zero(a)
        if not replay_it and want_image == 0:
            return
        pix = rp.pixel_start + tid
        zero = wp.vec3(0.0, 0.0, 0.0)
        acc = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0))
        for j in range(rp.sample_count):
            index = rp.sample_start + j
            q = start_path(cam, pix, rp.width, rp.seed, index)
            n = int(0)
            while q.alive != 0 and n < wp.static(depth_cap):     # pass 1, storing each vertex
                h = hit(geo, mats, tex, q.o, q.d)
                states[tid, n] = q
                hits[tid, n] = h
                q = forward(geo, mats, tex, lights, rp, q, h, VIS_TRACE)
                n += 1
            states[tid, n] = q
            total = q.radiance
            if not wp.isfinite(total):
                continue                         # the fast kernel drops it: no gradient either
            acc += wp.vec3d(wp.float64(total[0]), wp.float64(total[1]), wp.float64(total[2]))
            if not replay_it:
                continue
            ar = a
            at = zero
            ao = zero
            ad = zero
            k = n - 1
            while k >= 0:                        # pass 2, backwards: the adjoint of each input state
                ag, am, ax, al, arp, apath, ah, av, a1, a2, a3, a4 = wp.grad(objective)(
                    geo, mats, tex, lights, rp, states[tid, k], hits[tid, k], states[tid, k + 1].vis,
                    ar, at, ao, ad)
                ar = apath.radiance
                at = apath.throughput
                ao = apath.o
                ad = apath.d
                k -= 1
            ac, c0, c1, c2, c3, c4, c5, ap, aw, asd, ai, b1, b2 = wp.grad(camera_objective)(
                cam, cam.origin, cam.to_upper_left, cam.x_step, cam.y_step, cam.right, cam.up,
                pix, rp.width, rp.seed, index, ao, ad)
            wp.atomic_add(camera_grad, 0, c0)
            wp.atomic_add(camera_grad, 1, c1)
            wp.atomic_add(camera_grad, 2, c2)
            wp.atomic_add(camera_grad, 3, c3)
            wp.atomic_add(camera_grad, 4, c4)
            wp.atomic_add(camera_grad, 5, c5)
        if want_image != 0:
            film[tid] = film[tid] + acc

    return replay_pathwise


def get_pathwise_kernel(features: Features, integrator: str, sampler: str, max_depth: int,
                        device: str = "cpu") -> wp.Kernel:
    """The pathwise path-replay kernel of (integrator, sampler) for these features, loaded on
    ``device``; its scratch rows hold ``max_depth + 1`` states (``scratch_shape``).

    Inputs: the scene structs (arrays whose gradients are wanted carry ``.grad``), the camera, the
    render parameters (a tile), the adjoint image of the tile, ``want_image`` with the tile's float64
    film, the camera deltas' gradient (6 vec3), and the scratch (:func:`scratch`)."""
    check_depth(max_depth)
    k = kernel_cache.cached("replay_pathwise", (integrator, sampler, features, max_depth),
                            lambda: _build(features, integrator, sampler, max_depth))
    return kernel_cache.load(k, device)     # on this thread, before any worker launches it


def check_depth(max_depth: int) -> None:
    if not 1 <= max_depth <= MAX_PATHWISE_DEPTH:
        raise ValueError(f"max_depth must be in [1, {MAX_PATHWISE_DEPTH}] for geometry, camera, fuzz or "
                         f"light-position gradients (its scratch holds every vertex of a path)")


def _build(features: Features, integrator: str, sampler: str, max_depth: int) -> wp.Kernel:
    vertex, start_path = get_vertex(integrator, sampler, features, True, pathwise=True)
    # the first pass runs the fast kernel's vertex (path replay's own, inlined: the same values)
    forward = get_vertex(integrator, sampler, features, True)[0]
    # Warp 1.19: the adjoint-code flag reaches callees only while a function is built (see diff.prb)
    # (and pass 1 builds start_path before the camera's wp.grad needs its adjoint)
    for f in (vertex, forward, start_path):
        f.adj.force_adjoint_codegen = True
    return _make_kernel(vertex, forward, start_path, make_hit(features), make_refine_hit(features), max_depth)


def scratch(pixels: int, max_depth: int, device) -> tuple[wp.array, wp.array]:
    """One worker's scratch: ``pixels`` rows of ``max_depth + 1`` path states and hits."""
    return (wp.empty((pixels, max_depth + 1), dtype=PathState, device=device),
            wp.empty((pixels, max_depth + 1), dtype=Hit, device=device))


def pathwise_inputs(scene_args: list, adj_image: wp.array, want_image: bool, film: wp.array,
                    camera_grad: wp.array, rows: tuple) -> list:
    """The kernel's inputs after the scene's (``Bound.scene_args``), in its order."""
    return [*scene_args, adj_image, int(want_image), film, camera_grad, *rows]


register_kind(KernelKind("replay_pathwise", lambda b: get_pathwise_kernel(
    b.features, b.integrator.name, b.settings.sampler, b.settings.max_depth, b.dev.device), render_features))
