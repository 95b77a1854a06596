"""The physically based material kind ``pbr``: glTF 2.0 metallic-roughness and its extensions.

One model that glTF, standard MTL files and Mitsuba scenes map onto (docs/materials.md has the
mapping tables). At a point it mixes, in the local shading frame (``common.to_local``):

* a **conductor**, weight ``metallic``: GGX reflection (``bsdfs.microfacet``) with Schlick's Fresnel
  from F0 = base colour, energy-compensated (Turquin 2019);
* a **dielectric**, weight ``1 - metallic``, itself
  - ``transmission``: rough glass (reflection and refraction with the exact Fresnel, Walter et al.
    2007), the refracted light tinted by the base colour (glTF's KHR_materials_transmission); thin-
    walled (``thin``): a sheet that light crosses unbent;
  - ``1 - transmission``: a specular layer (GGX with F0 = ((ior - 1)/(ior + 1))^2 x specular colour,
    capped at 1, times ``specular``; compensated) over a Lambertian base. Energy-consistent: the base
    is scaled by (1 - E(mu_o)) (1 - E(mu_i)) / (1 - E_avg), E the layer's directional albedo and
    E_avg its hemispherical average (Kulla & Conty 2017): reciprocal, and a white base under the
    layer reflects exactly what the layer does not (furnace: tests/bsdfs/test_materials.py).

Over them, where a scene has them: a **sheen** (KHR_materials_sheen, ``bsdfs.sheen``: the sample
viewer's Charlie lobe, the rest scaled by 1 - max(colour) E_sheen(mu_o)), and over everything a
**clearcoat** (KHR_materials_clearcoat: mix(rest, coat, clearcoat x F(mu_o))), about a normal of its own where
its row has a map (``pbr.coat_frame``): its clearcoat normal map about the interpolated normal
(``Surface.ns0``), else that interpolated normal rather than the base's normal or bump map.

Roughness is perceptual (alpha = roughness^2); anisotropy stretches alpha along the tangent rotated by
``anisotropy_rotation`` (KHR_materials_anisotropy). Below ``microfacet.DELTA_ALPHA`` a lobe is a
perfect mirror or smooth refraction: specular (singular, no density), as the seed's glass.

Sampling picks a lobe in proportion to its estimated albedo at ``wo`` with ``u_lobe``; the
returned weight is the whole mixture's f cos over its whole density (one-sample MIS over the lobes,
unbiased for any choice probabilities), and delta lobes weigh by their own choice probability.
Gradients: the sampled direction and every density and choice probability are held still
(``common.held``), so the derivative of a sample's weight is f'/p, the detached-sampling estimator:
unbiased for every parameter, through path replay and the tape alike. (The index of refraction also
bends smooth refraction, a delta lobe whose direction is held still: its derivative covers the
Fresnel weights only; docs/materials.md.)

The shading normal: ``shade`` applies the normal map (tangent space, ``normal`` its strength) or the
bump map, then bends the normal towards the geometric one until ``wo`` lies above it (at a quarter
of wo's height over the geometric surface): a mapped or interpolated normal facing away from the
viewer neither leaks light nor turns black. Reflection lobes count only directions on ``wo``'s side of
the geometric surface, transmission lobes only the other side (no light through walls).
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import warp as wp

from warp_spt.bsdfs import microfacet as mf
from warp_spt.bsdfs import sheen
from warp_spt.device.lobes import (
    LOBE_DIFFUSE,
    LOBE_GLOSSY,
    LOBE_REFLECTION,
    LOBE_SPECULAR,
    LOBE_TRANSMISSION,
)
from warp_spt.bsdfs.common import BsdfSample, held, held_dir, to_local, to_world, with_flags
from warp_spt.device.sampling import cosine_hemisphere
from warp_spt.device.structs import Features, Materials, Textures
from warp_spt.accel.surface import INV_PI, Surface, frame_from
from warp_spt.scene.material_schema import COLUMN
from warp_spt.scene.model import TEX_NONE

SLOT_BASE = COLUMN["base_color"].slot
SLOT_METALLIC, CH_METALLIC = COLUMN["metallic"].slot, COLUMN["metallic"].channel
SLOT_ROUGHNESS, CH_ROUGHNESS = COLUMN["roughness"].slot, COLUMN["roughness"].channel
SLOT_NORMAL = COLUMN["normal"].slot
SLOT_BUMP, CH_BUMP = COLUMN["bump"].slot, COLUMN["bump"].channel
SLOT_COAT_NORMAL = COLUMN["clearcoat_normal"].slot

# lobe indices of the mixture
METAL, SPEC, DIFF, TRANS, COAT, SHEEN = 0, 1, 2, 3, 4, 5
COAT_F0 = 0.04              # KHR_materials_clearcoat: the coat's ior is 1.5


def declare(table, rows: np.ndarray) -> tuple[int, frozenset]:
    """The lobes the pbr ``rows`` of ``table`` can produce and the code paths they need: always the
    lobe choice and a frame; the Fresnel choice and transmission code where some row transmits, the
    uv-following frame where some row is anisotropic or has a normal or bump map."""
    tex = table.tex[rows]
    metallic = table.metallic[rows]
    mapped_metal = (tex[:, SLOT_METALLIC] != TEX_NONE).any()
    trans = table.transmission[rows] > 0
    lobes = 0
    if (metallic > 0).any() or mapped_metal:
        lobes |= LOBE_GLOSSY | LOBE_SPECULAR | LOBE_REFLECTION
    if (metallic < 1).any() or mapped_metal:
        lobes |= LOBE_GLOSSY | LOBE_SPECULAR | LOBE_REFLECTION
        if (trans < 1).any():
            lobes |= LOBE_DIFFUSE
        if trans.any():
            lobes |= LOBE_TRANSMISSION
    normal_map = bool((tex[:, SLOT_NORMAL] != TEX_NONE).any())
    bump = bool((tex[:, SLOT_BUMP] != TEX_NONE).any())
    aniso = bool((table.anisotropy[rows] > 0).any())
    coated = table.clearcoat[rows] > 0
    coat = bool(coated.any())
    coat_map = bool((coated & (tex[:, SLOT_COAT_NORMAL] != TEX_NONE)).any())
    # a coat whose normal differs from the base's: its own map, or a base map it does not follow
    coat_frame = bool((coated & ((tex[:, SLOT_COAT_NORMAL] != TEX_NONE) | (tex[:, SLOT_NORMAL] != TEX_NONE)
                                 | (tex[:, SLOT_BUMP] != TEX_NONE))).any())
    if coat:
        lobes |= LOBE_GLOSSY | LOBE_SPECULAR | LOBE_REFLECTION
    has_sheen = bool((table.sheen_color[rows] > 0).any())
    if has_sheen:
        lobes |= LOBE_GLOSSY | LOBE_REFLECTION
    flags = {"frame", "dims.lobe"}
    flags |= {name for name, on in (("dims.fresnel", trans.any()), ("pbr.transmission", trans.any()),
                                    ("pbr.thin", table.thin[rows].any()), ("pbr.normal_map", normal_map),
                                    ("pbr.bump", bump), ("pbr.aniso", aniso), ("pbr.clearcoat", coat),
                                    ("pbr.coat_frame", coat_frame), ("pbr.sheen", has_sheen),
                                    ("frame.uv", normal_map or bump or aniso or coat_map)) if on}
    return lobes, frozenset(flags)


@wp.struct
class PbrPoint:
    """The material's parameters at a shading point, textures applied, and the lobes' choice weights."""

    base: wp.vec3
    metallic: float
    ax: float
    ay: float
    eta: float               # n below / n above the shading frame (ior entering from the front)
    f0: wp.vec3              # the dielectric layer's Schlick F0 (capped at 1)
    spec: float              # KHR_materials_specular's factor on the layer
    trans: float
    thin: int
    delta: int               # the lobes are perfectly smooth
    ms: int                  # multiple-scattering compensation of the reflection lobes
    prob: wp.vec4            # choice probabilities of METAL, SPEC, DIFF, TRANS at this wo
    e_avg: wp.vec3           # the layer's hemispherical albedo (the base's normalisation)
    coat: float              # clearcoat x the coat's Fresnel at wo: its weight, and 1 - coat the rest's
    coat_a: float            # the coat's GGX alpha
    p_coat: float            # the coat's choice probability (the others' prob sum to 1 - p_coat)
    sheen: float             # max(sheen colour) x the sheen's albedo at wo: 1 - sheen scales the base
    sheen_color: wp.vec3
    sheen_r: float           # the sheen's roughness, held
    p_sheen: float           # the sheen's choice probability (within the coat's 1 - p_coat)
    cframe: int              # the coat has a normal of its own: cn, with ct and cb about it (in the base's frame)
    ct: wp.vec3
    cb: wp.vec3
    cn: wp.vec3


@wp.func
def luminance(c: wp.vec3) -> float:
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]


@wp.func
def rotated(sf: Surface, angle: float) -> Surface:
    """``sf`` with its tangent turned by ``angle`` about the shading normal (the anisotropy direction)."""
    out = sf
    y = wp.cross(sf.ns, sf.t)
    out.t = sf.t * wp.cos(angle) + y * wp.sin(angle)
    return out


@wp.func
def bend(sf: Surface, n: wp.vec3) -> wp.vec3:
    """``n`` (unit, on wo's side) tilted towards the geometric normal until wo lies at least a
    quarter of its height over the geometric surface above it."""
    a = wp.dot(sf.wo, n)
    c = wp.dot(sf.wo, sf.ng)
    h = 0.25 * c
    if a >= h:
        return n
    s = (h - a) / wp.max(c - a, 1.0e-12)
    return wp.normalize(n * (1.0 - s) + sf.ng * s)


def make(features: Features, base) -> SimpleNamespace:
    """The contract's functions of the pbr kind for these features (``base``: the colour look-ups)."""
    color, scalar = base.color, base.scalar
    has_trans = features.needs("pbr.transmission")
    has_thin = features.needs("pbr.thin")
    has_normal_map = features.needs("pbr.normal_map")
    has_bump = features.needs("pbr.bump")
    has_aniso = features.needs("pbr.aniso")
    has_coat = features.needs("pbr.clearcoat")
    has_sheen = features.needs("pbr.sheen")
    has_coat_frame = features.needs("pbr.coat_frame")

    @wp.func
    def frame_of(m: Materials, sf: Surface) -> Surface:
        """The frame the lobes see: the tangent turned to the anisotropy direction."""
        if wp.static(has_aniso):
            return rotated(sf, m.anisotropy_rotation[sf.mat])
        return sf

    @wp.func
    def coat_normal(m: Materials, t: Textures, sf: Surface) -> wp.vec3:
        """The coat's world normal (KHR_materials_clearcoat): its own tangent-space map about the
        interpolated normal ``sf.ns0`` (the frame of the base's map before ``shade`` turned it), else
        that interpolated normal, not the base's map; bent as the base's is, so that wo stays above it."""
        k = sf.mat
        n = sf.ns0
        slot = m.tex[k][wp.static(SLOT_COAT_NORMAL)]
        if slot != TEX_NONE:
            c = color(t, slot, wp.vec3(0.5, 0.5, 1.0), sf)
            s = m.clearcoat_normal[k]
            v = wp.vec3((2.0 * c[0] - 1.0) * s, (2.0 * c[1] - 1.0) * s, 2.0 * c[2] - 1.0)
            n_face = wp.where(sf.front != 0, sf.ns0, -sf.ns0)
            # the map's tangent about ns0: b is still the one surface_at made (orthogonal to ns0 and the
            # tangent), while shade turned t to the base's mapped normal
            t0 = wp.cross(sf.b, n_face)
            if wp.dot(t0, sf.t) < 0.0:
                t0 = -t0
            mapped = wp.normalize(t0) * v[0] + sf.b * v[1] + n_face * v[2]
            if wp.length(mapped) > 1.0e-8:
                n = wp.normalize(mapped)
                if sf.front == 0:
                    n = -n
        return bend(sf, n)

    @wp.func
    def coat_in(q: PbrPoint, w: wp.vec3) -> wp.vec3:
        """A direction of the base's frame in the coat's."""
        return wp.vec3(wp.dot(w, q.ct), wp.dot(w, q.cb), wp.dot(w, q.cn))

    @wp.func
    def coat_out(q: PbrPoint, w: wp.vec3) -> wp.vec3:
        """A direction of the coat's frame in the base's."""
        return q.ct * w[0] + q.cb * w[1] + q.cn * w[2]

    @wp.func
    def point(m: Materials, t: Textures, sf: Surface) -> PbrPoint:
        """The parameters at ``sf``, for ``sf.wo``."""
        k = sf.mat
        tex = m.tex[k]
        q = PbrPoint()
        q.base = color(t, tex[wp.static(SLOT_BASE)], m.base_color[k], sf)
        q.metallic = wp.clamp(scalar(t, tex[wp.static(SLOT_METALLIC)], wp.static(CH_METALLIC), m.metallic[k], sf),
                              0.0, 1.0)
        rough = wp.clamp(scalar(t, tex[wp.static(SLOT_ROUGHNESS)], wp.static(CH_ROUGHNESS), m.roughness[k], sf),
                         0.0, 1.0)
        aniso = float(0.0)
        if wp.static(has_aniso):
            aniso = m.anisotropy[k]
        a = mf.ggx_alphas(rough, aniso)
        q.ax = a[0]
        q.ay = a[1]
        q.delta = wp.where(wp.max(q.ax, q.ay) < mf.DELTA_ALPHA, 1, 0)
        q.ms = m.multiscatter[k]
        ior = m.ior[k]
        q.eta = wp.where(sf.front != 0, ior, 1.0 / ior)
        r = (ior - 1.0) / (ior + 1.0)
        sc = m.specular_color[k]
        q.f0 = wp.vec3(wp.min(r * r * sc[0], 1.0), wp.min(r * r * sc[1], 1.0), wp.min(r * r * sc[2], 1.0))
        q.spec = m.specular[k]
        q.trans = float(0.0)
        q.thin = 0
        if wp.static(has_trans):
            q.trans = m.transmission[k]
            if wp.static(has_thin):
                q.thin = m.thin[k]
        mu = wp.clamp(wp.dot(sf.wo, sf.ns), 1.0e-4, 1.0)
        alpha = mf.table_alpha(q.ax, q.ay)
        e_metal = mf.specular_albedo(mu, alpha, q.base)
        e_layer = mf.specular_albedo(mu, alpha, q.f0) * q.spec
        q.e_avg = mf.specular_albedo_avg(alpha, q.f0) * q.spec
        dielectric = 1.0 - q.metallic
        w_metal = q.metallic * luminance(e_metal)
        w_trans = dielectric * q.trans
        w_spec = dielectric * (1.0 - q.trans) * luminance(e_layer)
        one = wp.vec3(1.0, 1.0, 1.0)
        w_diff = dielectric * (1.0 - q.trans) * luminance(wp.cw_mul(q.base, one - e_layer))
        total = w_metal + w_trans + w_spec + w_diff
        if total > 0.0:
            q.prob = wp.vec4(held(w_metal / total), held(w_spec / total), held(w_diff / total), held(w_trans / total))
        else:
            q.prob = wp.vec4(0.0, 0.0, 1.0, 0.0)
        if wp.static(has_sheen):
            # the sample viewer's albedo scaling: sheen + base x (1 - max(colour) E(mu_o))
            q.sheen_color = m.sheen_color[k]
            q.sheen_r = sheen.held_roughness(m.sheen_roughness[k])
            e_sheen = sheen.albedo(mu, q.sheen_r)
            c = q.sheen_color
            q.sheen = wp.max(c[0], wp.max(c[1], c[2])) * e_sheen
            # a floor on the albedo keeps every direction the lobe reaches sampled
            w_sheen = luminance(c) * wp.max(e_sheen, 1.0e-3)
            under = (1.0 - q.sheen) * total
            if w_sheen + under > 0.0:
                q.p_sheen = held(w_sheen / (w_sheen + under))
                q.prob = q.prob * (1.0 - q.p_sheen)
            total = w_sheen + under
        if wp.static(has_coat):
            mu_c = mu
            if wp.static(has_coat_frame):
                q.cframe = 0
                if m.clearcoat[k] > 0.0 and (tex[wp.static(SLOT_COAT_NORMAL)] != TEX_NONE
                                             or tex[wp.static(SLOT_NORMAL)] != TEX_NONE
                                             or tex[wp.static(SLOT_BUMP)] != TEX_NONE):
                    nc = coat_normal(m, t, sf)
                    q.cn = to_local(frame_of(m, sf), nc)
                    q.ct = frame_from(q.cn, wp.vec3(1.0, 0.0, 0.0))
                    q.cb = wp.cross(q.cn, q.ct)
                    q.cframe = 1
                    mu_c = wp.clamp(wp.dot(sf.wo, nc), 1.0e-4, 1.0)
            # glTF: mix(rest, coat, clearcoat x F(mu_o)), the coat's lobe D V without Fresnel, mu_o about its normal
            q.coat = wp.clamp(m.clearcoat[k], 0.0, 1.0) * (COAT_F0 + (1.0 - COAT_F0) * wp.pow(1.0 - mu_c, 5.0))
            q.coat_a = mf.ggx_alphas(wp.clamp(m.clearcoat_roughness[k], 0.0, 1.0), 0.0)[0]
            ab = mf.ggx_split_sum(mu_c, q.coat_a)
            w_coat = q.coat * (ab[0] + ab[1])
            rest = (1.0 - q.coat) * total
            if w_coat + rest > 0.0:
                q.p_coat = held(w_coat / (w_coat + rest))
                q.prob = q.prob * (1.0 - q.p_coat)
                q.p_sheen = q.p_sheen * (1.0 - q.p_coat)
        return q

    @wp.func
    def diffuse_scale(q: PbrPoint, mu_o: float, mu_i: float) -> wp.vec3:
        """(1 - E(mu_o)) (1 - E(mu_i)) / (1 - E_avg): the base's share under the layer, per channel."""
        alpha = mf.table_alpha(q.ax, q.ay)
        eo = mf.specular_albedo(mu_o, alpha, q.f0) * q.spec
        ei = mf.specular_albedo(mu_i, alpha, q.f0) * q.spec
        one = wp.vec3(1.0, 1.0, 1.0)
        den = one - q.e_avg
        num = wp.cw_mul(one - eo, one - ei)
        return wp.vec3(num[0] / wp.max(den[0], 1.0e-6), num[1] / wp.max(den[1], 1.0e-6), num[2] / wp.max(den[2], 1.0e-6))

    @wp.func
    def trans_eval(q: PbrPoint, wo: wp.vec3, wi: wp.vec3) -> wp.vec3:
        f = wp.vec3(0.0, 0.0, 0.0)
        if wp.static(has_thin):
            if q.thin != 0:
                f = mf.thin_dielectric_eval(wo, wi, q.eta, q.ax, q.ay)
            else:
                f = mf.dielectric_eval(wo, wi, q.eta, q.ax, q.ay)
        else:
            f = mf.dielectric_eval(wo, wi, q.eta, q.ax, q.ay)
        if wi[2] < 0.0:
            f = wp.cw_mul(f, q.base)            # refracted light takes the base colour
        return f

    @wp.func
    def trans_pdf(q: PbrPoint, wo: wp.vec3, wi: wp.vec3) -> float:
        if wp.static(has_thin):
            if q.thin != 0:
                return mf.thin_dielectric_pdf(wo, wi, q.eta, q.ax, q.ay)
        return mf.dielectric_pdf(wo, wi, q.eta, q.ax, q.ay)

    @wp.func
    def mixture(q: PbrPoint, wo: wp.vec3, wi: wp.vec3):
        """(f cos, pdf) of the lobes with a density, for local ``wo`` (above) and ``wi``."""
        f = wp.vec3(0.0, 0.0, 0.0)
        pdf = float(0.0)
        if wi[2] > 0.0:
            if q.delta == 0:
                if q.prob[0] > 0.0:
                    f += mf.conductor_eval(wo, wi, q.base, q.ax, q.ay, q.ms) * q.metallic
                    pdf += q.prob[0] * held(mf.conductor_pdf(wo, wi, q.ax, q.ay))
                if q.prob[1] > 0.0:
                    f += mf.conductor_eval(wo, wi, q.f0, q.ax, q.ay, q.ms) * ((1.0 - q.metallic) * (1.0 - q.trans) * q.spec)
                    pdf += q.prob[1] * held(mf.conductor_pdf(wo, wi, q.ax, q.ay))
            if q.prob[2] > 0.0:
                scale = diffuse_scale(q, wo[2], wi[2])
                f += wp.cw_mul(q.base, scale) * ((1.0 - q.metallic) * (1.0 - q.trans) * wi[2] * INV_PI)
                pdf += q.prob[2] * wi[2] * INV_PI
        if wp.static(has_trans):
            if q.delta == 0 and q.prob[3] > 0.0:
                f += trans_eval(q, wo, wi) * ((1.0 - q.metallic) * q.trans)
                pdf += q.prob[3] * held(trans_pdf(q, wo, wi))
        if wp.static(has_sheen):
            f = f * (1.0 - q.sheen) + q.sheen_color * sheen.value(wo, wi, q.sheen_r)
            if q.p_sheen > 0.0 and wi[2] > 0.0:
                pdf += q.p_sheen * wi[2] * INV_PI
        if wp.static(has_coat):
            f = f * (1.0 - q.coat)
            wo_c = wo
            wi_c = wi
            if wp.static(has_coat_frame):
                if q.cframe != 0:
                    wo_c = coat_in(q, wo)
                    wi_c = coat_in(q, wi)
            if q.p_coat > 0.0 and wi_c[2] > 0.0:
                f += mf.conductor_eval(wo_c, wi_c, wp.vec3(1.0), q.coat_a, q.coat_a, 0) * q.coat
                pdf += q.p_coat * held(mf.conductor_pdf(wo_c, wi_c, q.coat_a, q.coat_a))
        return f, pdf

    @wp.func
    def side_ok(sf: Surface, wi: wp.vec3, wi_local: wp.vec3) -> bool:
        """A reflection stays on wo's side of the geometric surface, a transmission leaves it."""
        g = wp.dot(wi, sf.ng)
        return (wi_local[2] > 0.0 and g > 0.0) or (wi_local[2] < 0.0 and g < 0.0)

    @wp.func
    def eval(m: Materials, t: Textures, sf: Surface, wi: wp.vec3) -> wp.vec3:
        """f(wo, wi) |cos| of the lobes with a density."""
        fr = frame_of(m, sf)
        wo_l = to_local(fr, sf.wo)
        wi_l = to_local(fr, wi)
        if not side_ok(sf, wi, wi_l):
            return wp.vec3(0.0, 0.0, 0.0)
        q = point(m, t, sf)
        f, pdf = mixture(q, wo_l, wi_l)
        return f

    @wp.func
    def pdf(m: Materials, t: Textures, sf: Surface, wi: wp.vec3) -> float:
        """The density of ``sample`` producing ``wi`` (its lobes with a density)."""
        fr = frame_of(m, sf)
        wo_l = to_local(fr, sf.wo)
        wi_l = to_local(fr, wi)
        if not side_ok(sf, wi, wi_l):
            return 0.0
        q = point(m, t, sf)
        f, p = mixture(q, wo_l, wi_l)
        return p

    @wp.func
    def sample(m: Materials, t: Textures, sf: Surface, u_lobe: float, u_dir: wp.vec2, u_fresnel: float) -> BsdfSample:
        """A lobe by ``u_lobe`` (in proportion to the lobes' albedo estimates), its direction by ``u_dir``
        (``u_fresnel``: reflect or refract in the dielectric)."""
        fr = frame_of(m, sf)
        q = point(m, t, sf)
        wo = to_local(fr, sf.wo)
        out = BsdfSample()
        out.alive = 0
        out.pdf = 0.0
        out.weight = wp.vec3(0.0, 0.0, 0.0)
        lobe = int(DIFF)
        c0 = q.prob[0]
        c1 = c0 + q.prob[1]
        c2 = c1 + q.prob[2]
        if u_lobe < c0:
            lobe = METAL
        elif u_lobe < c1:
            lobe = SPEC
        elif u_lobe < c2:
            lobe = DIFF
        else:
            lobe = TRANS
            if wp.static(not has_trans):
                lobe = DIFF
        if wp.static(has_sheen):
            if u_lobe >= 1.0 - q.p_coat - q.p_sheen:
                lobe = SHEEN
        if wp.static(has_coat):
            if u_lobe >= 1.0 - q.p_coat:
                lobe = COAT
        wi = wp.vec3(0.0, 0.0, 0.0)
        flags = int(0)
        if lobe == DIFF or lobe == SHEEN:
            wi = held_dir(cosine_hemisphere(wp.vec3(0.0, 0.0, 1.0), u_dir[0], u_dir[1]))
            flags = wp.where(lobe == SHEEN, LOBE_GLOSSY, LOBE_DIFFUSE) | LOBE_REFLECTION
        else:
            ls = mf.LobeSample()
            p_lobe = float(0.0)
            if wp.static(has_coat):
                if lobe == COAT:
                    wo_c = wo
                    if wp.static(has_coat_frame):
                        if q.cframe != 0:
                            wo_c = coat_in(q, wo)
                    ls = mf.conductor_sample(wo_c, wp.vec3(1.0), q.coat_a, q.coat_a, 0, u_dir)
                    if wp.static(has_coat_frame):
                        if q.cframe != 0:
                            ls.wi = coat_out(q, ls.wi)
                    ls.value = ls.value * q.coat
                    p_lobe = q.p_coat
            if lobe == METAL:
                ls = mf.conductor_sample(wo, q.base, q.ax, q.ay, q.ms, u_dir)
                ls.value = ls.value * q.metallic
            elif lobe == SPEC:
                ls = mf.conductor_sample(wo, q.f0, q.ax, q.ay, q.ms, u_dir)
                ls.value = ls.value * ((1.0 - q.metallic) * (1.0 - q.trans) * q.spec)
            elif lobe != COAT:
                if wp.static(has_thin):
                    if q.thin != 0:
                        ls = mf.thin_dielectric_sample(wo, q.eta, q.ax, q.ay, u_fresnel, u_dir)
                    else:
                        ls = mf.dielectric_sample(wo, q.eta, q.ax, q.ay, u_fresnel, u_dir)
                else:
                    ls = mf.dielectric_sample(wo, q.eta, q.ax, q.ay, u_fresnel, u_dir)
                ls.value = ls.value * ((1.0 - q.metallic) * q.trans)
                if ls.wi[2] < 0.0:
                    ls.value = wp.cw_mul(ls.value, q.base)
            if ls.ok == 0:
                return out
            wi = held_dir(ls.wi)
            flags = ls.flags
            if (flags & LOBE_SPECULAR) != 0:
                # a delta lobe: weight = its value over the probability of having taken it
                wd = to_world(fr, wi)
                if not side_ok(sf, wd, wi):
                    return out
                out.dir = wd
                if wp.static(has_sheen):
                    if lobe != COAT:
                        ls.value = ls.value * (1.0 - q.sheen)
                if wp.static(has_coat):
                    if lobe != COAT:
                        p_lobe = q.prob[lobe]
                        ls.value = ls.value * (1.0 - q.coat)
                    out.weight = ls.value / (held(ls.pdf) * p_lobe)
                else:
                    out.weight = ls.value / (held(ls.pdf) * q.prob[lobe])
                out.alive = 1
                return with_flags(out, flags)
        wd = to_world(fr, wi)
        if not side_ok(sf, wd, wi):
            return out
        f, p = mixture(q, wo, wi)
        if p <= 0.0:
            return out
        out.dir = wd
        out.weight = f / p
        out.pdf = p
        out.alive = 1
        return with_flags(out, flags)

    @wp.func
    def lobes(m: Materials, t: Textures, sf: Surface) -> int:
        """The lobes with a non-zero choice probability at this point."""
        q = point(m, t, sf)
        kind = wp.where(q.delta != 0, LOBE_SPECULAR, LOBE_GLOSSY)
        out = int(0)
        if q.prob[0] > 0.0 or q.prob[1] > 0.0:
            out = out | kind | LOBE_REFLECTION
        if q.prob[2] > 0.0:
            out = out | LOBE_DIFFUSE | LOBE_REFLECTION
        if q.prob[3] > 0.0:
            out = out | kind | LOBE_REFLECTION | LOBE_TRANSMISSION
        if wp.static(has_coat):
            if q.p_coat > 0.0:
                out = out | wp.where(q.coat_a < mf.DELTA_ALPHA, LOBE_SPECULAR, LOBE_GLOSSY) | LOBE_REFLECTION
        if wp.static(has_sheen):
            if q.p_sheen > 0.0:
                out = out | LOBE_GLOSSY | LOBE_REFLECTION
        return out

    @wp.func
    def albedo(m: Materials, t: Textures, sf: Surface) -> wp.vec3:
        """The base colour (glTF's albedo for metals and dielectrics alike), in [0, 1]."""
        return color(t, m.tex[sf.mat][wp.static(SLOT_BASE)], m.base_color[sf.mat], sf)

    @wp.func
    def shade(m: Materials, t: Textures, sf: Surface) -> Surface:
        """The normal or bump map applied to the frame, then the normal bent so that wo stays above it."""
        out = sf
        n = sf.ns
        k = sf.mat
        n_face = wp.where(sf.front != 0, sf.ns, -sf.ns)     # the outward normal the maps were made for
        if wp.static(has_normal_map):
            slot = m.tex[k][wp.static(SLOT_NORMAL)]
            if slot != TEX_NONE:
                c = color(t, slot, wp.vec3(0.5, 0.5, 1.0), sf)
                s = m.normal[k]
                v = wp.vec3((2.0 * c[0] - 1.0) * s, (2.0 * c[1] - 1.0) * s, 2.0 * c[2] - 1.0)
                mapped = sf.t * v[0] + sf.b * v[1] + n_face * v[2]
                if wp.length(mapped) > 1.0e-8:
                    n = wp.normalize(mapped)
                    if sf.front == 0:
                        n = -n
        if wp.static(has_bump):
            slot = m.tex[k][wp.static(SLOT_BUMP)]
            if slot != TEX_NONE:
                tile = t.tiles[slot]
                du = 1.0 / float(wp.max(tile[1], 1))
                dv = 1.0 / float(wp.max(tile[2], 1))
                shifted = sf
                h0 = color(t, slot, wp.vec3(0.0, 0.0, 0.0), sf)[wp.static(CH_BUMP)]
                shifted.uv = sf.uv + wp.vec2(du, 0.0)
                hu = color(t, slot, wp.vec3(0.0, 0.0, 0.0), shifted)[wp.static(CH_BUMP)]
                shifted.uv = sf.uv + wp.vec2(0.0, dv)
                hv = color(t, slot, wp.vec3(0.0, 0.0, 0.0), shifted)[wp.static(CH_BUMP)]
                bm = m.bump[k]
                g = sf.t * ((hu - h0) / du * bm) + sf.b * ((hv - h0) / dv * bm)
                mapped = n_face - g
                if wp.length(mapped) > 1.0e-8:
                    n = wp.normalize(mapped)
                    if sf.front == 0:
                        n = -n
        n = bend(sf, n)
        out.ns = n
        out.t = frame_from(n, sf.t)
        return out

    return SimpleNamespace(shade=shade, sample=sample, eval=eval, pdf=pdf, albedo=albedo, lobes=lobes)
