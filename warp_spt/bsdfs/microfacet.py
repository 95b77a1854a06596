"""GGX (Trowbridge-Reitz) microfacet lobes in the local shading frame, as Warp functions.

Everything here works in the LOCAL frame: z is the shading normal, x the tangent (the direction of
``alpha_x``). ``wo`` and ``wi`` are unit vectors pointing away from the surface. Callers flip the
frame to the side ``wo`` is on, so ``wo.z > 0``; the lobes also accept ``wo.z < 0`` by mirroring
(conductors are two-sided; for dielectrics ``eta`` is then read from the other side).

Conventions:

* ``eta`` of a dielectric boundary is n(z < 0 side) / n(z > 0 side), i.e. with ``wo.z > 0`` the
  index of the side ``wo`` does not point into over the index of the side it does;
* a lobe's ``value`` is f * |cos(wi)|; a sample's ``pdf`` is the solid-angle density, or for a
  delta (perfectly smooth) lobe the discrete probability of the branch taken, so ``value / pdf``
  is always the path throughput weight; ``eval`` and ``pdf`` of a delta lobe are 0;
* transmission is for radiance (divided by eta'^2, as pbrt-v4's ``TransportMode::Radiance``);
* roughness enters as glTF's perceptual roughness (alpha = roughness^2), see :func:`ggx_alphas`.

The formulas and their sources are in docs/materials.md, "Microfacet formulas"; the albedo tables
come from scripts/make_ggx_tables.py (``warp_spt.bsdfs.ggx_tables``).
"""

from __future__ import annotations

import warp as wp

from warp_spt.bsdfs import ggx_tables

from warp_spt.device.lobes import (  # noqa: F401 (the lobe flags' one home; re-exported for the lobes' callers)
    LOBE_DIFFUSE,
    LOBE_GLOSSY,
    LOBE_REFLECTION,
    LOBE_SPECULAR,
    LOBE_TRANSMISSION,
)

# Below this alpha (both axes) a lobe is the perfectly smooth (delta) lobe: roughness < 0.032.
DELTA_ALPHA = wp.constant(1.0e-3)
# A rough lobe's alphas are clamped to at least this, so that an anisotropic lobe whose one axis
# is smooth keeps a finite D (pbrt-v4 clamps the same way).
_MIN_ALPHA = wp.constant(1.0e-4)
# |eta - 1| below this is an index-matched boundary: light passes straight through.
_ETA_ONE = wp.constant(1.0e-5)
_PI = wp.constant(3.141592653589793)
_TWO_PI = wp.constant(6.283185307179586)

_N = wp.constant(ggx_tables.N)
_Table = wp.types.vector(length=_N * _N, dtype=wp.float32)
_Column = wp.types.vector(length=_N, dtype=wp.float32)
_TAB_A = wp.constant(_Table(*ggx_tables.A))
_TAB_B = wp.constant(_Table(*ggx_tables.B))
_AVG_E = wp.constant(_Column(*ggx_tables.E_AVG))
_AVG_A = wp.constant(_Column(*ggx_tables.A_AVG))
_AVG_B = wp.constant(_Column(*ggx_tables.B_AVG))
_AVG_C = wp.constant(_Column(*ggx_tables.C_AVG))
_AVG_D = wp.constant(_Column(*ggx_tables.D_AVG))
_LAST = wp.constant(float(_N - 1))


@wp.struct
class LobeSample:
    """One sampled direction of one lobe (see the module's conventions); ``ok`` = 0: no sample."""

    wi: wp.vec3
    value: wp.vec3
    pdf: float
    flags: int
    ok: int


@wp.func
def lobe_sample(wi: wp.vec3, value: wp.vec3, pdf: float, flags: int, ok: int) -> LobeSample:
    """A LobeSample with every field written once (in-place writes after a call confuse Warp's
    adjoint of that call: scripts/warp_struct_write_repro.py)."""
    s = LobeSample()
    s.wi = wi
    s.value = value
    s.pdf = pdf
    s.flags = flags
    s.ok = ok
    return s


@wp.func
def no_sample() -> LobeSample:
    return lobe_sample(wp.vec3(0.0, 0.0, 1.0), wp.vec3(0.0), 0.0, 0, 0)


# ---------------------------------------------------------------- the distribution


