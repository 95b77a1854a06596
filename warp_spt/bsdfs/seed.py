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

:func:`declare` names the lobes the scene's rows of this kind use (``"seed.diffuse"``: some
Roughness > 0, ``"seed.specular"``: some < 1, ``"seed.refraction"``: some refractable) and :func:`make`
compiles only those. It draws the lobe choice only where both lobes exist and the Fresnel choice only
where some row refracts, as the renderer always did, so the seed's scenes keep their images bit for
bit. It is the kind ``"seed"`` of the material-kind registry (``warp_spt.bsdfs``; the
contract is in ``warp_spt.bsdfs.common``); it needs no shading frame (it works in world space).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import warp as wp

from warp_spt.device.lobes import (
    LOBE_DIFFUSE,
    LOBE_REFLECTION,
    LOBE_SPECULAR,
    LOBE_TRANSMISSION,
)
from warp_spt.bsdfs.common import BsdfSample, lobe_weight
from warp_spt.device.sampling import cosine_hemisphere, uniform_sphere
from warp_spt.device.structs import Features, Materials, Textures
from warp_spt.accel.surface import INV_PI, Surface
from warp_spt.scene.model import SLOT_DIFFUSE, SLOT_REFLECT, SLOT_REFRACT

DIFFUSE_LOBE = LOBE_DIFFUSE | LOBE_REFLECTION
MIRROR_LOBE = LOBE_SPECULAR | LOBE_REFLECTION
GLASS_LOBE = LOBE_SPECULAR | LOBE_TRANSMISSION


def declare(table, rows: np.ndarray) -> tuple[int, frozenset]:
    """The lobes of the seed's ``rows`` of ``table`` and the code paths they need (module docs)."""
    rough = table.roughness[rows]
    diffuse, specular = bool((rough > 0).any()), bool((rough < 1).any())
    refraction = bool(table.refractable[rows].any())
    lobes = (DIFFUSE_LOBE if diffuse else 0) | (MIRROR_LOBE if specular else 0) | (GLASS_LOBE if refraction else 0)
    flags = {name for name, on in (("seed.diffuse", diffuse), ("seed.specular", specular),
                                   ("seed.refraction", refraction), ("dims.lobe", diffuse and specular),
                                   ("dims.fresnel", refraction)) if on}
    return lobes, frozenset(flags)


