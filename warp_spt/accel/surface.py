"""The surface at a hit, the shading point every material call receives; and where new rays start.

``make_surface(features)`` builds ``surface_at`` for the primitives the scene has. It gives the
position, the geometric and shading normals (both towards the side the ray came from), the material,
the uv, ``wo`` (the direction back along the ray) and, where a material kind asked for one
(``Features.needs("frame")``), a shading frame: the tangent ``t`` (from the mesh's uv where the kind
needs it to follow the uv, ``"frame.uv"``: normal maps, anisotropy; else any direction orthogonal to
``ns``) and the uv's bitangent ``b``. Materials (``warp_spt.bsdfs``; their ``shade`` may
perturb the frame) and lights (``warp_spt.emitters``) read the :class:`Surface` it returns.
"""

from __future__ import annotations

import warp as wp

from warp_spt.device.adjoint import zero_adjoint
from warp_spt.accel.ray_queries import KIND_TRIANGLE, Hit, with_derivative_vec
from warp_spt.device.structs import Features, Geometry

INV_PI = wp.constant(0.3183098861837907)
INV_TWO_PI = wp.constant(0.15915494309189535)
# Ray origins keep eps = REL * max|p| + ABS * scene extent away from the surfaces they lie on
# (along the normal, offset_origin, and in from the triangle's edges, triangle_point).
# REL covers float32 rounding of a hit point (at most ~1 ulp, and an ulp is <= 1.2e-7 * |p|): 5e-7
# is >= 4 ulps. It was 2e-6 (17-34 ulps); at 1e6 from the origin that is 2 units, more than the
# gap between the test Cornell box's light and its ceiling, which then leaked.
# ABS covers the ray-triangle test's own rounding, which grows with the triangle's size (<= extent).
# Geometry finer than eps (gaps, thin walls, spheres of radius < eps) is not resolved; the limits
# are measured in tests/rendering/test_stability.py and listed in docs/limits.md.
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
    wo: wp.vec3        # unit direction back towards where the ray came from (-d)
    t: wp.vec3         # shading tangent, orthogonal to ns (Features.needs("frame") only; else zero)
    b: wp.vec3         # the uv's bitangent direction, orthogonal to ns and t (normal maps' y axis)
    ns0: wp.vec3       # ns as interpolated, before a material's maps change ns (a clearcoat's own frame)


