"""The seed's material model, fixed (SEMANTICS §7-8), with a sampling-complete interface.

A material is a mixture of lobes. ``Roughness`` is the probability of the diffuse lobe; otherwise
the path takes a fuzzy mirror reflection or, for refractable materials, Schlick-weighted refraction.
Each lobe multiplies the path throughput by its colour (the seed's "albedo" style: the lobe
probabilities are the mixture weights). So the BSDF times cosine is

    f(wi) cos = Roughness * Kd / pi * cos(ns, wi)     (diffuse: has a density)
              + (1 - Roughness) * [mirror or glass]   (singular: no closed-form density)

The fuzzy mirror ``normalize(r + fuzz * u)`` has no closed-form density, so both it and glass are
treated as singular (the "skip pdf" idea of RTIOW's third book): they continue by sampling only, and
the emitter they hit counts in full. ``eval`` and ``pdf`` therefore cover the diffuse lobe alone,
and MIS (``warp_spt.integrators.nee``) weighs only diffuse directions.

Fixes over the seed: inside/outside comes from the geometry (Q3), diffuse sampling is truly
cosine-weighted, a fuzzed reflection below the surface is absorbed (Q6), total internal reflection
reflects.

``make_materials(features)`` compiles only the lobes the scene's materials use (Features.diffuse,
.specular, .refraction) and the colour sources it needs (textures, the checker, the procedural textures of
Features.procedural).
"""

from __future__ import annotations

from types import SimpleNamespace

import warp as wp

from warp_spt.core.device_scene import Features, Materials, Textures
from warp_spt.core.proctex import make_dispatch, seed_checker
from warp_spt.core.sampling import cosine_hemisphere, uniform_sphere
from warp_spt.core.surface import INV_PI, Surface
from warp_spt.core.textures import sample_texture
from warp_spt.scene.model import TEX_CHECKER, TEX_PROC_BASE


@wp.func
def lobe_weight(p: float) -> float:
    """1 in value; in the adjoint, d/dp = 1/p (the score of a discrete choice made with probability p).

    Multiplying a lobe's weight by ``lobe_weight(prob of that lobe)`` leaves every image bit-identical
    and makes the differentiable kernel's derivative in ``Roughness`` correct in expectation: the
    choice ``u < Roughness`` is a step for common random numbers, so its pathwise derivative is 0,
    and the score term p'/p restores d E[L] / d Roughness (warp_spt.diff.gradients, tests/test_gradients.py).
    """
    return 1.0


@wp.func_grad(lobe_weight)
def _adj_lobe_weight(p: float, adj_ret: float):
    wp.adjoint[p] += adj_ret / p


@wp.struct
class BsdfSample:
    """One sampled direction. ``weight`` = f cos / pdf (the throughput factor); ``pdf`` is the
    solid-angle density of the whole mixture for that direction (0 when ``singular``)."""

    dir: wp.vec3
    weight: wp.vec3
    pdf: float
    singular: int      # 1: mirror/glass lobe, no density: no MIS for what it hits
    alive: int         # 0: absorbed (below the surface)
    through: int       # 1: the ray passes through the surface (refraction)