@wp.func
def ggx_alphas(roughness: float, anisotropy: float) -> wp.vec2:
    """(alpha_x, alpha_y) from glTF's perceptual roughness and KHR_materials_anisotropy's strength
    in [0, 1]: alpha = roughness^2, stretched along the tangent to mix(alpha, 1, anisotropy^2)."""
    a = roughness * roughness
    return wp.vec2(a + (1.0 - a) * anisotropy * anisotropy, a)


@wp.func
def is_smooth(ax: float, ay: float) -> bool:
    return wp.max(ax, ay) < DELTA_ALPHA


@wp.func
def ggx_d(m: wp.vec3, ax: float, ay: float) -> float:
    """The anisotropic GGX normal distribution D(m) (per unit solid angle of m; 0 below z = 0)."""
    if m[2] <= 0.0:
        return 0.0
    x = m[0] / ax
    y = m[1] / ay
    t = x * x + y * y + m[2] * m[2]
    return 1.0 / (_PI * ax * ay * t * t)


@wp.func
def ggx_lambda(w: wp.vec3, ax: float, ay: float) -> float:
    """Smith's Lambda(w) for GGX: (sqrt(1 + (ax^2 wx^2 + ay^2 wy^2) / wz^2) - 1) / 2."""
    z2 = w[2] * w[2]
    s = ax * ax * w[0] * w[0] + ay * ay * w[1] * w[1]
    if z2 <= 1.0e-30:
        return 1.0e30
    return 0.5 * (wp.sqrt(1.0 + s / z2) - 1.0)


@wp.func
def ggx_g1(w: wp.vec3, ax: float, ay: float) -> float:
    return 1.0 / (1.0 + ggx_lambda(w, ax, ay))


@wp.func
def ggx_g2(wo: wp.vec3, wi: wp.vec3, ax: float, ay: float) -> float:
    """Height-correlated Smith masking-shadowing (Heitz 2014)."""
    return 1.0 / (1.0 + ggx_lambda(wo, ax, ay) + ggx_lambda(wi, ax, ay))


@wp.func
def ggx_sample_vn(wo: wp.vec3, ax: float, ay: float, u: wp.vec2) -> wp.vec3:
    """A microfacet normal (z > 0) with the density of the normals visible from ``wo``
    (:func:`ggx_pdf_vn`), by the spherical-cap method (Dupuy & Benyoub 2023): stretch ``wo`` to the
    alpha = 1 configuration, sample the cap of the unit sphere it sees, unstretch the normal."""
    wh = wp.normalize(wp.vec3(ax * wo[0], ay * wo[1], wo[2]))
    if wh[2] < 0.0:
        wh = -wh
    phi = _TWO_PI * u[0]
    z = (1.0 - u[1]) * (1.0 + wh[2]) - wh[2]
    s = wp.sqrt(wp.clamp(1.0 - z * z, 0.0, 1.0))
    h = wp.vec3(s * wp.cos(phi), s * wp.sin(phi), z) + wh
    return wp.normalize(wp.vec3(ax * h[0], ay * h[1], wp.max(h[2], 1.0e-9)))


@wp.func
def ggx_pdf_vn(wo: wp.vec3, m: wp.vec3, ax: float, ay: float) -> float:
    """The density of :func:`ggx_sample_vn`'s m: G1(wo) max(0, wo.m) D(m) / |wo.z| (Heitz 2018),
    with ``wo`` taken on the upper side, as the sampler takes it."""
    w = wo
    if w[2] < 0.0:
        w = -wo
    if w[2] <= 0.0:
        return 0.0
    return ggx_g1(w, ax, ay) * wp.max(wp.dot(w, m), 0.0) * ggx_d(m, ax, ay) / w[2]


# ---------------------------------------------------------------- Fresnel


@wp.func
def fresnel_dielectric(cos_i: float, eta: float) -> float:
    """Unpolarised Fresnel reflectance of a dielectric boundary, exact; eta = n_below / n_above,
    cos_i < 0 means arriving from below; 1 under total internal reflection."""
    c = wp.clamp(cos_i, -1.0, 1.0)
    e = eta
    if c < 0.0:
        e = 1.0 / eta
        c = -c
    sin2_t = (1.0 - c * c) / (e * e)
    if sin2_t >= 1.0:
        return 1.0
    cos_t = wp.sqrt(wp.max(0.0, 1.0 - sin2_t))
    r_par = (e * c - cos_t) / (e * c + cos_t)
    r_perp = (c - e * cos_t) / (c + e * cos_t)
    return 0.5 * (r_par * r_par + r_perp * r_perp)