@wp.func
def any_tangent(n: wp.vec3) -> wp.vec3:
    """A unit vector orthogonal to unit ``n``, continuous except where n.z changes sign (Duff et al.
    2017's branchless basis: no normalisation, no special case near the poles)."""
    s = wp.where(n[2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (s + n[2])
    return wp.vec3(1.0 + s * n[0] * n[0] * a, s * n[0] * n[1] * a, -s * n[0])


@wp.func
def frame_from(ns: wp.vec3, t_hint: wp.vec3) -> wp.vec3:
    """The tangent ``t_hint`` made orthogonal to ``ns`` and unit (``any_tangent`` where it is zero
    or parallel to ``ns``)."""
    t = t_hint - ns * wp.dot(t_hint, ns)
    if wp.length(t) > 1.0e-12:
        return wp.normalize(t)
    return any_tangent(ns)


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
    edges, tests/rendering/test_stability.py):

    * evaluated as p2 + small edge terms: the plain form's three large products (what
      wp.mesh_eval_position does) each round, and the sum could land an ulp outside the triangle;
      rounding p2 + r to nearest is monotonic, so the point stays inside the triangle's box.
    * moved away from the triangle's edges: a hit within an ulp of an edge where two walls meet
      lies ON the other wall's plane, offset_origin moves it along this wall's normal only, and
      the next ray then met the other wall at t = 0 from behind and went through it. Barycentrics
      are raised to at least eps / altitude (capped at 1/3: tiny triangles give their centroid).
    """
    return triangle_point_of(wp.mesh_get_point(mesh, 3 * face), wp.mesh_get_point(mesh, 3 * face + 1),
                             wp.mesh_get_point(mesh, 3 * face + 2), u, v, extent)


@wp.func
def triangle_point_of(p0: wp.vec3, p1: wp.vec3, p2: wp.vec3, u: float, v: float, extent: float) -> wp.vec3:
    """:func:`triangle_point` of the triangle with these world-space corners (an instance's, moved
    out of its mesh's object space)."""
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


def make_surface(features: Features, differentiable: bool = False):
    """``surface_at(geo, hit, o, d)``, specialised to the scene's primitives. ``differentiable`` (the
    tape's kernel): a triangle's point keeps its value and takes the derivative of ``o + t d``, the
    point where the ray meets the (moving) triangle's plane: the value's corners come from the
    wp.Mesh, whose look-up has no adjoint."""

    @wp.func
    def surface_at(s: Geometry, h: Hit, o: wp.vec3, d: wp.vec3) -> Surface:
        sf = Surface()
        n_out = h.normal
        ns = h.normal
        if h.kind == KIND_TRIANGLE:
            if wp.static(features.meshes):
                g = s.face_offset[h.index] + h.face
                sf.mat = s.face_material[g]
                placed = False
                if wp.static(features.instances):
                    placed = h.placed > 0
                if placed:
                    # corners into world space first: the point is then made exactly as for a
                    # world-space mesh (kept inside the triangle, off its edges)
                    mesh = s.mesh_ids[h.index]
                    a = s.inst_linear[h.placed - 1]
                    c = s.inst_offset[h.placed - 1]
                    sf.p = triangle_point_of(a * wp.mesh_get_point(mesh, 3 * h.face) + c,
                                             a * wp.mesh_get_point(mesh, 3 * h.face + 1) + c,
                                             a * wp.mesh_get_point(mesh, 3 * h.face + 2) + c, h.u, h.v, s.extent)
                else:
                    sf.p = triangle_point(s.mesh_ids[h.index], h.face, h.u, h.v, s.extent)
                if wp.static(differentiable):
                    sf.p = with_derivative_vec(sf.p, o + d * h.t)
                w = 1.0 - h.u - h.v
                sf.uv = s.corner_uv[3 * g] * h.u + s.corner_uv[3 * g + 1] * h.v + s.corner_uv[3 * g + 2] * w
                if wp.static(features.smooth):
                    if s.has_corner_normals != 0:
                        n = (s.corner_normal[3 * g] * h.u + s.corner_normal[3 * g + 1] * h.v
                             + s.corner_normal[3 * g + 2] * w)
                        if placed:
                            n = s.inst_normal[h.placed - 1] * n        # normals map by A^-T
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
        sf.ns0 = ns
        sf.wo = -d
        if wp.static(features.needs("frame")):
            hint = wp.vec3(0.0, 0.0, 0.0)
            sign = float(1.0)
            if wp.static(features.needs("frame.uv")):
                if h.kind == KIND_TRIANGLE:
                    if wp.static(features.meshes):
                        if s.has_corner_tangents != 0:
                            g = s.face_offset[h.index] + h.face
                            w = 1.0 - h.u - h.v
                            c0 = s.corner_tangent[3 * g]
                            c1 = s.corner_tangent[3 * g + 1]
                            c2 = s.corner_tangent[3 * g + 2]
                            hint = (wp.vec3(c0[0], c0[1], c0[2]) * h.u + wp.vec3(c1[0], c1[1], c1[2]) * h.v
                                    + wp.vec3(c2[0], c2[1], c2[2]) * w)
                            sign = c0[3]
                            if wp.static(features.instances):
                                if h.placed > 0:
                                    # tangents map by A; a mirroring A flips the (t, b, n) frame's
                                    # handedness, which the bitangent's sign carries
                                    a = s.inst_linear[h.placed - 1]
                                    hint = a * hint
                                    if wp.determinant(a) < 0.0:
                                        sign = -sign
                else:
                    # a sphere's u grows with the azimuth about z (surface_at's spherical uv)
                    hint = wp.vec3(-ns[1], ns[0], 0.0)
            sf.t = frame_from(ns, hint)
            # the uv's bitangent about the outward normal: flipped with ns on a back face, so that
            # (t, b, outward n) stays the frame a tangent-space normal map was baked in
            n_face = wp.where(sf.front != 0, ns, -ns)
            sf.b = wp.cross(n_face, sf.t) * sign
        return sf

    return surface_at


def detach_surface(surface_at) -> None:
    """Give ``surface_at`` (from :func:`make_surface`) a zero adjoint: no derivative reaches the hit,
    the ray or the geometry through it. Path replay's own functions only (``warp_spt.diff.prb``): it takes
    no pathwise derivatives (the hit and the sampled directions stay put), so the adjoint of the
    surface was computed and then dropped, after re-running the surface's forward code for it; the
    tape, whose camera gradients move the hits, keeps the full adjoint."""
    zero_adjoint(surface_at, (Surface,))
