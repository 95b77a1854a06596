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
# Ray origins keep eps = REL * max|p| + ABS * scene extent away from the surfaces they lie on
# (along the normal, offset_origin, and in from the triangle's edges, triangle_point).
# REL covers float32 rounding of a hit point (at most ~1 ulp, and an ulp is <= 1.2e-7 * |p|): 5e-7
# is >= 4 ulps. It was 2e-6 (17-34 ulps); at 1e6 from the origin that is 2 units, more than the
# gap between the test Cornell box's light and its ceiling, which then leaked.
# ABS covers the ray-triangle test's own rounding, which grows with the triangle's size (<= extent).
# Geometry finer than eps (gaps, thin walls, spheres of radius < eps) is not resolved; the limits
# are measured in tests/test_stability.py and listed in docs/limits.md.
OFFSET_REL = wp.constant(5.0e-7)
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
def offset_eps(p: wp.vec3, extent: float) -> float:
    """How far a ray origin keeps from the surfaces it lies on (see OFFSET_REL, OFFSET_ABS)."""
    m = wp.max(wp.max(wp.abs(p[0]), wp.abs(p[1])), wp.abs(p[2]))
    return OFFSET_REL * m + OFFSET_ABS * extent


@wp.func
def offset_origin(p: wp.vec3, ng: wp.vec3, through: int, extent: float) -> wp.vec3:
    """Move a new ray's origin off the surface, to the side it leaves on (replaces the seed's Q15)."""
    eps = offset_eps(p, extent)
    if through != 0:
        eps = -eps
    return p + ng * eps


@wp.func
def triangle_point(mesh: wp.uint64, face: int, u: float, v: float, extent: float) -> wp.vec3:
    """The hit point u*p0 + v*p1 + (1-u-v)*p2, kept at least about offset_eps inside the triangle.

    Two fixes for scenes far from the origin (the Cornell box shifted by 1e5 leaked sky along its
    edges, tests/test_stability.py):

    * evaluated as p2 + small edge terms: the plain form's three large products (what
      wp.mesh_eval_position does) each round, and the sum could land an ulp outside the triangle;
      rounding p2 + r to nearest is monotonic, so the point stays inside the triangle's box.
    * moved away from the triangle's edges: a hit within an ulp of an edge where two walls meet
      lies ON the other wall's plane, offset_origin moves it along this wall's normal only, and
      the next ray then met the other wall at t = 0 from behind and went through it. Barycentrics
      are raised to at least eps / altitude (capped at 1/3: tiny triangles give their centroid).
    """
    p0 = wp.mesh_get_point(mesh, 3 * face)
    p1 = wp.mesh_get_point(mesh, 3 * face + 1)
    p2 = wp.mesh_get_point(mesh, 3 * face + 2)
    e0 = p0 - p2
    e1 = p1 - p2
    eps = offset_eps(p2 + (e0 * u + e1 * v), extent)
    two_area = wp.length(wp.cross(e0, e1))
    k = wp.where(two_area > 0.0, eps / two_area, 1.0e30)
    # barycentric of a point at distance eps from the edge opposite each vertex: eps * |edge| / 2A
    bu = wp.max(u, wp.min(k * wp.length(p1 - p2), 0.33333334))
    bv = wp.max(v, wp.min(k * wp.length(p0 - p2), 0.33333334))
    bw = wp.max(1.0 - u - v, wp.min(k * wp.length(p1 - p0), 0.33333334))
    total = bu + bv + bw
    return p2 + (e0 * (bu / total) + e1 * (bv / total))


def make_shading(features: Features):
    """``surface_at``, ``emission`` and ``sample_scatter`` functions specialised to the scene's features."""

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
                sf.p = triangle_point(s.mesh_ids[h.index], h.face, h.u, h.v, s.extent)
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

    @wp.func
    def sample_scatter(s: SceneArrays, sf: Surface, d: wp.vec3, bilinear: int, state_in: wp.uint32):
        """Draw this bounce's four random numbers and scatter; returns the advanced random state
        (a state passed into a function is not advanced in the caller, so it comes back explicitly)."""
        state = state_in
        u_lobe = wp.randf(state)
        u1 = wp.randf(state)
        u2 = wp.randf(state)
        u_fresnel = wp.randf(state)
        return scatter(s, sf, d, u_lobe, u1, u2, u_fresnel, bilinear), state

    return surface_at, emission, sample_scatter