def make(features: Features, base) -> SimpleNamespace:
    """The contract's functions (``shade``, ``sample``, ``eval``, ``pdf``, ``albedo``, ``lobes``) of the
    seed's model for these features; ``base.color`` reads a colour column with its texture."""
    color = base.color
    has_diffuse = features.needs("seed.diffuse")
    has_specular = features.needs("seed.specular")
    has_refraction = features.needs("seed.refraction")

    @wp.func
    def specular(m: Materials, t: Textures, sf: Surface, d: wp.vec3, u_dir: wp.vec2, u_fresnel: float) -> BsdfSample:
        """The singular lobes: Schlick-weighted refraction (refractable materials), else fuzzy mirror."""
        out = BsdfSample()
        out.alive = 1
        out.through = 0
        out.singular = 1
        out.flags = MIRROR_LOBE
        out.pdf = 0.0
        tex = m.tex[sf.mat]
        cos_i = wp.clamp(-wp.dot(d, sf.ns), 0.0, 1.0)
        if wp.static(has_refraction):
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
                        out.weight = color(t, tex[wp.static(SLOT_REFRACT)], m.refract[sf.mat], sf)
                        out.through = 1
                        out.flags = GLASS_LOBE
                        if wp.dot(out.dir, sf.ng) >= 0.0:
                            out.alive = 0
                        return out
        r = d + sf.ns * (2.0 * cos_i)
        out.dir = wp.normalize(r + uniform_sphere(u_dir[0], u_dir[1]) * m.fuzz[sf.mat])
        out.weight = color(t, tex[wp.static(SLOT_REFLECT)], m.reflect[sf.mat], sf)
        if wp.dot(out.dir, sf.ng) <= 0.0:
            out.alive = 0              # fuzz pushed it below the surface: absorbed (seed leaked, Q6)
        return out

    @wp.func
    def sample(m: Materials, t: Textures, sf: Surface, u_lobe: float, u_dir: wp.vec2, u_fresnel: float) -> BsdfSample:
        """Choose a lobe with ``u_lobe`` and sample its direction with ``u_dir`` (and ``u_fresnel``)."""
        d = -sf.wo
        if wp.static(has_diffuse):
            rough = m.roughness[sf.mat]
            diffuse = u_lobe < rough
            if wp.static(not has_specular):
                diffuse = True
            if diffuse:
                out = BsdfSample()
                out.alive = 1
                out.through = 0
                out.singular = 0
                out.flags = DIFFUSE_LOBE
                out.weight = color(t, m.tex[sf.mat][wp.static(SLOT_DIFFUSE)], m.diffuse[sf.mat], sf)
                if wp.static(has_specular):
                    out.weight = out.weight * lobe_weight(rough)
                out.dir = cosine_hemisphere(sf.ns, u_dir[0], u_dir[1])
                out.pdf = rough * wp.max(wp.dot(out.dir, sf.ns), 0.0) * INV_PI
                if wp.dot(out.dir, sf.ng) <= 0.0:
                    out.alive = 0          # a smooth normal pointed it below the real surface
                return out
            if wp.static(has_specular):
                sp = specular(m, t, sf, d, u_dir, u_fresnel)
                sp.weight = sp.weight * lobe_weight(1.0 - rough)
                return sp
        return specular(m, t, sf, d, u_dir, u_fresnel)

    @wp.func
    def pdf(m: Materials, t: Textures, sf: Surface, wi: wp.vec3) -> float:
        """Density of ``sample`` producing ``wi`` through its diffuse lobe (singular lobes have none)."""
        if wp.static(has_diffuse):
            return m.roughness[sf.mat] * wp.max(wp.dot(wi, sf.ns), 0.0) * INV_PI
        return 0.0

    @wp.func
    def eval(m: Materials, t: Textures, sf: Surface, wi: wp.vec3) -> wp.vec3:
        """f(wi) cos for the diffuse lobe: zero below the shading or the geometric surface, as in
        ``sample``, which absorbs such directions."""
        if wp.static(has_diffuse):
            c = wp.dot(wi, sf.ns)
            if c > 0.0 and wp.dot(wi, sf.ng) > 0.0:
                kd = color(t, m.tex[sf.mat][wp.static(SLOT_DIFFUSE)], m.diffuse[sf.mat], sf)
                return kd * (m.roughness[sf.mat] * c * INV_PI)
        return wp.vec3(0.0, 0.0, 0.0)

    @wp.func
    def lobes(m: Materials, t: Textures, sf: Surface) -> int:
        """The diffuse lobe exists where Roughness > 0 (the only lobe with a density), the mirror or
        glass lobe where it is < 1."""
        rough = m.roughness[sf.mat]
        out = int(0)
        if rough > 0.0:
            out = out | DIFFUSE_LOBE
        if rough < 1.0:
            out = out | wp.where(m.refractable[sf.mat] != 0, MIRROR_LOBE | GLASS_LOBE, MIRROR_LOBE)
        return out

    @wp.func
    def albedo(m: Materials, t: Textures, sf: Surface) -> wp.vec3:
        """The diffuse colour (with its texture): what the denoiser's albedo pass has always recorded."""
        return color(t, m.tex[sf.mat][wp.static(SLOT_DIFFUSE)], m.diffuse[sf.mat], sf)

    @wp.func
    def shade(m: Materials, t: Textures, sf: Surface) -> Surface:
        """The seed's model shades with the surface as it is."""
        return sf

    return SimpleNamespace(shade=shade, sample=sample, pdf=pdf, eval=eval, albedo=albedo, lobes=lobes)
