"""Volumetric path tracing: ``nee``'s bounce with participating media (issue 35, docs/volumes.md).

Each step traces the path's ray to the next surface as ``nee`` does; where the ray travels in a
medium (``PathState.medium``), a free flight (delta tracking with spectral MIS over the RGB channels,
``core.media``) first decides whether it scatters in the medium before that surface. A scattering
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

from warp_spt.core.cutout import make_blocked, make_hit
from warp_spt.core.geometry import KIND_MISS, KIND_TRIANGLE, Hit
from warp_spt.core.lights import LightSample, Lights, make_lights
from warp_spt.core.materials import make_materials
from warp_spt.core.media import EVENT_ABSORB, EVENT_SCATTER, hg_eval, hg_sample, make_media
from warp_spt.core.sampling import hash_u32, stream_state
from warp_spt.core.structs import Features, Geometry, Materials, Textures
from warp_spt.core.surface import Surface, make_surface, offset_origin
from warp_spt.integrators.common import DIM_BOUNCE, OFF_DIR, OFF_ROULETTE, Integrator, PathState, RenderParams
from warp_spt.integrators.nee import (
    STRIDE,
    VIS_TRACE,
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


def make(features: Features, sampler: Sampler, differentiable: bool = False):
    """The volpath step for ``features``: ``nee``'s very step when the scene has no medium."""
    if differentiable:
        raise ValueError("integrator 'volpath' has no differentiable kernel")
    if not features.media:
        return make_path_step(features, sampler, light_sampling=True)
    md = make_media(features)
    hit = make_hit(features)
    blocked = make_blocked(features)
    material_of = make_material_of(features)
    crosses = "interface" in features.media

    @wp.func
    def shadow_path(geo: Geometry, mats: Materials, tex: Textures, medium: int, o: wp.vec3, d: wp.vec3,
                    t_max: float, rng: wp.uint32) -> wp.vec3:
        """Transmittance from ``o`` (in ``medium``) to ``t_max`` along ``d``, 0 when a surface blocks
        it; with pass-through boundaries in the scene (``"interface"``), the ray crosses them, each
        segment's medium tracked as a path's (up to _MAX_CROSSINGS of them)."""
        if wp.static(not crosses):
            if blocked(geo, mats, tex, o, d, t_max):
                return wp.vec3(0.0, 0.0, 0.0)
            if medium < 0:
                return wp.vec3(1.0, 1.0, 1.0)
            T, r = md.transmittance(geo.media, medium, o, d, t_max, rng)
            return T
        T = wp.vec3(1.0, 1.0, 1.0)
        m = medium
        x = o
        left = t_max
        r = rng
        for k in range(_MAX_CROSSINGS):
            h = hit(geo, mats, tex, x, d)
            if h.kind == KIND_MISS or h.t >= left:
                if m >= 0:
                    Tm, r = md.transmittance(geo.media, m, x, d, left, r)
                    T = wp.cw_mul(T, Tm)
                return T
            row = material_of(geo, h)
            if geo.media.mat_interface[row] == 0:
                return wp.vec3(0.0, 0.0, 0.0)
            if m >= 0:
                Tm, r = md.transmittance(geo.media, m, x, d, h.t, r)
                T = wp.cw_mul(T, Tm)
                if wp.max(wp.max(T[0], T[1]), T[2]) <= 0.0:
                    return T
            inner = geo.media.mat_medium[row]
            m = wp.where(m == inner, geo.media.outer, inner)
            n = wp.where(wp.dot(h.normal, d) > 0.0, -h.normal, h.normal)      # towards where the ray came from
            y = offset_origin(x + d * h.t, n, 1, geo.extent)
            left = left - wp.dot(y - x, d)
            x = y
        return wp.vec3(0.0, 0.0, 0.0)

    @wp.func
    def shadow(geo: Geometry, mats: Materials, tex: Textures, p: PathState, sf: Surface, so: wp.vec3,
               sd: wp.vec3, t_max: float) -> wp.vec3:
        """A surface vertex's shadow ray (nee's hook): from the medium on the side it leaves."""
        m = p.medium
        if wp.dot(sd, sf.ng) < 0.0:          # across the surface (a transmitting lobe)
            inner = geo.media.mat_medium[sf.mat]
            if inner >= 0:
                m = wp.where(p.medium == inner, geo.media.outer, inner)
        return shadow_path(geo, mats, tex, m, so, sd, t_max, tracking_stream(p, _SALT_SURFACE_SHADOW))

    hit = make_hit(features)
    vertex = make_path_vertex(features, sampler, light_sampling=True, inline=True,
                              media=SimpleNamespace(shadow=shadow))
    surface_at = make_surface(features)
    mat = make_materials(features)
    light = make_lights(features, surface_at, mat.emission)
    light_sample = make_light_sample(sampler, light, inline=True)
    roulette = make_roulette(sampler)
    sample_lights = bool(features.emitters or features.sky or features.punctual)

    @wp.func(inline=True)
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
        u_dir, st = sampler.next_2d(p.sampler, base + OFF_DIR)     # dims in increasing order
        if wp.static(sample_lights):
            sf = Surface()
            sf.p = x
            sf.ng = wp.vec3(0.0, 0.0, 0.0)       # no surface: the light sample starts at x itself
            sf.front = 1
            ls, xo, st = light_sample(geo, lights, st, sf, base)
            if ls.pdf > 0.0:
                ph = hg_eval(p.d, ls.dir, g)
                le = light.le(geo, mats, tex, lights, ls, xo) * ph
                if wp.max(wp.max(le[0], le[1]), le[2]) > 0.0 or not wp.isfinite(le):
                    T = shadow_path(geo, mats, tex, p.medium, xo, ls.dir, ls.t_max,
                                    tracking_stream(p, _SALT_MEDIUM_SHADOW))
                    w = light.mis_li(ls, power_heuristic(ls.pdf, ph))
                    p.radiance += wp.cw_mul(p.throughput, wp.cw_mul(le, T)) * (w / ls.pdf)
        d_new = hg_sample(p.d, g, u_dir)
        p.pdf = hg_eval(p.d, d_new, g)       # the phase function is sampled exactly: the weight is 1
        p.o = x
        p.d = d_new
        p.singular = 0
        p.vis = VIS_TRACE
        p.sampler = st
        return roulette(p, rp, base + OFF_ROULETTE)

    @wp.func(inline=True)
    def step(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
             path: PathState) -> PathState:
        p = path
        if p.rays == 0:
            p.medium = geo.media.outer          # the camera stands in the scene's medium
            p.spectral = wp.vec3(1.0, 1.0, 1.0)
        h = hit(geo, mats, tex, p.o, p.d)
        p.rays += 1
        if p.medium >= 0:
            t_max = wp.where(h.kind == KIND_MISS, _FAR, h.t)
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
        p = vertex(geo, mats, tex, lights, rp, p, h, VIS_TRACE)
        if h.kind != KIND_MISS and p.alive != 0:
            if wp.dot(d_in, h.normal) * wp.dot(p.d, h.normal) > 0.0:     # the path went through the surface
                inner = geo.media.mat_medium[material_of(geo, h)]
                if inner >= 0:
                    # in or out by the medium the ray was in, not by the winding: a mesh wound inwards
                    # (or inconsistently) still bounds its medium
                    p.medium = wp.where(p.medium == inner, geo.media.outer, inner)
        return p

    return step


INTEGRATOR = Integrator("volpath", make, None, STRIDE, tape=False, media=True,
                        summary="nee with participating media: delta tracking, ratio-tracked shadow rays, "
                                "phase-function MIS")