@wp.func
def fresnel_schlick(f0: wp.vec3, cos: float) -> wp.vec3:
    c = 1.0 - wp.clamp(cos, 0.0, 1.0)
    c2 = c * c
    return f0 + (wp.vec3(1.0) - f0) * (c2 * c2 * c)


@wp.func
def reflect(wo: wp.vec3, m: wp.vec3) -> wp.vec3:
    return 2.0 * wp.dot(wo, m) * m - wo


@wp.func
def refract(wo: wp.vec3, n: wp.vec3, eta: float):
    """The refracted direction of ``wo`` through a boundary of normal ``n`` (eta = index on the
    side opposite ``n`` over the index on ``n``'s side). Returns (ok, wt, eta'), eta' the relative
    index actually crossed (1/eta from below); ok = 0 under total internal reflection."""
    c = wp.dot(n, wo)
    e = eta
    nn = n
    if c < 0.0:
        e = 1.0 / eta
        c = -c
        nn = -n
    sin2_t = wp.max(0.0, 1.0 - c * c) / (e * e)
    if sin2_t >= 1.0:
        return 0, wp.vec3(0.0), e
    cos_t = wp.sqrt(1.0 - sin2_t)
    return 1, -wo / e + (c / e - cos_t) * nn, e


# ---------------------------------------------------------------- the albedo tables


@wp.func
def _cell(x: float):
    """Bilinear cell of a table coordinate in [0, 1]: (index, fraction)."""
    t = wp.clamp(x, 0.0, 1.0) * _LAST
    i = wp.min(int(t), _N - 2)
    return i, t - float(i)


@wp.func
def ggx_split_sum(mu: float, alpha: float) -> wp.vec2:
    """(A, B) of the split sum: the Schlick-F albedo of the GGX reflection lobe is f0 A + B.
    Bilinear in (sqrt(mu), sqrt(alpha)) over the 32 x 32 table; isotropic alpha (callers with an
    anisotropic lobe pass ``table_alpha(alpha_x, alpha_y)``)."""
    i, fx = _cell(wp.sqrt(wp.clamp(mu, 0.0, 1.0)))
    j, fy = _cell(wp.sqrt(wp.clamp(alpha, 0.0, 1.0)))
    k = i * _N + j
    w00 = (1.0 - fx) * (1.0 - fy)
    w10 = fx * (1.0 - fy)
    w01 = (1.0 - fx) * fy
    w11 = fx * fy
    a = _TAB_A[k] * w00 + _TAB_A[k + _N] * w10 + _TAB_A[k + 1] * w01 + _TAB_A[k + _N + 1] * w11
    b = _TAB_B[k] * w00 + _TAB_B[k + _N] * w10 + _TAB_B[k + 1] * w01 + _TAB_B[k + _N + 1] * w11
    return wp.vec2(a, b)


@wp.func
def ggx_albedo(mu: float, alpha: float) -> float:
    """E(mu, alpha): the directional albedo of the single-scattering GGX reflection lobe, F = 1."""
    ab = ggx_split_sum(mu, alpha)
    return ab[0] + ab[1]


@wp.func
def _avg(col: _Column, alpha: float) -> float:
    j, fy = _cell(wp.sqrt(wp.clamp(alpha, 0.0, 1.0)))
    return col[j] * (1.0 - fy) + col[j + 1] * fy


@wp.func
def ggx_albedo_avg(alpha: float) -> float:
    """E_avg(alpha) = 2 * integral of E(mu, alpha) mu dmu (F = 1)."""
    return _avg(_AVG_E, alpha)


@wp.func
def table_alpha(ax: float, ay: float) -> float:
    """The isotropic alpha an anisotropic lobe is compensated as: the smaller one. Its albedo is at
    least the anisotropic lobe's, so the compensation never creates energy (sqrt(ax ay) made a
    strongly anisotropic lobe up to 6.8% too bright near grazing; the smaller alpha leaves part of
    its single-scattering loss instead: docs/materials.md)."""
    return wp.min(ax, ay)