def make_materials(features: Features) -> SimpleNamespace:
    """``color``, ``emission``, ``sample``, ``eval``, ``pdf`` as Warp functions for these features."""

    proc = make_dispatch(features.procedural)

    @wp.func
    def color(t: Textures, tex: int, const: wp.vec3, sf: Surface) -> wp.vec3:
        """A material colour: texture slot ``tex`` at the surface point if it has one, else ``const``."""
        if wp.static(features.textures):
            if tex >= 0:
                return sample_texture(t.texels, t.tiles, tex, sf.uv, t.bilinear)
        if wp.static(features.checker):
            if tex == TEX_CHECKER:
                return seed_checker(sf.uv, sf.p, sf.ns)
        if wp.static(len(features.procedural) > 0):
            if tex <= TEX_PROC_BASE:
                return proc(t.proc_kind, t.proc_params, TEX_PROC_BASE - tex, sf.uv, sf.p, sf.ns)
        return const

    @wp.func
    def emission(m: Materials, t: Textures, sf: Surface) -> wp.vec3:
        """Emitted radiance, the same on both faces (the seed's emitters are two-sided)."""
        return color(t, m.tex[sf.mat][3], m.emission[sf.mat], sf)

    @wp.func
    def specular(m: Materials, t: Textures, sf: Surface, d: wp.vec3, u_dir: wp.vec2, u_fresnel: float) -> BsdfSample:
        """The singular lobes: Schlick-weighted refraction (refractable materials), else fuzzy mirror."""
        out = BsdfSample()
        out.alive = 1
        out.through = 0
        out.singular = 1
        out.pdf = 0.0
        tex = m.tex[sf.mat]
        cos_i = wp.clamp(-wp.dot(d, sf.ns), 0.0, 1.0)
        if wp.static(features.refraction):
            if m.refractable[sf.mat] != 0:
                eta = m.ior[sf.mat]                # ratio n_incident / n_transmitted
                if sf.front != 0:
                    eta = 1.0 / eta
                sin2_t = eta * eta * (1.0 - cos_i * cos_i)
                if sin2_t <= 1.0:                  # otherwise total internal reflection
                    r0 = (1.0 - eta) / (1.0 + eta)
                    r0 = r0 * r0
                    k = 1.0 - cos_i
                    fresnel = r0 + (1.0 - r0) * k * k * k * k * k
                    if u_fresnel >= fresnel:
                        tr = d * eta + sf.ns * (eta * cos_i - wp.sqrt(1.0 - sin2_t))
                        out.dir = wp.normalize(tr)
                        out.weight = color(t, tex[2], m.refract[sf.mat], sf)
                        out.through = 1
                        if wp.dot(out.dir, sf.ng) >= 0.0:
                            out.alive = 0
                        return out
        r = d + sf.ns * (2.0 * cos_i)
        out.dir = wp.normalize(r + uniform_sphere(u_dir[0], u_dir[1]) * m.fuzz[sf.mat])
        out.weight = color(t, tex[1], m.reflect[sf.mat], sf)
        if wp.dot(out.dir, sf.ng) <= 0.0:
            out.alive = 0              # fuzz pushed it below the surface: absorbed (seed leaked, Q6)
        return out

    @wp.func
    def sample(m: Materials, t: Textures, sf: Surface, d: wp.vec3, u_lobe: float, u_dir: wp.vec2,
               u_fresnel: float) -> BsdfSample:
        """Choose a lobe with ``u_lobe`` and sample its direction with ``u_dir`` (and ``u_fresnel``)."""
        if wp.static(features.diffuse):
            rough = m.roughness[sf.mat]
            diffuse = u_lobe < rough
            if wp.static(not features.specular):
                diffuse = True
            if diffuse:
                out = BsdfSample()
                out.alive = 1
                out.through = 0
                out.singular = 0
                out.weight = color(t, m.tex[sf.mat][0], m.diffuse[sf.mat], sf)
                if wp.static(features.specular):
                    out.weight = out.weight * lobe_weight(rough)
                out.dir = cosine_hemisphere(sf.ns, u_dir[0], u_dir[1])
                out.pdf = rough * wp.max(wp.dot(out.dir, sf.ns), 0.0) * INV_PI
                if wp.dot(out.dir, sf.ng) <= 0.0:
                    out.alive = 0          # a smooth normal pointed it below the real surface
                return out
            if wp.static(features.specular):
                sp = specular(m, t, sf, d, u_dir, u_fresnel)
                sp.weight = sp.weight * lobe_weight(1.0 - rough)
                return sp
        return specular(m, t, sf, d, u_dir, u_fresnel)

    @wp.func
    def pdf(m: Materials, sf: Surface, wi: wp.vec3) -> float:
        """Density of ``sample`` producing ``wi`` through its diffuse lobe (singular lobes have none)."""
        if wp.static(features.diffuse):
            return m.roughness[sf.mat] * wp.max(wp.dot(wi, sf.ns), 0.0) * INV_PI
        return 0.0

    @wp.func
    def eval(m: Materials, t: Textures, sf: Surface, wi: wp.vec3) -> wp.vec3:
        """f(wi) cos for the diffuse lobe: zero below the shading or the geometric surface, as in
        ``sample``, which absorbs such directions."""
        if wp.static(features.diffuse):
            c = wp.dot(wi, sf.ns)
            if c > 0.0 and wp.dot(wi, sf.ng) > 0.0:
                kd = color(t, m.tex[sf.mat][0], m.diffuse[sf.mat], sf)
                return kd * (m.roughness[sf.mat] * c * INV_PI)
        return wp.vec3(0.0, 0.0, 0.0)

    return SimpleNamespace(color=color, emission=emission, sample=sample, pdf=pdf, eval=eval)
