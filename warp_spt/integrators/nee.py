"""Next-event estimation with multiple importance sampling (power heuristic), and Russian roulette.

At every vertex whose material has a lobe with a density (diffuse or glossy: ``lobes &
LOBE_SMOOTH``, the material contract's flags), one light is
sampled from the light table (``warp_spt.emitters``) and joined by an any-hit shadow ray; the BSDF
sample that continues the path may hit an emitter too, and each of the two estimates is weighted by
the power heuristic, so their sum counts each light path once. Specular lobes (the seed's fuzzy
mirror and glass, smooth metal and glass) continue by sampling only and the emitter they hit counts in full. Camera rays count emitters in
full. NEE happens only at vertices that may still scatter (hits < max_depth), so the image
converges to the seed integrator's.

Russian roulette from ``roulette_depth`` hits on: survive with probability min(1, max throughput
component), and divide by it: unbiased. A scene whose lights (emitters and sky) are all dark
compiles no light-sampling code and behaves as the seed integrator plus roulette.
"""

from dataclasses import dataclass
from typing import Callable

import warp as wp

from warp_spt.device.adjoint import zero_adjoint
from warp_spt.device.structs import Features, Geometry, Materials, Textures
from warp_spt.bsdfs.cutout import make_blocked, make_hit
from warp_spt.accel.ray_queries import KIND_MISS, Hit
from warp_spt.emitters import LightSample, Lights, detach_lights, make_lights, reuse_pick
from warp_spt.device.lobes import LOBE_SMOOTH
from warp_spt.bsdfs import make_materials
from warp_spt.accel.surface import Surface, detach_surface, make_surface, offset_origin
from warp_spt.integrators.common import (
    DIM_BOUNCE,
    FULL_STRIDE,
    OFF_DIR,
    OFF_FRESNEL,
    OFF_LIGHT,
    OFF_LIGHT_POS,
    OFF_LOBE,
    OFF_ROULETTE,
    SEED_STRIDE,
    Integrator,
    PathState,
    RenderParams,
    continue_path,
    finite3,
    make_bsdf_dims,
)
from warp_spt.samplers import Sampler, SamplerState, batch_lanes

STRIDE = FULL_STRIDE
# the ``vis`` argument of ``vertex``: the shadow ray's answer when the caller knows it (path replay's
# adjoint, which must not trace), or VIS_TRACE: trace it (what ``vertex`` returns when it traced none)
VIS_TRACE = wp.constant(-1)
VIS_OCCLUDED = wp.constant(0)
VIS_VISIBLE = wp.constant(1)


@wp.func
def power_heuristic(pa: float, pb: float) -> float:
    """Weight of technique a when b could also have produced the sample (beta = 2)."""
    a2 = pa * pa
    return a2 / (a2 + pb * pb)


@wp.func
def detached(x: float) -> float:
    """``x``, through which no derivative flows (its adjoint is 0): Russian roulette's survival
    probability, and in path replay the MIS weights (``mis_weight``). For roulette: the estimator
    ``X / q`` with probability ``q`` has expectation ``X`` whatever ``q``, so the unbiased derivative
    is ``X' / q`` on survival; differentiating ``1 / q`` too would add ``-X q' / q`` in expectation
    (docs/gradients.md, Russian roulette)."""
    return x


zero_adjoint(detached, (float,))


def make(features: Features, sampler: Sampler, differentiable: bool = False):
    """The bounce step of NEE + MIS for scenes with these features (``differentiable``: for the tape's
    differentiable kernel, hits carry derivatives in the ray, ``geometry.make_closest_hit``; cut-outs:
``bsdfs.cutout``)."""
    return make_path_step(features, sampler, light_sampling=True, differentiable=differentiable)


def make_vertex(features: Features, sampler: Sampler, inline: bool | None = None, pathwise: bool = False):
    """The NEE + MIS vertex (``make_path_vertex``): what path replay differentiates (``pathwise``:
    with every derivative the tape's has, for ``diff.replay_pathwise``)."""
    return make_path_vertex(features, sampler, light_sampling=True, inline=inline, replay=not pathwise,
                            differentiable=pathwise)