@wp.func
def compensation(mu: float, alpha: float, f0: wp.vec3) -> wp.vec3:
    """Turquin 2019's multiple-scattering factor 1 + f0 (1 - E(mu)) / E(mu)."""
    e = wp.max(ggx_albedo(mu, alpha), 1.0e-4)
    return wp.vec3(1.0) + f0 * ((1.0 - e) / e)


@wp.func
def specular_albedo(mu: float, alpha: float, f0: wp.vec3) -> wp.vec3:
    """Directional albedo of the compensated GGX reflection lobe with Schlick F0 (per channel):
    (f0 A + B) (1 + f0 (1 - E) / E)."""
    ab = ggx_split_sum(mu, alpha)
    return wp.cw_mul(f0 * ab[0] + wp.vec3(ab[1]), compensation(mu, alpha, f0))


@wp.func
def specular_albedo_avg(alpha: float, f0: wp.vec3) -> wp.vec3:
    """The cosine-weighted hemispherical average of :func:`specular_albedo`, exact in f0 for the
    tabulated moments: f0 (A_avg + D_avg) + B_avg + f0^2 C_avg."""
    a = _avg(_AVG_A, alpha) + _avg(_AVG_D, alpha)
    b = _avg(_AVG_B, alpha)
    c = _avg(_AVG_C, alpha)
    return f0 * a + wp.vec3(b) + wp.cw_mul(f0, f0) * c


# ---------------------------------------------------------------- conductor


@wp.func
def conductor_eval(wo: wp.vec3, wi: wp.vec3, f0: wp.vec3, ax: float, ay: float,
                   compensate: int) -> wp.vec3:
    """f cos of GGX reflection with Schlick's Fresnel: D G2 F / (4 |cos wo|), 0 for a delta lobe."""
    if is_smooth(ax, ay):
        return wp.vec3(0.0)
    flip = wp.where(wo[2] < 0.0, -1.0, 1.0)
    o = wo * flip
    i = wi * flip
    if o[2] <= 0.0 or i[2] <= 0.0:
        return wp.vec3(0.0)
    h = o + i
    if wp.dot(h, h) <= 0.0:
        return wp.vec3(0.0)
    m = wp.normalize(h)
    bx = wp.max(ax, _MIN_ALPHA)
    by = wp.max(ay, _MIN_ALPHA)
    value = fresnel_schlick(f0, wp.dot(o, m)) * (ggx_d(m, bx, by) * ggx_g2(o, i, bx, by) / (4.0 * o[2]))
    if compensate != 0:
        value = wp.cw_mul(value, compensation(o[2], table_alpha(bx, by), f0))
    return value


@wp.func
def _reflection_density(o: wp.vec3, r: wp.vec3, ax: float, ay: float) -> wp.vec2:
    """(D_vis(m) / (4 o.m), o.m) for the half vector m of ``o`` and ``r``, both above the surface
    (the density of reflecting ``o`` into ``r`` by a visible-normal sample); zeros where m is
    undefined or faces away from ``o``. Shared by the conductor and the thin sheet's two branches."""
    h = o + r
    if wp.dot(h, h) <= 0.0:
        return wp.vec2(0.0, 0.0)
    m = wp.normalize(h)
    c = wp.dot(o, m)
    if c <= 0.0:
        return wp.vec2(0.0, 0.0)
    bx = wp.max(ax, _MIN_ALPHA)
    by = wp.max(ay, _MIN_ALPHA)
    return wp.vec2(ggx_pdf_vn(o, m, bx, by) / (4.0 * c), c)


@wp.func
def conductor_pdf(wo: wp.vec3, wi: wp.vec3, ax: float, ay: float) -> float:
    """Density of :func:`conductor_sample`: D_vis(m) / (4 wo.m)."""
    if is_smooth(ax, ay):
        return 0.0
    flip = wp.where(wo[2] < 0.0, -1.0, 1.0)
    o = wo * flip
    i = wi * flip
    if o[2] <= 0.0 or i[2] <= 0.0:
        return 0.0
    return _reflection_density(o, i, ax, ay)[0]


