"""Volumetric path tracing: ``nee``'s bounce with participating media (issue 35, docs/volumes.md).

Each step traces the path's ray to the next surface as ``nee`` does; where the ray travels in a
medium (``PathState.medium``), a free flight (delta tracking with spectral MIS over the RGB channels,
``media``) first decides whether it scatters in the medium before that surface. A scattering
vertex counts as a bounce (depth, sample dimensions, roulette): it samples a light (a shadow ray whose
transmittance ratio tracking estimates) with MIS against the phase function, then continues in a
Henyey-Greenstein direction. A ray that reaches the surface, weighed by the flight, goes on to
``nee``'s own vertex, with one hook: its light samples are weighed by the transmittance of the medium
their shadow ray crosses. A transmission through a surface whose material has an interior medium
(``Scene.interiors``) enters it, or leaves it for the scene's medium (``Scene.fog``, or none) when
the ray was in it; a surface without one keeps the ray's medium. Media do not nest: a medium inside
another closed medium mesh is left for the scene's medium, not the enclosing one.

A scene without media compiles exactly ``nee``'s step (``Features.media`` empty): the same image.
Shadow rays (from medium and surface vertices alike, ``shadow_path``) cross pass-through medium
boundaries (MTL ``index_matched``), tracking the medium of each segment, and stop at any other
surface: light reaches a medium inside glass by phase sampling alone (unbiased).
"""

from __future__ import annotations

from types import SimpleNamespace

import warp as wp

from warp_spt.device.adjoint import zero_adjoint
from warp_spt.bsdfs.cutout import make_blocked, make_hit
from warp_spt.accel.ray_queries import KIND_MISS, KIND_TRIANGLE, Hit
from warp_spt.emitters import LightSample, Lights, detach_lights, make_lights
from warp_spt.bsdfs import make_materials
from warp_spt.media import EVENT_ABSORB, EVENT_SCATTER, hg, hg_eval, hg_sample, make_media
from warp_spt.device.sampling import hash_u32, stream_state
from warp_spt.device.structs import Features, Geometry, Materials, Textures
from warp_spt.accel.surface import Surface, detach_surface, make_surface, offset_origin
from warp_spt.integrators.common import (DIM_BOUNCE, OFF_DIR, OFF_ROULETTE, Integrator, PathState, RenderParams,
                                         finite3)
from warp_spt.integrators.nee import (
    STRIDE,
    VIS_TRACE,
    detached,
    make_light_sample,
    make_roulette,
    make_path_step,
    make_path_vertex,
    power_heuristic,
)
from warp_spt.samplers import Sampler

_FAR = wp.constant(1.0e30)
# salts of the trackers' random streams at one depth: the flight, a medium vertex's and a surface's shadow ray
_SALT_FLIGHT = wp.constant(0)
_SALT_MEDIUM_SHADOW = wp.constant(1)
_SALT_SURFACE_SHADOW = wp.constant(2)
_GOLDEN = wp.constant(wp.uint32(0x9E3779B9))
_MAX_CROSSINGS = wp.constant(16)      # pass-through boundaries one shadow ray may cross (then: blocked)


@wp.func
def tracking_stream(p: PathState, salt: int) -> wp.uint32:
    """The start of a tracker's PCG stream: a pure function of the sample, the depth and ``salt``
    (the trackers draw unboundedly many numbers; the sampler's dimensions stay the bounce's)."""
    h = stream_state(p.sampler.seed, p.sampler.pixel, p.sampler.index)
    return hash_u32(h ^ hash_u32(wp.uint32(p.depth * 8 + salt) + _GOLDEN))


@wp.func
def hero_of(p: PathState) -> int:
    """The channel whose majorant and probabilities lead the path's free flights: uniform per sample."""
    h = hash_u32(stream_state(p.sampler.seed, p.sampler.pixel, p.sampler.index) ^ _GOLDEN)
    return int(h % wp.uint32(3))


def make_material_of(features: Features):
    @wp.func
    def material_of(geo: Geometry, h: Hit) -> int:
        """The material row of the surface ``h`` met."""
        if h.kind == KIND_TRIANGLE:
            if wp.static(features.meshes):
                return geo.face_material[geo.face_offset[h.index] + h.face]
            return 0
        if wp.static(features.spheres):
            return geo.sphere_material[h.index]
        return 0

    return material_of


@wp.struct
class ShadowDeriv:
    """Derivatives of a shadow ray's transmittance with respect to sigma_t (sigma_a and sigma_s alike)
    of the media its segments crossed: ``row0`` (where it starts) and ``row1`` (the other side of a
    pass-through boundary; -1: none)."""

    row0: int
    d0: wp.vec3
    row1: int
    d1: wp.vec3


@wp.func
def detached3(x: wp.vec3) -> wp.vec3:
    """``x``, through which no derivative flows (its adjoint is 0)."""
    return x