INTEGRATOR = Integrator("nee", make, make_vertex, STRIDE, pathwise=True,
                        summary="next-event estimation: a light sample at every vertex, MIS with the BSDF")


def make_light_sample(sampler: Sampler, light, inline: bool | None = None, drawn: bool = False):
    """``light_sample(geo, lights, state, sf, base) -> (light sample, shadow ray origin, state)``: the
    light sample of a vertex at ``sf`` whose bounce's dimensions start at ``base`` (the light choice
    and the point on it, from ``light.sample_li``); shared by ``nee``'s vertex and ``volpath``'s
    medium vertex. ``drawn`` (random-access samplers): ``light_sample(geo, lights, state, sf, base,
    u)`` takes the 2-D request at ``base + OFF_LIGHT_POS`` already drawn (a batch) as ``u``."""

    @wp.func(inline=inline)
    def light_sample_drawn(geo: Geometry, lights: Lights, state: SamplerState, sf: Surface, base: int,
                           u: wp.vec2):
        # one 2D request chooses the light and the point on it (the choice's leftover bits become
        # the point's first coordinate), saving a request per vertex; the light dimension is drawn
        # only where a light is too unlikely to leave enough bits
        st = state
        u_pos = u
        u_pick = u_pos[0]
        if lights.num_entries > 1:
            rest = reuse_pick(lights, u_pick)
            if rest < 0.0:
                rest, st = sampler.next_1d(st, base + OFF_LIGHT)
            u_pos = wp.vec2(rest, u_pos[1])
        x = offset_origin(sf.p, sf.ng, 0, geo.extent)
        return light.sample_li(geo, lights, x, u_pick, u_pos), x, st

    if drawn:
        return light_sample_drawn

    @wp.func(inline=inline)
    def light_sample(geo: Geometry, lights: Lights, state: SamplerState, sf: Surface, base: int):
        if wp.static(sampler.random_access):
            u_pos, st = sampler.next_2d(state, base + OFF_LIGHT_POS)
            return light_sample_drawn(geo, lights, st, sf, base, u_pos)
        st = state
        u_pick = float(0.0)
        if lights.num_entries > 1:
            u_pick, st = sampler.next_1d(st, base + OFF_LIGHT)
        u_pos, st = sampler.next_2d(st, base + OFF_LIGHT_POS)
        x = offset_origin(sf.p, sf.ng, 0, geo.extent)
        return light.sample_li(geo, lights, x, u_pick, u_pos), x, st

    return light_sample


def make_roulette(sampler: Sampler):
    """``roulette(p, rp, dim) -> PathState``: Russian roulette on the throughput from
    ``rp.roulette_depth`` on (survival probability its largest channel, at most 1; the number from
    sample dimension ``dim``); shared by ``nee``'s surface vertex and ``volpath``'s medium vertex."""

    @wp.func(inline=True)
    def roulette(path: PathState, rp: RenderParams, dim: int) -> PathState:
        p = path
        if rp.roulette_depth > 0 and p.depth >= rp.roulette_depth and p.alive != 0:
            u_rr, st = sampler.next_1d(p.sampler, dim)
            p.sampler = st
            q = detached(wp.min(wp.max(wp.max(p.throughput[0], p.throughput[1]), p.throughput[2]), 1.0))
            if u_rr >= q:
                p.alive = 0
            else:
                p.throughput = p.throughput / q
        return p

    return roulette


@wp.func
def shadow_ray(sf: Surface, x: wp.vec3, ls: LightSample, extent: float):
    """(origin, direction, length) of the shadow ray of light sample ``ls``, drawn from ``x`` (the
    point offset to the side the ray came from): a light on the other side of the surface, reached
    through a transmitting lobe (rough glass), is traced from that other side (traced from ``x``, it
    was always blocked by the surface itself: rough glass under nee rendered 2% dark)."""
    if wp.dot(ls.dir, sf.ng) >= 0.0:
        return x, ls.dir, ls.t_max
    o = offset_origin(sf.p, sf.ng, 1, extent)
    if ls.h.kind == KIND_MISS:          # an infinite light: the direction is all there is
        return o, ls.dir, ls.t_max
    d = (x + ls.dir * ls.t_max) - o     # to the same point just short of the emitter
    t = wp.length(d)
    return o, d / t, t