@wp.func
def conductor_sample(wo: wp.vec3, f0: wp.vec3, ax: float, ay: float, compensate: int,
                     u: wp.vec2) -> LobeSample:
    """Reflect ``wo`` about a visible normal; the mirror direction (delta) when smooth."""
    flip = wp.where(wo[2] < 0.0, -1.0, 1.0)
    o = wo * flip
    if o[2] <= 0.0:
        return no_sample()
    if is_smooth(ax, ay):
        wi = wp.vec3(-o[0], -o[1], o[2])
        return lobe_sample(wi * flip, fresnel_schlick(f0, o[2]), 1.0, LOBE_SPECULAR | LOBE_REFLECTION, 1)
    bx = wp.max(ax, _MIN_ALPHA)
    by = wp.max(ay, _MIN_ALPHA)
    m = ggx_sample_vn(o, bx, by, u)
    c = wp.dot(o, m)
    wi = reflect(o, m)
    if wi[2] <= 0.0 or c <= 0.0:
        return no_sample()
    d = ggx_d(m, bx, by)
    pdf = ggx_g1(o, bx, by) * d / (4.0 * o[2])
    value = fresnel_schlick(f0, c) * (d * ggx_g2(o, wi, bx, by) / (4.0 * o[2]))
    if compensate != 0:
        value = wp.cw_mul(value, compensation(o[2], table_alpha(bx, by), f0))
    return lobe_sample(wi * flip, value, pdf, LOBE_GLOSSY | LOBE_REFLECTION, 1)


# ---------------------------------------------------------------- dielectric


@wp.func
def _generalized_half(o: wp.vec3, i: wp.vec3, eta: float):
    """(ok, m, eta') for o.z > 0: the generalised half vector of Walter 2007, facing +z, with the
    microfacet seen from the right side by both directions (ok = 0 otherwise)."""
    reflect_ = i[2] > 0.0
    etap = wp.where(reflect_, 1.0, eta)
    h = i * etap + o
    if wp.dot(h, h) <= 1.0e-20 or i[2] == 0.0:
        return 0, wp.vec3(0.0, 0.0, 1.0), etap
    m = wp.normalize(h)
    if m[2] < 0.0:
        m = -m
    if wp.dot(m, i) * i[2] < 0.0 or wp.dot(m, o) < 0.0:
        return 0, m, etap
    return 1, m, etap


@wp.func
def _dielectric_rough_value(o: wp.vec3, i: wp.vec3, m: wp.vec3, etap: float, f: float,
                            bx: float, by: float) -> float:
    """f cos for o.z > 0 through microfacet m with Fresnel f: reflection if i.z > 0."""
    dg = ggx_d(m, bx, by) * ggx_g2(o, i, bx, by)
    if i[2] > 0.0:
        return dg * f / (4.0 * o[2])
    di = wp.dot(i, m)
    do = wp.dot(o, m)
    denom = di + do / etap
    denom = denom * denom
    return dg * (1.0 - f) * wp.abs(di * do / (o[2] * denom)) / (etap * etap)


@wp.func
def _dielectric_rough_pdf(o: wp.vec3, i: wp.vec3, m: wp.vec3, etap: float, f: float,
                          bx: float, by: float) -> float:
    pm = ggx_pdf_vn(o, m, bx, by)
    if i[2] > 0.0:
        return pm * f / (4.0 * wp.abs(wp.dot(o, m)))
    di = wp.dot(i, m)
    denom = di + wp.dot(o, m) / etap
    return pm * (1.0 - f) * wp.abs(di) / (denom * denom)


@wp.func
def dielectric_eval(wo: wp.vec3, wi: wp.vec3, eta: float, ax: float, ay: float) -> wp.vec3:
    """f cos of a rough dielectric boundary (Walter 2007): reflection D G2 F / (4 |cos o|) and
    transmission D G2 (1 - F) |i.m o.m| / (|cos o| (i.m + o.m / eta')^2) / eta'^2. Grey."""
    if is_smooth(ax, ay) or wp.abs(eta - 1.0) < _ETA_ONE:
        return wp.vec3(0.0)
    o = wo
    i = wi
    e = eta
    if o[2] < 0.0:
        o = -wo
        i = -wi
        e = 1.0 / eta
    if o[2] <= 0.0:
        return wp.vec3(0.0)
    ok, m, etap = _generalized_half(o, i, e)
    if ok == 0:
        return wp.vec3(0.0)
    bx = wp.max(ax, _MIN_ALPHA)
    by = wp.max(ay, _MIN_ALPHA)
    f = fresnel_dielectric(wp.dot(o, m), e)
    return wp.vec3(_dielectric_rough_value(o, i, m, etap, f, bx, by))


