"""Path-replay backpropagation (Vicini, Speierer and Jakob 2021; Mitsuba 3's ``prb`` integrator).

The gradient of a path's radiance ``L = sum_k T_k * C_k`` (``T_k`` the throughput before vertex k,
``C_k`` what vertex k adds: emission, sky, light sampling; ``T_{k+1} = T_k * w_k``) is

    dL/dθ = sum_k  T_k * dC_k/dθ  +  T_k * dw_k/dθ * Lo_{k+1},     Lo_{k+1} = (L - R_{k+1}) / T_{k+1}

where ``R_{k+1}`` is the radiance gathered up to and including vertex k: the light that still
arrives from beyond vertex k, per unit throughput, is the path's total minus what came before. So
one pass that knows ``L`` can walk the path again *forwards* and add each vertex's term as it goes:
nothing is stored per vertex, the depth is unbounded, and memory does not depend on spp or depth.

Per sample, the replay kernel (forward-only, ``enable_backward=False``, a dynamic loop):

1. traces the path as the fast kernel does (closest hit + the integrator's ``vertex``, inlined as
   there) to get ``L``, and sums it into the pixel's film, so that ``render_gradients`` needs no
   separate forward render for the image when it knows the adjoint image beforehand;
2. traces it again with the same random numbers; at each vertex it calls ``wp.grad`` of a scalar
   ``objective = a . R_{k+1} + b . T_{k+1}`` of that one vertex, with ``a`` the pixel's adjoint per
   sample and ``b = a * Lo_{k+1}`` held constant. The vertex is the integrator's own ``vertex``
   function (``Integrator.make_vertex``), the very code ``step`` runs after its closest hit: the hit
   is found outside the differentiated function, and the visibility of the light sample is passed
   in (``vis``, what the forward call returned), so its adjoint never traces a ray. The adjoints
   of array reads land in the arrays' ``.grad`` buffers (per-tile aliases, as for the tape).

Russian roulette replays its decisions; its survival probability carries no derivative
(``integrators.nee.detached``). Where a vertex sets a channel of the throughput to exactly 0, ``Lo``
of that channel is unknown from the ratio: it gets no gradient from later bounces (a limit).

Sampling is *detached* (directions do not move with θ), as in Mitsuba's PRB, which is unbiased for
parameters that change the integrand but not the sampled directions: colours, emission, texels,
procedural-texture parameters, the sky's colours (constant, or the gradient's zenith and nadir),
and ``Roughness`` through the score term (``materials.lobe_weight``) and the diffuse density.
The sampling itself carries no derivative either: the light sample's point, direction and density
(``emitters.detach_lights``) and the MIS weights (``nee``'s ``mis_weight``). Held at their values, the
two techniques' weights still sum to 1 at every point, so their derivatives would only add terms
whose expectation is 0; dropping them keeps the gradient unbiased, and each vertex's adjoint is one
call (the BSDF-side weight of the next vertex would otherwise need this vertex's density
differentiated again) whose callees do not re-run the light sampler's forward code for adjoints
that were then thrown away. The tape differentiates the weights (its camera moves the points where
they are evaluated, and there the cancellation does not hold), so the two agree in expectation on
``Roughness`` under NEE and exactly elsewhere.

Pathwise derivatives (``Fuzz``, which bends the sampled direction, and the camera, which moves
every hit: the tape's closest hit is re-intersected in closed form for it) need the derivative of
everything downstream with respect to a direction or a hit: not available in a forward replay, so
they stay on the tape (``render_gradients(mode="tape")``, which ``"auto"`` takes for them).

Warp 1.19 notes: ``wp.grad(f)`` of a function returning ``float`` emits ``float(1)``, which the
CPU build's ``float`` macro breaks; ``-> wp.float32`` compiles. A ``wp.grad`` call zero-initialises
the adjoints of its struct arguments, whose arrays then fall back to ``array.grad``. The flag that
makes ``wp.grad`` generate adjoint code reaches a function's callees only if it is set before that
function is built, and the module hash does not include it (see ``get_replay_kernel``).
"""

from __future__ import annotations

import warp as wp

from warp_spt.device.camera_rays import CameraParams
from warp_spt.device.structs import Features, Geometry, Materials, Textures
from warp_spt.bsdfs.cutout import make_hit
from warp_spt.accel.ray_queries import Hit
from warp_spt.emitters import Lights
from warp_spt.integrators import PathState, RenderParams, get_vertex
from warp_spt.integrators.nee import VIS_TRACE
from warp_spt.rendering.setup import KernelKind, register_kind, render_features
from warp_spt.runtime import kernel_cache


@wp.func
def remaining(total: wp.vec3, gathered: wp.vec3, throughput: wp.vec3) -> wp.vec3:
    """(total - gathered) / throughput per channel, 0 where the throughput is 0: a channel a vertex
    set to exactly 0 then gets no gradient from later bounces (docs/gradients.md, Limits)."""
    out = wp.vec3(0.0, 0.0, 0.0)
    for c in range(3):
        if throughput[c] != 0.0:
            out[c] = (total[c] - gathered[c]) / throughput[c]
    return out


@wp.func
def sample_adjoint(adj_image: wp.array(dtype=wp.vec3), tid: int, sample_count: int) -> wp.vec3:
    """d loss / d (one sample's radiance) of pixel ``tid``: its adjoint shared by its samples."""
    return adj_image[tid] / float(sample_count)