def make_path_step(features: Features, sampler: Sampler, light_sampling: bool, differentiable: bool = False,
                   hooks: "VertexHooks | None" = None):
    """A path-tracing bounce step: trace the path's ray, then ``make_path_vertex``'s vertex at what it
    meets. ``light_sampling`` False leaves pure BSDF sampling, no roulette, and the seed's four
    dimensions per bounce (``integrators.seed``); ``differentiable`` re-intersects the hit in closed
    form so that it carries derivatives in the ray (the tape kernel only). ``hooks``
    (:class:`VertexHooks`): an integrator built on this vertex (``guided``, ``ears``); its step is
    ``step(geo, mats, tex, lights, rp, path, aux)`` and returns what ``hooks.finish`` makes."""
    hit = make_hit(features, differentiable=differentiable)
    # the fast kernel inlines the step and its vertex: called out of line, each bounce copied the scene
    # structs they take by value (about 2 KB); the tape kernel, unrolled, keeps the compiler's choice
    inline = None if differentiable else True
    vertex = make_path_vertex(features, sampler, light_sampling, inline=inline, hooks=hooks,
                              batched=not differentiable, differentiable=differentiable)
    if hooks is not None:
        Aux = hooks.Aux

        @wp.func(inline=True)
        def hooked_step(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
                        path: PathState, aux: Aux):
            p = path
            h = hit(geo, mats, tex, p.o, p.d)
            p.rays += 1
            return vertex(geo, mats, tex, lights, rp, p, h, aux)

        return hooked_step

    @wp.func(inline=inline)
    def step(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
             path: PathState) -> PathState:
        p = path
        h = hit(geo, mats, tex, p.o, p.d)
        p.rays += 1
        return vertex(geo, mats, tex, lights, rp, p, h, VIS_TRACE)

    return step


@dataclass(frozen=True)
class VertexHooks:
    """What an integrator built on ``nee``'s vertex (``make_path_vertex(hooks=...)``) changes in it:
    Warp functions, each inlined where the vertex would otherwise do ``nee``'s own thing. Emission,
    the sky, light sampling and its MIS, the depth limit and the sample dimensions stay the vertex's.

    * ``Aux``: the type (a ``wp.struct``) of the vertex's last argument, the integrator's per-launch
      data (its learnt tables), in place of ``nee``'s visibility; the vertex traces its shadow rays.
    * ``new_out() -> out``: what the vertex reports besides the path (recording data, a value of the
      integrator's own type), as at a vertex that reports nothing; ``finish(p, out)``: the vertex's
      (and the step's) return value (e.g. the tuple ``(p, out)``).
    * ``emitted(out, le) -> out``: recording callback for the radiance (vec3, throughput and MIS
      weight included) the vertex's own hit adds (an emitter met, the sky); None: nothing.
    * ``guide(aux, mats, tex, sf) -> guide``: the direction hook's state at this vertex
      (looked up once, before light sampling); ``share(guide) -> float``: the fraction of the
      material's density in the direction's, which MIS against light sampling weighs (1: ``nee``);
      ``sample(aux, guide, mats, tex, sf, u_lobe, u_dir, u_fresnel) -> (BsdfSample, pdf)``: the
      direction that continues the path, and the density it was drawn with. None: the material's.
    * ``record(aux, guide, out, sf, bs, pdf) -> out``: recording callback for the direction taken.
    * ``leave(aux, out, p, rp, dim) -> (PathState, out)``: the continuation after the direction
      (``dim``: the bounce's roulette dimension); None: ``nee``'s Russian roulette.
    """

    Aux: type
    new_out: Callable
    finish: Callable
    emitted: Callable | None = None
    guide: Callable | None = None
    share: Callable | None = None
    sample: Callable | None = None
    record: Callable | None = None
    leave: Callable | None = None