@wp.func
def dielectric_pdf(wo: wp.vec3, wi: wp.vec3, eta: float, ax: float, ay: float) -> float:
    """Density of :func:`dielectric_sample` (reflection and transmission, each times the Fresnel
    probability of choosing it)."""
    if is_smooth(ax, ay) or wp.abs(eta - 1.0) < _ETA_ONE:
        return 0.0
    o = wo
    i = wi
    e = eta
    if o[2] < 0.0:
        o = -wo
        i = -wi
        e = 1.0 / eta
    if o[2] <= 0.0:
        return 0.0
    ok, m, etap = _generalized_half(o, i, e)
    if ok == 0:
        return 0.0
    bx = wp.max(ax, _MIN_ALPHA)
    by = wp.max(ay, _MIN_ALPHA)
    f = fresnel_dielectric(wp.dot(o, m), e)
    return _dielectric_rough_pdf(o, i, m, etap, f, bx, by)


@wp.func
def dielectric_sample(wo: wp.vec3, eta: float, ax: float, ay: float, u_choice: float,
                      u: wp.vec2) -> LobeSample:
    """Sample a visible normal, then reflect (probability F(wo.m), exact Fresnel) or refract; the
    smooth boundary's two delta branches below DELTA_ALPHA; straight through when eta = 1."""
    o = wo
    e = eta
    flip = 1.0
    if o[2] < 0.0:
        o = -wo
        e = 1.0 / eta
        flip = -1.0
    if o[2] <= 0.0:
        return no_sample()
    if wp.abs(eta - 1.0) < _ETA_ONE:
        return lobe_sample(-wo, wp.vec3(1.0), 1.0, LOBE_SPECULAR | LOBE_TRANSMISSION, 1)
    if is_smooth(ax, ay):
        f = fresnel_dielectric(o[2], e)
        if u_choice < f:
            wr = wp.vec3(-o[0], -o[1], o[2])
            return lobe_sample(wr * flip, wp.vec3(f), f, LOBE_SPECULAR | LOBE_REFLECTION, 1)
        ok, wt, etap = refract(o, wp.vec3(0.0, 0.0, 1.0), e)
        if ok == 0:
            return no_sample()
        return lobe_sample(wt * flip, wp.vec3((1.0 - f) / (etap * etap)), 1.0 - f,
                           LOBE_SPECULAR | LOBE_TRANSMISSION, 1)
    bx = wp.max(ax, _MIN_ALPHA)
    by = wp.max(ay, _MIN_ALPHA)
    m = ggx_sample_vn(o, bx, by, u)
    c = wp.dot(o, m)
    if c <= 0.0:
        return no_sample()
    f = fresnel_dielectric(c, e)
    if u_choice < f:
        wi = reflect(o, m)
        if wi[2] <= 0.0:
            return no_sample()
        return lobe_sample(wi * flip, wp.vec3(_dielectric_rough_value(o, wi, m, 1.0, f, bx, by)),
                           _dielectric_rough_pdf(o, wi, m, 1.0, f, bx, by),
                           LOBE_GLOSSY | LOBE_REFLECTION, 1)
    ok, wt, etap = refract(o, m, e)
    if ok == 0 or wt[2] >= 0.0:
        return no_sample()
    return lobe_sample(wt * flip, wp.vec3(_dielectric_rough_value(o, wt, m, etap, f, bx, by)),
                       _dielectric_rough_pdf(o, wt, m, etap, f, bx, by),
                       LOBE_GLOSSY | LOBE_TRANSMISSION, 1)


# ---------------------------------------------------------------- thin dielectric


@wp.func
def thin_reflectance(cos_i: float, eta: float) -> float:
    """Reflectance of a thin sheet (two parallel boundaries, light bouncing between them):
    R + T^2 R / (1 - R^2) = 2R / (1 + R), R the one-boundary Fresnel at cos_i."""
    r = fresnel_dielectric(wp.abs(cos_i), eta)
    if r >= 1.0:
        return 1.0
    return 2.0 * r / (1.0 + r)


@wp.func
def _flip_z(w: wp.vec3) -> wp.vec3:
    return wp.vec3(w[0], w[1], -w[2])