@wp.func
def is_zero(a: wp.vec3) -> bool:
    return a[0] == 0.0 and a[1] == 0.0 and a[2] == 0.0


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


def _make_kernel(vertex, forward, start_path, hit, inline):
    @wp.func(inline=inline)
    def objective(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
                  path: PathState, h: Hit, vis: int, a: wp.vec3, b: wp.vec3) -> wp.float32:
        """What vertex ``path``/``h`` adds to the image, and its throughput seeded with the adjoint
        of what follows (constants here); ``vis`` the visibility its forward call found."""
        p = vertex(geo, mats, tex, lights, rp, path, h, vis)
        return wp.dot(p.radiance, a) + wp.dot(p.throughput, b)

    @wp.func
    def finish(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
               path: PathState) -> PathState:
        """The rest of the path, as the fast kernel traces it."""
        q = path
        while q.alive != 0:
            q = forward(geo, mats, tex, lights, rp, q, hit(geo, mats, tex, q.o, q.d), VIS_TRACE)
        return q

    @wp.kernel(enable_backward=False, module="unique")
    def replay(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, cam: CameraParams,
               rp: RenderParams, adj_image: wp.array(dtype=wp.vec3), want_image: int,
               film: wp.array(dtype=wp.vec3d)):
        """Each thread replays the samples of one pixel of the tile; with ``want_image`` it also adds
        the pass-1 radiance sums to ``film`` (the fast kernel's sums: same paths, same order)."""
        tid = wp.tid()
        a = sample_adjoint(adj_image, tid, rp.sample_count)
        replay_it = not is_zero(a)
        if not replay_it and want_image == 0:
            return
        pix = rp.pixel_start + tid
        zero = wp.vec3(0.0, 0.0, 0.0)
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
            while q.alive != 0:
                h = hit(geo, mats, tex, q.o, q.d)
                nxt = forward(geo, mats, tex, lights, rp, q, h, VIS_TRACE)
                b = zero
                if nxt.alive != 0:
                    b = wp.cw_mul(a, remaining(total, nxt.radiance, nxt.throughput))
                # the adjoints of array reads (materials, texels, the sky's colours) land in the arrays' .grad
                ag, am, at, al, arp, apath, ah, av, aa, ab = wp.grad(objective)(
                    geo, mats, tex, lights, rp, q, h, nxt.vis, a, b)
                q = nxt
        if want_image != 0:
            film[tid] = film[tid] + acc

    return replay


def get_replay_kernel(features: Features, integrator: str, sampler: str, device: str = "cpu",
                      inline: bool | None = True) -> wp.Kernel:
    """The path-replay kernel of (integrator, sampler) for these features, loaded on ``device``.

    Inputs: the scene structs (arrays whose gradients are wanted carry ``.grad``), the camera, the
    render parameters (a tile: ``pixel_start``, samples), the adjoint image of the tile, and
    ``want_image`` (0 or 1) with the tile's float64 film, to which the radiance sums are added when
    it is 1. (The sky's gradients, as the materials', land in its colour array's ``.grad``.)
    ``inline``: the wp.func inline hint of the differentiated vertex, its helpers and ``objective``
    (the forward passes always inline the vertex). On by default: Warp's adjoint of a function re-runs
    its forward, and of every out-of-line callee once more per nesting level; inlined, the compiler
    shares those re-runs with the caller's. It took the backward from about 2.8x to 2.0x the forward
    (kernel time, nee + sobol) for +4 s of cold compile (15 to 19 s; docs/gradients.md, Cost)."""
    k = kernel_cache.cached("replay", (integrator, sampler, features, inline),
                            lambda: _build(features, integrator, sampler, inline))
    return kernel_cache.load(k, device)     # on this thread, before any worker launches it


def _build(features: Features, integrator: str, sampler: str, inline: bool | None) -> wp.Kernel:
    vertex, start_path = get_vertex(integrator, sampler, features, inline)
    # the forward passes run the vertex inlined (the fast kernel's choice, nee.make_path_step): called
    # out of line, each bounce copied the scene structs, and pass 1 took 1.2-1.4x the fast kernel
    forward = get_vertex(integrator, sampler, features, True)[0]    # ``vertex`` itself by default
    # Warp 1.19: wp.grad flags its function for adjoint code, and a function passes the flag to its
    # callees only while it is being built. The kernel builds ``forward`` first (pass 1), and with it
    # the callees it shares with ``vertex`` (texture lookups, the materials' helpers): unflagged, they
    # got empty adjoints (texel gradients 0). So both are flagged before the build. (Warp's module
    # hash does not include the flags: a kernel once built without them stays wrong in the cache.)
    # get_vertex's functions are path replay's own: the fast and tape kernels build theirs in get_step.
    vertex.adj.force_adjoint_codegen = True
    forward.adj.force_adjoint_codegen = True
    _skip_replay(vertex)
    return _make_kernel(vertex, forward, start_path, make_hit(features), inline)


def replay_inputs(scene_args: list, adj_image: wp.array, want_image: bool, film: wp.array) -> list:
    """The replay kernel's inputs after the scene's (``Bound.scene_args``), in its order."""
    return [*scene_args, adj_image, int(want_image), film]


register_kind(KernelKind("replay", lambda b: get_replay_kernel(
    b.features, b.integrator.name, b.settings.sampler, b.dev.device), render_features))
