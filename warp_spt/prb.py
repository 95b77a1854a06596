"""Path-replay backpropagation (Vicini, Speierer and Jakob 2021; Mitsuba 3's ``prb`` integrator).

The gradient of a path's radiance ``L = sum_k T_k * C_k`` (``T_k`` the throughput before vertex k,
``C_k`` what vertex k adds: emission, sky, light sampling; ``T_{k+1} = T_k * w_k``) is

    dL/dθ = sum_k  T_k * dC_k/dθ  +  T_k * dw_k/dθ * Lo_{k+1},     Lo_{k+1} = (L - R_{k+1}) / T_{k+1}

where ``R_{k+1}`` is the radiance gathered up to and including vertex k: the light that still
arrives from beyond vertex k, per unit throughput, is the path's total minus what came before. So
one pass that knows ``L`` can walk the path again *forwards* and add each vertex's term as it goes:
nothing is stored per vertex, the depth is unbounded, and memory does not depend on spp or depth.

Per sample, the replay kernel (forward-only, ``enable_backward=False``, a dynamic loop):

1. traces the path as the fast kernel does (closest hit + the integrator's ``vertex``) to get ``L``,
   and sums it into the pixel's film, so that ``render_gradients`` needs no separate forward render
   for the image when it knows the adjoint image beforehand;
2. traces it again with the same random numbers; at each vertex it calls ``wp.grad`` of a scalar
   ``objective = a . R_{k+1} + b . T_{k+1}`` of that one vertex, with ``a`` the pixel's adjoint per
   sample and ``b = a * Lo_{k+1}`` held constant. The vertex is the integrator's own ``vertex``
   function (``integrators.VERTICES``), the very code ``step`` runs after its closest hit: the hit
   is found outside the differentiated function, and the visibility of the light sample is passed
   in (``vis``, what the forward call returned), so its adjoint never traces a ray. The adjoints
   of array reads land in the arrays' ``.grad`` buffers (per-tile aliases, as for the tape).

Russian roulette replays its decisions; its survival probability carries no derivative
(``integrators.nee.detached``). Where a vertex sets a channel of the throughput to exactly 0, ``Lo``
of that channel is unknown from the ratio: it gets no gradient from later bounces (a limit).

Sampling is *detached* (directions do not move with θ), as in Mitsuba's PRB, which is unbiased for
parameters that change the integrand but not the sampled directions: colours, emission, texels,
procedural-texture parameters, the sky's colours (constant, or the gradient's mean and slope),
and ``Roughness`` through the score term (``materials.lobe_weight``) and the diffuse density.
MIS weights: the light-sampling weight sees its diffuse density as the tape does, and the BSDF-side
weight at the *next* vertex depends on this vertex's sampled density, so when that next vertex's
adjoint reaches its incoming ``pdf`` the previous vertex is differentiated once more with that seed
(``c``). Pathwise derivatives (``Fuzz``, which bends the sampled direction, and the camera, which
moves every hit: the tape's closest hit is re-intersected in closed form for it) need the
derivative of everything downstream with respect to a direction or a hit: not available in a
forward replay, so they stay on the tape (``render_gradients(mode="tape")``, which ``"auto"``
takes for them).

Warp 1.19 notes: ``wp.grad(f)`` of a function returning ``float`` emits ``float(1)``, which the
CPU build's ``float`` macro breaks; ``-> wp.float32`` compiles. A ``wp.grad`` call zero-initialises
the adjoints of its struct arguments, whose arrays then fall back to ``array.grad``. The flag that
makes ``wp.grad`` generate adjoint code reaches a function's callees only if it is set before that
function is built (see ``get_replay_kernel``).
"""

from __future__ import annotations

import warp as wp

from .device_scene import Features, Geometry, Materials, Textures
from .geometry import NO_HIT, Hit, make_closest_hit
from .integrators import CameraParams, PathState, RenderParams, get_vertex
from .integrators.nee import VIS_TRACE
from .lights import Lights

_kernels: dict[tuple, wp.Kernel] = {}


@wp.func
def remaining(total: wp.vec3, gathered: wp.vec3, throughput: wp.vec3) -> wp.vec3:
    """(total - gathered) / throughput per channel, 0 where the throughput is 0: a channel a vertex
    set to exactly 0 then gets no gradient from later bounces (docs/gradients.md, Limits)."""
    out = wp.vec3(0.0, 0.0, 0.0)
    for c in range(3):
        if throughput[c] != 0.0:
            out[c] = (total[c] - gathered[c]) / throughput[c]
    return out


def _skip_replay(vertex) -> None:
    """Inside ``objective``'s adjoint, Warp replays ``vertex`` forward and then calls its adjoint,
    which replays it again; the first replay is wasted (the adjoint of ``objective``'s dot products
    needs only the seeds, not ``vertex``'s value), so it returns its input unchanged. Only path
    replay's own ``vertex`` (``get_vertex``) gets this replay."""

    @wp.func_replay(vertex)
    def replay_vertex(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
                      path: PathState, h: Hit, vis: int):
        return path

    # Warp 1.19 names the replay after its own counter ("replay_<key>_0") but calls it after the
    # closure's ("replay_<key>_<n>"): give it the name the call site uses
    vertex.custom_replay_func.native_func = "replay_" + vertex.native_func