@wp.func
def thin_dielectric_eval(wo: wp.vec3, wi: wp.vec3, eta: float, ax: float, ay: float) -> wp.vec3:
    """f cos of a rough thin sheet. Approximation: transmission is the mirror image, through the
    sheet's plane, of the rough reflection lobe (so straight through in the smooth limit), each
    microfacet reflecting thin_reflectance(wo.m) and passing the rest."""
    if is_smooth(ax, ay) or wp.abs(eta - 1.0) < _ETA_ONE:
        return wp.vec3(0.0)
    flip = wp.where(wo[2] < 0.0, -1.0, 1.0)
    o = wo * flip
    i = wi * flip
    if o[2] <= 0.0 or i[2] == 0.0:
        return wp.vec3(0.0)
    r = i
    if i[2] < 0.0:
        r = _flip_z(i)
    h = o + r
    if wp.dot(h, h) <= 0.0:
        return wp.vec3(0.0)
    m = wp.normalize(h)
    bx = wp.max(ax, _MIN_ALPHA)
    by = wp.max(ay, _MIN_ALPHA)
    f = thin_reflectance(wp.dot(o, m), eta)
    base = ggx_d(m, bx, by) * ggx_g2(o, r, bx, by) / (4.0 * o[2])
    if i[2] > 0.0:
        return wp.vec3(base * f)
    return wp.vec3(base * (1.0 - f))


@wp.func
def thin_dielectric_pdf(wo: wp.vec3, wi: wp.vec3, eta: float, ax: float, ay: float) -> float:
    if is_smooth(ax, ay) or wp.abs(eta - 1.0) < _ETA_ONE:
        return 0.0
    flip = wp.where(wo[2] < 0.0, -1.0, 1.0)
    o = wo * flip
    i = wi * flip
    if o[2] <= 0.0 or i[2] == 0.0:
        return 0.0
    r = i
    if i[2] < 0.0:
        r = _flip_z(i)
    pc = _reflection_density(o, r, ax, ay)
    if pc[1] <= 0.0:
        return 0.0
    f = thin_reflectance(pc[1], eta)
    p = pc[0]
    if i[2] > 0.0:
        return p * f
    return p * (1.0 - f)


@wp.func
def thin_dielectric_sample(wo: wp.vec3, eta: float, ax: float, ay: float, u_choice: float,
                           u: wp.vec2) -> LobeSample:
    """A thin sheet: reflect with the sheet's reflectance, else leave on the other side without
    bending (smooth: delta branches; rough: see :func:`thin_dielectric_eval`)."""
    flip = wp.where(wo[2] < 0.0, -1.0, 1.0)
    o = wo * flip
    if o[2] <= 0.0:
        return no_sample()
    if wp.abs(eta - 1.0) < _ETA_ONE:
        return lobe_sample(-wo, wp.vec3(1.0), 1.0, LOBE_SPECULAR | LOBE_TRANSMISSION, 1)
    if is_smooth(ax, ay):
        f = thin_reflectance(o[2], eta)
        if u_choice < f:
            return lobe_sample(wp.vec3(-o[0], -o[1], o[2]) * flip, wp.vec3(f), f,
                               LOBE_SPECULAR | LOBE_REFLECTION, 1)
        return lobe_sample(-wo, wp.vec3(1.0 - f), 1.0 - f, LOBE_SPECULAR | LOBE_TRANSMISSION, 1)
    bx = wp.max(ax, _MIN_ALPHA)
    by = wp.max(ay, _MIN_ALPHA)
    m = ggx_sample_vn(o, bx, by, u)
    c = wp.dot(o, m)
    wr = reflect(o, m)
    if wr[2] <= 0.0 or c <= 0.0:
        return no_sample()
    f = thin_reflectance(c, eta)
    d = ggx_d(m, bx, by)
    p = ggx_g1(o, bx, by) * d / (4.0 * o[2])
    base = d * ggx_g2(o, wr, bx, by) / (4.0 * o[2])
    if u_choice < f:
        return lobe_sample(wr * flip, wp.vec3(base * f), p * f, LOBE_GLOSSY | LOBE_REFLECTION, 1)
    return lobe_sample(_flip_z(wr) * flip, wp.vec3(base * (1.0 - f)), p * (1.0 - f),
                       LOBE_GLOSSY | LOBE_TRANSMISSION, 1)