zero_adjoint(detached3, (wp.vec3,))


@wp.func
def attach(value: wp.vec3, deriv: wp.vec3, x: wp.vec3) -> wp.vec3:
    """``value`` exactly, whose derivative with respect to ``x`` is ``deriv`` (per channel): how path
    replay gives Warp's adjoint the derivatives the trackers computed forwards (their loops have
    none of Warp's). ``x`` is read from the media table inside the differentiated vertex, so the
    adjoint lands in that array's gradient buffer."""
    if not wp.isfinite(deriv):
        return value
    return value + wp.cw_mul(deriv, x - detached3(x))


def make(features: Features, sampler: Sampler, differentiable: bool = False):
    """The volpath step for ``features``: ``nee``'s very step when the scene has no medium."""
    if differentiable:
        raise ValueError("integrator 'volpath' has no tape kernel (its gradients are path replay's)")
    if not features.media:
        return make_path_step(features, sampler, light_sampling=True)
    hit = make_hit(features)
    vertex = _make_vertex(features, sampler, inline=True, replay=False)

    @wp.func(inline=True)
    def step(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
             path: PathState) -> PathState:
        p = path
        h = hit(geo, mats, tex, p.o, p.d)
        p.rays += 1
        return vertex(geo, mats, tex, lights, rp, p, h, VIS_TRACE)

    return step


def make_vertex(features: Features, sampler: Sampler, inline: bool | None = None):
    """The vertex path replay differentiates (``nee``'s without media): the free flight, then a medium
    vertex or ``nee``'s surface vertex, each tracker's derivatives attached (docs/volumes.md, Gradients)."""
    if not features.media:
        return make_path_vertex(features, sampler, light_sampling=True, inline=inline, replay=True)
    return _make_vertex(features, sampler, inline=inline, replay=True)