def make_path_vertex(features: Features, sampler: Sampler, light_sampling: bool, inline: bool | None = None,
                     replay: bool = False, media=None, hooks: VertexHooks | None = None, batched: bool = False,
                     differentiable: bool = False):
    """``vertex(geo, mats, tex, lights, rp, path, hit, vis) -> PathState``: everything a bounce does
    once its ray has met ``hit`` (sky, emission, light sampling, the next direction, roulette). The
    fast and tape kernels run it inside ``step`` with ``vis`` = VIS_TRACE (it traces its shadow ray);
    path replay (``warp_spt.diff.prb``) differentiates it alone, with the hit found outside and the
    visibility its forward call found (the result's ``vis``) passed in, so its adjoint never traces
    a ray. (One result, not a tuple: Warp 1.19 ignores the custom replay of a function with two.)
    ``inline``: wp.func's inline hint (the fast kernel's step inlines it). ``replay``: for path
    replay, which differentiates the vertex alone: its helpers (``direct``, ``mis_bsdf``) take the
    vertex's hint too, and the surface's adjoint is zero (``surface.detach_surface``). ``media``: the
    hooks of an integrator that tracks participating media (``integrators.volpath``): its
    ``shadow(geo, mats, tex, path, sf, o, d, t_max) -> T`` traces the shadow ray in place of
    ``blocked`` and returns the transmittance of the media it crosses (0: occluded), which weighs the
    light sample; None (every other integrator) compiles none of it. ``hooks``: an integrator's changes
    (:class:`VertexHooks`: direction sampling, continuation, recording); the vertex's last argument
    is then its ``Aux`` data and it returns ``hooks.finish(path, out)``; None compiles none of it.
    ``batched`` (forward kernels): where the sampler has ``make_batch``, the vertex's BSDF and light
    point requests are drawn as one batch at its start: the same numbers at a fraction of the cost
    (the light point is drawn for nothing at a vertex without a smooth lobe; the lanes make it cheap).
    ``differentiable`` (the tape's step): the surface point moves with the hit primitive
    (``surface.make_surface``)."""
    surface_at = make_surface(features, differentiable)
    if replay:
        detach_surface(surface_at)
    inline_callees = inline
    mat = make_materials(features)
    stride = STRIDE if light_sampling else SEED_STRIDE
    bsdf_dims = make_bsdf_dims(sampler, stride, features)
    sample_lights = light_sampling and features.samples_lights and features.scatters
    blocked = make_blocked(features)
    light = make_lights(features, surface_at, mat.emission)
    roulette = make_roulette(sampler)
    if replay:
        detach_lights(light)
    hooked = hooks is not None
    directed = hooked and hooks.sample is not None      # the direction comes from the hooks
    # the vertex's last argument: nee's shadow-ray visibility, or a hooked integrator's own data
    Aux = hooks.Aux if hooked else int

    light_sample = make_light_sample(sampler, light, inline=inline_callees)

    # the batch's lanes (offset in the bounce's dimensions -> lane): the requests of every vertex that
    # scatters; the rare ones (the light's 1-D number when the pick leaves too few bits, roulette,
    # off by default) stay single requests, drawn only when needed
    lanes = {}
    if batched and sampler.random_access and sampler.make_batch is not None and media is None:
        wanted = [OFF_LOBE] if features.needs("dims.lobe") else []
        wanted.append(OFF_DIR)
        if features.needs("dims.fresnel"):
            wanted.append(OFF_FRESNEL)
        if sample_lights:
            wanted.append(OFF_LIGHT_POS)
        lanes = {off: k for k, off in enumerate(wanted)}
    batch = sampler.make_batch(tuple(lanes)) if lanes else None
    width = batch_lanes(len(lanes))      # the batch's y values start at entry ``width``
    L_LOBE, L_DIR = lanes.get(OFF_LOBE, 0), lanes.get(OFF_DIR, 0)
    L_FRESNEL, L_POS = lanes.get(OFF_FRESNEL, 0), lanes.get(OFF_LIGHT_POS, 0)
    light_sample_drawn = make_light_sample(sampler, light, inline=inline_callees, drawn=True) if lanes else None

    @wp.func
    def mis_weight(pa: float, pb: float) -> float:
        """The power heuristic; in path replay without derivative: the two techniques' weights sum to
        1 for every parameter value, so with the samples held still (detached sampling) the weights'
        derivatives cancel in expectation. (Not so on the tape: its camera moves the points where the
        weights are evaluated, so it keeps their derivatives.)"""
        if wp.static(replay):
            return detached(power_heuristic(pa, pb))
        return power_heuristic(pa, pb)

    @wp.func(inline=inline_callees)
    def mis_bsdf(p: PathState, pdf_light: float) -> float:
        """MIS weight of an emitter reached by BSDF sampling."""
        if wp.static(not sample_lights):
            return 1.0
        if p.singular != 0:
            return 1.0
        return mis_weight(p.pdf, pdf_light)

    @wp.func(inline=inline_callees)
    def direct(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, p: PathState, sf: Surface,
               base: int, vis: int, share: float, u_light: wp.vec2):
        """Light sampling at this vertex: (radiance to add, sampler state, visibility of the light
        sample: VIS_VISIBLE/VIS_OCCLUDED, VIS_TRACE if no shadow ray was needed). ``vis`` other than
        VIS_TRACE is taken as the shadow ray's answer instead of tracing it. ``share`` (hooked
        vertices only): the material's fraction of the direction's density, which MIS weighs.
        ``u_light`` (batched vertices only): the 2-D request at ``base + OFF_LIGHT_POS``."""
        contrib = wp.vec3(0.0, 0.0, 0.0)
        seen = int(VIS_TRACE)
        st = p.sampler
        if (mat.lobes(mats, tex, sf) & LOBE_SMOOTH) != 0:    # light sampling needs a lobe with a density
            # light.sample in two halves, the geometric one having no adjoint in path replay
            if wp.static(batch is not None):
                ls, x, st = light_sample_drawn(geo, lights, st, sf, base, u_light)
            else:
                ls, x, st = light_sample(geo, lights, st, sf, base)
            if ls.pdf > 0.0:
                f = mat.eval(mats, tex, sf, ls.dir)
                le = wp.cw_mul(f, light.le(geo, mats, tex, lights, ls, x))
                if wp.max(wp.max(le[0], le[1]), le[2]) > 0.0 or not finite3(le):   # NaN: the guard reports it
                    seen = vis
                    tr = wp.vec3(1.0, 1.0, 1.0)
                    if wp.static(media is not None):
                        seen = VIS_TRACE      # a transmittance, not only a visibility: traced again in replay
                    if seen == VIS_TRACE:
                        seen = VIS_VISIBLE
                        so, sd, st_max = shadow_ray(sf, x, ls, geo.extent)
                        if wp.static(media is None):
                            if blocked(geo, mats, tex, so, sd, st_max):
                                seen = VIS_OCCLUDED
                        else:
                            tr = media.shadow(geo, mats, tex, p, sf, so, sd, st_max)
                            if wp.max(wp.max(tr[0], tr[1]), tr[2]) <= 0.0:
                                seen = VIS_OCCLUDED
                    if seen == VIS_VISIBLE:
                        pb = mat.pdf(mats, tex, sf, ls.dir)
                        if wp.static(hooked):
                            # a hooked direction (a guide's mixture) is weighed by the material's share
                            # alone: MIS weights need only sum to 1, and the same density stands on the
                            # BSDF side (bs.pdf), so no guide look-up per light sample
                            pb = share * pb
                        w = light.mis_li(ls, mis_weight(ls.pdf, pb))
                        contrib = wp.cw_mul(p.throughput, le) * (w / ls.pdf)
                        if wp.static(media is not None):
                            contrib = wp.cw_mul(contrib, tr)
        return contrib, st, seen

    @wp.func(inline=inline)
    def vertex(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
               path: PathState, h: Hit, vis: Aux):
        p = path
        p.vis = VIS_TRACE
        if wp.static(hooked):
            out = hooks.new_out()
        if h.kind == KIND_MISS:
            w = mis_bsdf(p, light.pdf_miss(lights, p.d))
            hit_le = wp.cw_mul(p.throughput, light.le_escaped(lights, p.d, p.depth)) * w
            p.radiance += hit_le
            p.alive = 0
            if wp.static(hooked):
                if wp.static(hooks.emitted is not None):
                    out = hooks.emitted(out, hit_le)
                return hooks.finish(p, out)
            else:
                return p
        p.depth += 1
        sf = mat.shade(mats, tex, surface_at(geo, h, p.o, p.d))
        if wp.static(features.emitters):
            le = mat.emission(mats, tex, sf)
            if wp.max(wp.max(le[0], le[1]), le[2]) > 0.0 or not finite3(le):       # NaN: the guard reports it
                w = mis_bsdf(p, light.pdf_li(geo, lights, h, p.o, p.d))
                hit_le = wp.cw_mul(p.throughput, le) * w
                p.radiance += hit_le
                if wp.static(hooked and hooks.emitted is not None):
                    out = hooks.emitted(out, hit_le)
        if p.depth >= rp.max_depth:     # max_depth counts hits, as in the seed
            p.alive = 0
            if wp.static(hooked):
                return hooks.finish(p, out)
            else:
                return p
        base = DIM_BOUNCE + wp.static(stride) * (p.depth - 1)
        u_light = wp.vec2(0.0, 0.0)
        if wp.static(batch is not None):
            u = batch(p.sampler, base)
            u_lobe = float(0.0)
            if wp.static(OFF_LOBE in lanes):
                u_lobe = u[L_LOBE]
            u_dir = wp.vec2(u[L_DIR], u[L_DIR + wp.static(width)])
            u_fresnel = float(0.0)
            if wp.static(OFF_FRESNEL in lanes):
                u_fresnel = u[L_FRESNEL]
            if wp.static(OFF_LIGHT_POS in lanes):
                u_light = wp.vec2(u[L_POS], u[L_POS + wp.static(width)])
        else:
            u_lobe, u_dir, u_fresnel, p = bsdf_dims(p)       # dims in increasing order: bsdf, light, roulette
        share = float(1.0)
        if wp.static(directed):
            gv = hooks.guide(vis, mats, tex, sf)
            share = hooks.share(gv)
        if wp.static(sample_lights):
            if wp.static(hooked):      # ``vis`` is the hook's data: the shadow ray is traced
                contrib, st, seen = direct(geo, mats, tex, lights, p, sf, base, VIS_TRACE, share, u_light)
            else:
                contrib, st, seen = direct(geo, mats, tex, lights, p, sf, base, vis, share, u_light)
            # a copy, not p's own fields: Warp assigns struct fields in place, and the adjoint of
            # ``direct`` (gradients) replays it with ``p`` as it is at that point; an updated
            # p.sampler there drew other light samples (independent sampler: gradients off by up to 4x)
            lit = p
            lit.radiance += contrib
            lit.sampler = st
            lit.vis = seen
            p = lit
        if wp.static(directed):
            bs, pdf = hooks.sample(vis, gv, mats, tex, sf, u_lobe, u_dir, u_fresnel)
            if wp.static(hooks.record is not None):
                out = hooks.record(vis, gv, out, sf, bs, pdf)
            p = continue_path(p, sf, bs, geo.extent)
        else:
            p = continue_path(p, sf, mat.sample(mats, tex, sf, u_lobe, u_dir, u_fresnel), geo.extent)
        if wp.static(hooked and hooks.leave is not None):
            p, out = hooks.leave(vis, out, p, rp, base + OFF_ROULETTE)
        elif wp.static(light_sampling):
            p = roulette(p, rp, base + OFF_ROULETTE)
        if wp.static(hooked):
            return hooks.finish(p, out)
        else:
            return p

    return vertex
