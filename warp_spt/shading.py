"""Surface description at a hit and the seed's material model, fixed (SEMANTICS §7-8).

``Roughness`` is the probability of the diffuse lobe; otherwise the path takes a fuzzy mirror
reflection or, for refractable materials, Schlick-weighted refraction. Each lobe multiplies the path
throughput by its colour (the seed's "albedo" style: the lobe probabilities are the mixture weights).
Fixes over the seed: inside/outside comes from the geometry (Q3), diffuse sampling is truly
cosine-weighted, a fuzzed reflection below the surface is absorbed (Q6), total internal reflection
reflects.
"""

from __future__ import annotations

import warp as wp

from .device_scene import Features, SceneArrays
from .geometry import KIND_TRIANGLE, Hit
from .sampling import cosine_hemisphere, uniform_sphere
from .scene import TEX_CHECKER
from .textures import checker, sample_texture

INV_PI = wp.constant(0.3183098861837907)
INV_TWO_PI = wp.constant(0.15915494309189535)
# Ray origins move off a surface by REL * max|p| + ABS * scene extent: float32 rounding of a hit
# point grows with its coordinates, and the scene's own size sets the scale of everything else.
OFFSET_REL = wp.constant(2.0e-6)
OFFSET_ABS = wp.constant(1.0e-5)


@wp.struct
class Surface:
    """What shading needs at a hit. Normals face the side the ray came from."""

    p: wp.vec3
    ng: wp.vec3        # geometric normal, towards the incoming ray
    ns: wp.vec3        # shading normal (smooth where the OBJ has vn), same side as ng
    front: int         # 1 when the ray arrived from outside (against the outward/winding normal)
    mat: int
    uv: wp.vec2


@wp.struct
class Scatter:
    """One sampled bounce: new direction, throughput factor, whether it passes through the surface."""

    dir: wp.vec3
    weight: wp.vec3
    alive: int
    through: int


@wp.func
def sky_radiance(kind: int, color: wp.vec3, d: wp.vec3) -> wp.vec3:
    """The seed's skies: 1 = GradientSky on the Z component, anything else a constant colour."""
    if kind == 1:
        return wp.vec3(0.75 - 0.25 * d[2], 0.85 - 0.15 * d[2], 1.0)
    return color


@wp.func
def offset_origin(p: wp.vec3, ng: wp.vec3, through: int, extent: float) -> wp.vec3:
    """Move a new ray's origin off the surface, to the side it leaves on (replaces the seed's Q15)."""
    m = wp.max(wp.max(wp.abs(p[0]), wp.abs(p[1])), wp.abs(p[2]))
    eps = OFFSET_REL * m + OFFSET_ABS * extent
    if through != 0:
        eps = -eps
    return p + ng * eps


def make_shading(features: Features):
    """``surface_at`` and ``scatter`` functions specialised to the scene's features."""

    @wp.func
    def color(s: SceneArrays, tex: int, const: wp.vec3, uv: wp.vec2, bilinear: int) -> wp.vec3:
        if wp.static(features.textures):
            if tex >= 0:
                return sample_texture(s.texels, s.tiles, tex, uv, bilinear)
        if wp.static(features.checker):
            if tex == TEX_CHECKER:
                return checker(uv)
        return const

    @wp.func
    def surface_at(s: SceneArrays, h: Hit, o: wp.vec3, d: wp.vec3) -> Surface:
        sf = Surface()
        n_out = h.normal
        ns = h.normal
        if h.kind == KIND_TRIANGLE:
            if wp.static(features.meshes):
                g = s.face_offset[h.index] + h.face
                sf.mat = s.face_material[g]
                sf.p = wp.mesh_eval_position(s.mesh_ids[h.index], h.face, h.u, h.v)
                w = 1.0 - h.u - h.v
                sf.uv = s.corner_uv[3 * g] * h.u + s.corner_uv[3 * g + 1] * h.v + s.corner_uv[3 * g + 2] * w
                if wp.static(features.smooth):
                    if s.has_corner_normals != 0:
                        n = (s.corner_normal[3 * g] * h.u + s.corner_normal[3 * g + 1] * h.v
                             + s.corner_normal[3 * g + 2] * w)
                        if wp.length(n) > 1.0e-12:
                            ns = wp.normalize(n)
        else:
            if wp.static(features.spheres):
                sph = s.spheres[h.index]
                c = wp.vec3(sph[0], sph[1], sph[2])
                n_out = wp.normalize(o + d * h.t - c)
                ns = n_out
                sf.p = c + n_out * sph[3]          # back onto the surface: exact to float32
                sf.mat = s.sphere_material[h.index]
                # spherical uv (the seed used (0, 0) for every sphere point)
                sf.uv = wp.vec2(wp.atan2(n_out[1], n_out[0]) * INV_TWO_PI + 0.5,
                                wp.asin(wp.clamp(n_out[2], -1.0, 1.0)) * INV_PI + 0.5)
        sf.front = 1
        sf.ng = n_out
        if wp.dot(d, n_out) > 0.0:
            sf.front = 0
            sf.ng = -n_out
        if wp.dot(ns, sf.ng) < 0.0:
            ns = -ns
        sf.ns = ns
        return sf

    @wp.func
    def emission(s: SceneArrays, sf: Surface, bilinear: int) -> wp.vec3:
        return color(s, s.mat_tex[sf.mat][3], s.mat_emission[sf.mat], sf.uv, bilinear)

    @wp.func
    def scatter(s: SceneArrays, sf: Surface, d: wp.vec3, u_lobe: float, u1: float, u2: float,
                u_fresnel: float, bilinear: int) -> Scatter:
        out = Scatter()
        out.alive = 1
        out.through = 0
        m = sf.mat
        tex = s.mat_tex[m]
        if u_lobe < s.mat_roughness[m]:
            out.weight = color(s, tex[0], s.mat_diffuse[m], sf.uv, bilinear)
            out.dir = cosine_hemisphere(sf.ns, u1, u2)
            if wp.dot(out.dir, sf.ng) <= 0.0:
                out.alive = 0          # a smooth normal pointed it below the real surface
            return out
        cos_i = wp.clamp(-wp.dot(d, sf.ns), 0.0, 1.0)
        if wp.static(features.refraction):
            if s.mat_refractable[m] != 0:
                eta = s.mat_ior[m]                 # ratio n_incident / n_transmitted
                if sf.front != 0:
                    eta = 1.0 / eta
                sin2_t = eta * eta * (1.0 - cos_i * cos_i)
                if sin2_t <= 1.0:                  # otherwise total internal reflection
                    r0 = (1.0 - eta) / (1.0 + eta)
                    r0 = r0 * r0
                    k = 1.0 - cos_i
                    fresnel = r0 + (1.0 - r0) * k * k * k * k * k
                    if u_fresnel >= fresnel:
                        t = d * eta + sf.ns * (eta * cos_i - wp.sqrt(1.0 - sin2_t))
                        out.dir = wp.normalize(t)
                        out.weight = color(s, tex[2], s.mat_refract[m], sf.uv, bilinear)
                        out.through = 1
                        if wp.dot(out.dir, sf.ng) >= 0.0:
                            out.alive = 0
                        return out
        r = d + sf.ns * (2.0 * cos_i)
        out.dir = wp.normalize(r + uniform_sphere(u1, u2) * s.mat_fuzz[m])
        out.weight = color(s, tex[1], s.mat_reflect[m], sf.uv, bilinear)
        if wp.dot(out.dir, sf.ng) <= 0.0:
            out.alive = 0              # fuzz pushed it below the surface: absorbed (seed leaked, Q6)
        return out

    return surface_at, emission, scatter