def _make_vertex(features: Features, sampler: Sampler, inline: bool | None, replay: bool):
    """``vertex(geo, mats, tex, lights, rp, path, hit, vis) -> PathState``: everything a bounce does once
    its ray met ``hit``: the free flight in the ray's medium, then a medium vertex or a pass-through
    boundary or ``nee``'s vertex. ``replay``: path replay's (the trackers' derivatives attached, the
    sampling detached; shadow rays are traced again whatever ``vis`` says)."""
    md = make_media(features, diff=replay)
    hit = make_hit(features)
    blocked = make_blocked(features)
    material_of = make_material_of(features)
    crosses = "interface" in features.media

    @wp.func(inline=False)     # called, not inlined: see media's free_flight (NVRTC's cost)
    def shadow_path(geo: Geometry, mats: Materials, tex: Textures, medium: int, o: wp.vec3, d: wp.vec3,
                    t_max: float, rng: wp.uint32):
        """Transmittance from ``o`` (in ``medium``) to ``t_max`` along ``d``, 0 when a surface blocks
        it; with pass-through boundaries in the scene (``"interface"``), the ray crosses them, each
        segment's medium tracked as a path's (up to _MAX_CROSSINGS of them). ``replay``: and its
        :class:`ShadowDeriv` (a third medium's derivative is dropped: the set-up refuses scenes
        where a shadow ray could meet one, ``rendering.setup``)."""
        dv = ShadowDeriv()
        dv.row0 = medium
        dv.row1 = -1
        zero = wp.vec3(0.0, 0.0, 0.0)
        if wp.static(not crosses):
            if blocked(geo, mats, tex, o, d, t_max):
                if wp.static(replay):
                    return zero, dv
                else:
                    return zero
            if medium < 0:
                if wp.static(replay):
                    return wp.vec3(1.0, 1.0, 1.0), dv
                else:
                    return wp.vec3(1.0, 1.0, 1.0)
            if wp.static(replay):
                T, r, dT = md.transmittance(geo.media, medium, o, d, t_max, rng)
                dv.d0 = dT
                return T, dv
            else:
                T, r = md.transmittance(geo.media, medium, o, d, t_max, rng)
                return T
        T = wp.vec3(1.0, 1.0, 1.0)
        m = medium
        x = o
        left = t_max
        r = rng
        for k in range(_MAX_CROSSINGS):
            h = hit(geo, mats, tex, x, d)
            end = h.kind == KIND_MISS or h.t >= left
            if not end:
                if geo.media.mat_interface[material_of(geo, h)] == 0:
                    if wp.static(replay):
                        return zero, ShadowDeriv()
                    else:
                        return zero
            if m >= 0:
                Tm = wp.vec3(1.0, 1.0, 1.0)
                if wp.static(replay):
                    dT = wp.vec3(0.0, 0.0, 0.0)
                    Tm, r, dT = md.transmittance(geo.media, m, x, d, wp.where(end, left, h.t), r)
                    # forward mode through the product of the segments' estimates
                    dv.d0 = wp.cw_mul(dv.d0, Tm)
                    dv.d1 = wp.cw_mul(dv.d1, Tm)
                    if m == dv.row0:
                        dv.d0 = dv.d0 + wp.cw_mul(T, dT)
                    else:
                        if dv.row1 < 0:
                            dv.row1 = m
                        if m == dv.row1:
                            dv.d1 = dv.d1 + wp.cw_mul(T, dT)
                else:
                    Tm, r = md.transmittance(geo.media, m, x, d, wp.where(end, left, h.t), r)
                T = wp.cw_mul(T, Tm)
                if not end and wp.max(wp.max(T[0], T[1]), T[2]) <= 0.0:
                    if wp.static(replay):
                        return zero, ShadowDeriv()
                    else:
                        return zero
            if end:
                if wp.static(replay):
                    return T, dv
                else:
                    return T
            row = material_of(geo, h)
            inner = geo.media.mat_medium[row]
            m = wp.where(m == inner, geo.media.outer, inner)
            n = wp.where(wp.dot(h.normal, d) > 0.0, -h.normal, h.normal)      # towards where the ray came from
            y = offset_origin(x + d * h.t, n, 1, geo.extent)
            left = left - wp.dot(y - x, d)
            x = y
        if wp.static(replay):
            return zero, ShadowDeriv()
        else:
            return zero

    if replay:
        zero_adjoint(shadow_path, (wp.vec3, ShadowDeriv))

    @wp.func
    def transmitted(geo: Geometry, mats: Materials, tex: Textures, medium: int, o: wp.vec3, d: wp.vec3,
                    t_max: float, rng: wp.uint32) -> wp.vec3:
        """``shadow_path``'s transmittance; in path replay, with its derivatives attached to sigma_t."""
        if wp.static(replay):
            T, dv = shadow_path(geo, mats, tex, medium, o, d, t_max, rng)
            out = T
            if dv.row0 >= 0:
                out = attach(out, dv.d0, geo.media.sigma_a[dv.row0] + geo.media.sigma_s[dv.row0])
            if dv.row1 >= 0:
                out = attach(out, dv.d1, geo.media.sigma_a[dv.row1] + geo.media.sigma_s[dv.row1])
            return out
        else:
            return shadow_path(geo, mats, tex, medium, o, d, t_max, rng)

    @wp.func
    def shadow(geo: Geometry, mats: Materials, tex: Textures, p: PathState, sf: Surface, so: wp.vec3,
               sd: wp.vec3, t_max: float) -> wp.vec3:
        """A surface vertex's shadow ray (nee's hook): from the medium on the side it leaves."""
        m = p.medium
        if wp.dot(sd, sf.ng) < 0.0:          # across the surface (a transmitting lobe)
            inner = geo.media.mat_medium[sf.mat]
            if inner >= 0:
                m = wp.where(p.medium == inner, geo.media.outer, inner)
        return transmitted(geo, mats, tex, m, so, sd, t_max, tracking_stream(p, _SALT_SURFACE_SHADOW))

    surface_vertex = make_path_vertex(features, sampler, light_sampling=True, inline=inline, replay=replay,
                                      media=SimpleNamespace(shadow=shadow))
    surface_at = make_surface(features)
    if replay:
        detach_surface(surface_at)          # as nee's: path replay moves no hit
    mat = make_materials(features)
    light = make_lights(features, surface_at, mat.emission)
    if replay:
        detach_lights(light)
    light_sample = make_light_sample(sampler, light, inline=True)
    roulette = make_roulette(sampler)
    sample_lights = features.samples_lights

    @wp.func
    def mis_weight(pa: float, pb: float) -> float:
        """The power heuristic; without derivative in path replay (nee's ``mis_weight``)."""
        if wp.static(replay):
            return detached(power_heuristic(pa, pb))
        return power_heuristic(pa, pb)

    @wp.func(inline=inline)
    def scatter(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
                path: PathState, x: wp.vec3) -> PathState:
        """A scattering vertex in the medium at ``x``: light sampling with MIS, a phase direction, roulette."""
        p = path
        p.depth += 1
        if p.depth >= rp.max_depth:
            p.alive = 0
            return p
        base = DIM_BOUNCE + wp.static(STRIDE) * (p.depth - 1)
        g = geo.media.g[p.medium]
        d_in = p.d
        beta = p.throughput
        u_dir, st = sampler.next_2d(p.sampler, base + OFF_DIR)     # dims in increasing order
        radiance = p.radiance
        if wp.static(sample_lights):
            sf = Surface()
            sf.p = x
            sf.ng = wp.vec3(0.0, 0.0, 0.0)       # no surface: the light sample starts at x itself
            sf.front = 1
            ls, xo, st = light_sample(geo, lights, st, sf, base)
            if ls.pdf > 0.0:
                ph = hg_eval(d_in, ls.dir, g)
                le = light.le(geo, mats, tex, lights, ls, xo) * ph
                if wp.max(wp.max(le[0], le[1]), le[2]) > 0.0 or not finite3(le):
                    T = transmitted(geo, mats, tex, p.medium, xo, ls.dir, ls.t_max,
                                    tracking_stream(p, _SALT_MEDIUM_SHADOW))
                    w = light.mis_li(ls, mis_weight(ls.pdf, ph))
                    radiance = radiance + wp.cw_mul(beta, wp.cw_mul(le, T)) * (w / ls.pdf)
        g_fixed = detached(g)                # sampling is detached: the direction does not move with g
        d_new = hg_sample(d_in, g_fixed, u_dir)
        q = p                                # a copy: p went to functions whose adjoints replay it
        q.radiance = radiance
        if wp.static(replay):
            # the direction's weight is p_HG / p_HG = 1 with the density detached: d log p_HG / d g
            c = detached(wp.dot(d_in, d_new))
            q.throughput = beta * (hg(c, g) / detached(hg(c, g)))
        q.pdf = hg_eval(d_in, d_new, g_fixed)       # the phase function is sampled exactly: the weight is 1
        q.o = x
        q.d = d_new
        q.singular = 0
        q.vis = VIS_TRACE
        q.sampler = st
        return roulette(q, rp, base + OFF_ROULETTE)

    @wp.func(inline=inline)
    def vertex(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
               path: PathState, h: Hit, vis: int) -> PathState:
        p = path
        if p.spectral[0] + p.spectral[1] + p.spectral[2] == 0.0:     # PathState's zeros: a camera ray
            p.medium = geo.media.outer          # the camera stands in the scene's medium
            p.spectral = wp.vec3(1.0, 1.0, 1.0)
        if p.medium >= 0:
            t_max = wp.where(h.kind == KIND_MISS, _FAR, h.t)
            t = float(0.0)
            ev = int(0)
            # p's fields are written after it went to functions without derivatives (the flight, the
            # streams' hashes): their adjoints replay nothing that matters
            if wp.static(replay):
                ev, t, beta, w, emitted, r, dv = md.free_flight(geo.media, p.medium, p.o, p.d, t_max, hero_of(p),
                                                                p.throughput, p.spectral,
                                                                tracking_stream(p, _SALT_FLIGHT))
                sa = geo.media.sigma_a[p.medium]
                ss = geo.media.sigma_s[p.medium]
                p.radiance += attach(attach(emitted, dv.emit_a, sa), dv.emit_s, ss)
                p.throughput = attach(attach(beta, dv.beta_a, sa), dv.beta_s, ss)
                p.spectral = w
            else:
                ev, t, beta, w, emitted, r = md.free_flight(geo.media, p.medium, p.o, p.d, t_max, hero_of(p),
                                                            p.throughput, p.spectral, tracking_stream(p, _SALT_FLIGHT))
                p.radiance += emitted
                p.throughput = beta
                p.spectral = w
            if ev == EVENT_ABSORB:
                p.alive = 0
                return p
            if ev == EVENT_SCATTER:
                return scatter(geo, mats, tex, lights, rp, p, p.o + p.d * t)
        if wp.static(crosses):
            if h.kind != KIND_MISS:
                row = material_of(geo, h)
                if geo.media.mat_interface[row] != 0:
                    # a pass-through boundary is no vertex (pbrt's interface): the ray goes on with its
                    # depth and MIS state (the direction's density, from the last real vertex), so
                    # that an emitter met beyond it is weighed against the light sample that crossed it
                    inner = geo.media.mat_medium[row]
                    p.medium = wp.where(p.medium == inner, geo.media.outer, inner)
                    n = wp.where(wp.dot(h.normal, p.d) > 0.0, -h.normal, h.normal)
                    p.o = offset_origin(p.o + p.d * h.t, n, 1, geo.extent)
                    return p
        d_in = p.d
        medium = p.medium
        out = surface_vertex(geo, mats, tex, lights, rp, p, h, vis)
        if h.kind != KIND_MISS and out.alive != 0:
            if wp.dot(d_in, h.normal) * wp.dot(out.d, h.normal) > 0.0:     # the path went through the surface
                inner = geo.media.mat_medium[material_of(geo, h)]
                if inner >= 0:
                    # in or out by the medium the ray was in, not by the winding: a mesh wound inwards
                    # (or inconsistently) still bounds its medium
                    out.medium = wp.where(medium == inner, geo.media.outer, inner)
        return out

    return vertex


INTEGRATOR = Integrator("volpath", make, make_vertex, STRIDE, tape=False, media=True,
                        summary="nee with participating media: delta tracking, ratio-tracked shadow rays, "
                                "phase-function MIS")