def _make_kernel(vertex, start_path, closest_hit, inline):
    @wp.func(inline=inline)
    def objective(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
                  path: PathState, h: Hit, vis: int, a: wp.vec3, b: wp.vec3, c: float) -> wp.float32:
        """What vertex ``path``/``h`` adds to the image, its throughput and density seeded with the
        adjoints of what follows (constants here); ``vis`` the visibility its forward call found."""
        p = vertex(geo, mats, tex, lights, rp, path, h, vis)
        return wp.dot(p.radiance, a) + wp.dot(p.throughput, b) + p.pdf * c

    @wp.func
    def finish(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
               path: PathState) -> PathState:
        """The rest of the path, as the fast kernel traces it."""
        q = path
        while q.alive != 0:
            q = vertex(geo, mats, tex, lights, rp, q, closest_hit(geo, q.o, q.d, NO_HIT), VIS_TRACE)
        return q

    @wp.kernel(enable_backward=False, module="unique")
    def replay(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, cam: CameraParams,
               rp: RenderParams, adj_image: wp.array(dtype=wp.vec3), sky_grad: wp.array(dtype=wp.vec3),
               want_image: int, film: wp.array(dtype=wp.vec3d)):
        """Each thread replays the samples of one pixel of the tile; with ``want_image`` it also adds
        the pass-1 radiance sums to ``film`` (the fast kernel's sums: same paths, same order)."""
        tid = wp.tid()
        a = adj_image[tid] / float(rp.sample_count)       # d loss / d (one sample's radiance)
        replay_it = not (a[0] == 0.0 and a[1] == 0.0 and a[2] == 0.0)
        if not replay_it and want_image == 0:
            return
        pix = rp.pixel_start + tid
        zero = wp.vec3(0.0, 0.0, 0.0)
        sky = zero                               # d loss / d Lights.sky_color and .sky_slope
        slope = zero
        acc = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0))
        for j in range(rp.sample_count):
            start = start_path(cam, pix, rp.width, rp.seed, rp.sample_start + j)
            total = finish(geo, mats, tex, lights, rp, start).radiance    # pass 1: the sample's radiance
            if not wp.isfinite(total):
                continue                         # the fast kernel drops it: no gradient either
            acc += wp.vec3d(wp.float64(total[0]), wp.float64(total[1]), wp.float64(total[2]))
            if not replay_it:
                continue
            q = start                            # pass 2: replay, one vertex's adjoint at a time
            prev = start
            prev_h = Hit()
            prev_vis = int(VIS_TRACE)
            for k in range(rp.max_depth + 1):    # the bound is never reached: max_depth ends the path
                if q.alive == 0:
                    break
                h = closest_hit(geo, q.o, q.d, NO_HIT)
                nxt = vertex(geo, mats, tex, lights, rp, q, h, VIS_TRACE)
                vis = nxt.vis
                b = zero
                if nxt.alive != 0:
                    b = wp.cw_mul(a, remaining(total, nxt.radiance, nxt.throughput))
                ag, am, at, al, arp, apath, ah, av, aa, ab, ac = wp.grad(objective)(
                    geo, mats, tex, lights, rp, q, h, vis, a, b, 0.0)
                sky += al.sky_color
                slope += al.sky_slope
                if k > 0 and apath.pdf != 0.0:   # this vertex's MIS weight uses the previous density
                    ag, am, at, al, arp, apath, ah, av, aa, ab, ac = wp.grad(objective)(
                        geo, mats, tex, lights, rp, prev, prev_h, prev_vis, zero, zero, apath.pdf)
                    sky += al.sky_color
                    slope += al.sky_slope
                prev = q
                prev_h = h
                prev_vis = vis
                q = nxt
        if want_image != 0:
            film[tid] = film[tid] + acc
        wp.atomic_add(sky_grad, 0, sky)
        wp.atomic_add(sky_grad, 1, slope)

    return replay


def get_replay_kernel(features: Features, integrator: str, sampler: str, device: str = "cpu",
                      inline: bool | None = None) -> wp.Kernel:
    """The path-replay kernel of (integrator, sampler) for these features, loaded on ``device``.

    Inputs: the scene structs (arrays whose gradients are wanted carry ``.grad``), the camera, the
    render parameters (a tile: ``pixel_start``, samples), the adjoint image of the tile, an
    array receiving d loss / d ``Lights.sky_color`` (element 0) and ``Lights.sky_slope`` (element 1:
    the gradient sky's slope), the layout of ``gradients.D_SKY``/``D_SKY_SLOPE``, and ``want_image``
    (0 or 1) with the tile's float64 film, to which the radiance sums are added when it is 1.
    ``inline``: the wp.func inline hint of the vertex, its helpers and ``objective``. Off by default:
    True saves about 0.2x the forward time per backward but doubles the replay kernel's cold compile
    (docs/gradients.md, Cost), which the test suite's six replay kernels could not afford."""
    key = (integrator, sampler, features, inline)
    if key not in _kernels:
        vertex, start_path = get_vertex(integrator, sampler, features, inline)
        # Warp 1.19: wp.grad flags its function for adjoint code, and a function passes the flag to
        # its callees when it is built; but pass 1 builds ``vertex`` first, without the flag, so its
        # callees got empty adjoints (all gradients 0). Flag it before the build. (get_vertex's
        # functions are path replay's own: the fast and tape kernels build theirs in get_step.)
        vertex.adj.force_adjoint_codegen = True
        _skip_replay(vertex)
        _kernels[key] = _make_kernel(vertex, start_path, make_closest_hit(features), inline)
    k = _kernels[key]
    wp.load_module(k.module, device=device)     # on this thread, before any worker launches it
    return k
