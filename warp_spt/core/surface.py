"""The surface at a hit: position, normals, material, uv; and where new rays start from it.

``make_surface(features)`` builds ``surface_at`` for the primitives the scene has. Materials
(``warp_spt.core.materials``) and lights (``warp_spt.core.lights``) read the :class:`Surface` it returns.
"""

from __future__ import annotations

import warp as wp

from warp_spt.core.adjoint import zero_adjoint
from warp_spt.core.device_scene import Features, Geometry
from warp_spt.core.geometry import KIND_TRIANGLE, Hit

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


def make_surface(features: Features):
    """``surface_at(geo, hit, o, d)``, specialised to the scene's primitives."""

    @wp.func
    def surface_at(s: Geometry, h: Hit, o: wp.vec3, d: wp.vec3) -> Surface:
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

    return surface_at


def detach_surface(surface_at) -> None:
    """Give ``surface_at`` (from :func:`make_surface`) a zero adjoint: no derivative reaches the hit,
    the ray or the geometry through it. Path replay's own functions only (``warp_spt.diff.prb``): it takes
    no pathwise derivatives (the hit and the sampled directions stay put), so the adjoint of the
    surface was computed and then dropped, after re-running the surface's forward code for it; the
    tape, whose camera gradients move the hits, keeps the full adjoint."""
    zero_adjoint(surface_at, (Surface,))
