"""Ray-scene intersection on the device: our top-level BVH over per-OBJ meshes (or instances of
them) and spheres.

Inside a mesh, rays traverse its wide BVH (:mod:`warp_spt.accel.wide_traversal`), which answers as
``wp.mesh_query_ray`` would, faster. With instances (``Features.instances``: a mesh uploaded once and
placed by several affine transforms, ``MeshData.transforms``) a top-level item is an instance: the ray
goes into the mesh's object space (``o' = A^-1 (o - c)``, ``d' = A^-1 d``, left unnormalised so that
the hit's ``t`` is the world ``t``) and the geometric normal comes back through ``A^-T``.

``make_closest_hit(features)`` returns a Warp function specialised to the scene's features (no mesh
code in a spheres-only scene and vice versa).
"""

from __future__ import annotations

import warp as wp

from warp_spt.device.adjoint import zero_adjoint
from warp_spt.device.structs import Features, Geometry
from warp_spt.accel.wide_traversal import NO_HIT, MeshRay, make_any_hit_query, make_closest_query, mesh_ray

STACK = 64                 # traversal stack; bvh.build_tlas guarantees depth < 64
# Scenes of at most this many items (meshes + spheres) visit them all instead of traversing the TLAS,
# whose box tests then cost more than they prune. Measured (closest-hit rays/s, loop over TLAS, best
# of 25 on a busy machine): the tests' Cornell box (1 mesh + 2 spheres) 1.13-1.15x, the built-in
# demo (3 meshes + 3 spheres) 1.0-1.05x (benchmarks/bench_rays.py, "tlas loop" against
# "closest_hit"); that Cornell box with extra spheres (bench_rays.py --small-scene): 6 items
# 0.99-1.02x, 8 items 0.93-1.03x, 12 items 0.79-0.88x, 16 items 0.69-0.81x. Hence 6.
SMALL_SCENE = 6
KIND_MISS = wp.constant(-1)
KIND_TRIANGLE = wp.constant(0)
KIND_SPHERE = wp.constant(1)

vec_stack_i = wp.types.vector(length=STACK, dtype=wp.int32)
vec_stack_f = wp.types.vector(length=STACK, dtype=wp.float32)


@wp.struct
class Hit:
    """The closest intersection: kind (-1 miss, 0 triangle, 1 sphere), which one, where."""

    t: float
    kind: int
    index: int          # mesh index (triangles) or sphere index
    face: int           # triangle index within its mesh
    u: float            # barycentrics as wp.mesh_query_ray reports them
    v: float
    normal: wp.vec3     # unit geometric normal: triangle winding normal, or sphere outward normal
    # 1 + the top-level item (Geometry.inst_*) that placed the hit mesh (Features.instances only); 0: the
    # mesh is in world space (every hit of a scene without instances, and the light samplers' hits)
    placed: int


@wp.func
def safe_inverse(d: wp.vec3) -> wp.vec3:
    """1/d with zero components replaced by a huge finite value, so the slab test never sees 0*inf."""
    x = wp.where(wp.abs(d[0]) > 1.0e-30, d[0], wp.where(d[0] >= 0.0, 1.0e-30, -1.0e-30))
    y = wp.where(wp.abs(d[1]) > 1.0e-30, d[1], wp.where(d[1] >= 0.0, 1.0e-30, -1.0e-30))
    z = wp.where(wp.abs(d[2]) > 1.0e-30, d[2], wp.where(d[2] >= 0.0, 1.0e-30, -1.0e-30))
    return wp.vec3(1.0 / x, 1.0 / y, 1.0 / z)


@wp.func
def safe_inverse_from(inv: wp.vec3, d: wp.vec3) -> wp.vec3:
    """``safe_inverse(d)`` given ``inv``, the mesh ray's 1/d (``wide_traversal.mesh_ray``): the two
    divide the same numbers except where |d| <= 1e-30, so only those components are recomputed and
    a ray's top-level box tests cost no divisions of their own (bit for bit safe_inverse's)."""
    x = wp.where(wp.abs(d[0]) > 1.0e-30, inv[0], 1.0 / wp.where(d[0] >= 0.0, 1.0e-30, -1.0e-30))
    y = wp.where(wp.abs(d[1]) > 1.0e-30, inv[1], 1.0 / wp.where(d[1] >= 0.0, 1.0e-30, -1.0e-30))
    z = wp.where(wp.abs(d[2]) > 1.0e-30, inv[2], 1.0 / wp.where(d[2] >= 0.0, 1.0e-30, -1.0e-30))
    return wp.vec3(x, y, z)


@wp.func
def box_entry(lo: wp.vec3, hi: wp.vec3, o: wp.vec3, inv: wp.vec3, t_max: float) -> float:
    """Entry distance of the ray into the box, or NO_HIT. Inclusive, so flat boxes are hit (seed Q4)."""
    t0 = wp.cw_mul(lo - o, inv)
    t1 = wp.cw_mul(hi - o, inv)
    near = wp.max(wp.max(wp.min(t0[0], t1[0]), wp.min(t0[1], t1[1])), wp.min(t0[2], t1[2]))
    far = wp.min(wp.min(wp.max(t0[0], t1[0]), wp.max(t0[1], t1[1])), wp.max(t0[2], t1[2]))
    far = far * 1.0000004  # two ulps of slack: rounding must not reject a grazing hit
    near = wp.max(near, 0.0)
    if near <= far and near < t_max:
        return near
    return NO_HIT


@wp.func
def sphere_hit(sph: wp.vec4, o: wp.vec3, d: wp.vec3, t_max: float) -> float:
    """Nearest t in (0, t_max) where the unit-direction ray meets the sphere, or NO_HIT.

    Double precision and the stable form (discriminant from the perpendicular offset, near root as
    c/q) keep tiny spheres far away and huge spheres up close exact enough.
    """
    c = wp.vec3d(wp.float64(sph[0]), wp.float64(sph[1]), wp.float64(sph[2]))
    r = wp.float64(sph[3])
    dd = wp.vec3d(wp.float64(d[0]), wp.float64(d[1]), wp.float64(d[2]))
    oc = wp.vec3d(wp.float64(o[0]), wp.float64(o[1]), wp.float64(o[2])) - c
    b = wp.dot(oc, dd)
    f = oc - dd * b
    disc = r * r - wp.dot(f, f)
    if disc < wp.float64(0.0):
        return NO_HIT
    q = -b - wp.where(b >= wp.float64(0.0), wp.float64(1.0), wp.float64(-1.0)) * wp.sqrt(disc)
    if q == wp.float64(0.0):
        return NO_HIT
    cc = (wp.length(oc) - r) * (wp.length(oc) + r)
    t0 = cc / q
    t1 = q
    if t0 > t1:
        tmp = t0
        t0 = t1
        t1 = tmp
    if t0 > wp.float64(0.0) and t0 < wp.float64(t_max):
        return float(t0)
    if t1 > wp.float64(0.0) and t1 < wp.float64(t_max):
        return float(t1)
    return NO_HIT


def make_object_ray(wide: bool):
    """The ray in instance ``item``'s object space (the module's docstring: t stays a world distance),
    for the closest hit and the any-hit test alike; ``wide``: set up by ``mesh_ray`` for the wide traversal."""

    @wp.func(inline=True)
    def object_ray(s: Geometry, item: int, r: MeshRay) -> MeshRay:
        a = s.inst_to_object[item]
        ro = MeshRay()
        if wp.static(wide):
            ro = mesh_ray(a * r.o + s.inst_to_object_offset[item], a * r.d)
        else:
            ro.o = a * r.o + s.inst_to_object_offset[item]
            ro.d = a * r.d
        return ro

    return object_ray


def make_closest_hit(features: Features, small_scene: int = SMALL_SCENE, differentiable: bool = False):
    """The closest-hit function for scenes with these features.

    ``differentiable`` (the differentiable kernel only): the hit found by the traversal is
    re-intersected in closed form (:func:`make_refine_hit`), so that its distance and barycentrics
    carry derivatives with respect to the ray's origin and direction; the values stay those of the
    traversal bit for bit.

    A scene of at most ``small_scene`` items (meshes + spheres) skips our top-level BVH and visits
    every item in turn, behind the root box test (0 forces the TLAS, for tests and benchmarks): one
    mesh and no spheres is then a box test and a bare query of the mesh's own BVH. Same hits: the TLAS only prunes items whose box the ray
    misses or enters beyond the closest hit so far, which cannot hold the closest hit; only the
    order of visits differs, which matters just for exact ties in t between two items
    (tests/accel/test_intersect.py compares the two paths).
    """

    mesh_closest = make_closest_query(max(features.bvh_stack, 1))
    wide, warp_bvh = features.bvh_stack > 0, features.warp_meshes
    instanced = features.instances and features.meshes
    object_ray = make_object_ray(wide)

    # inline: called, it would copy the Geometry struct (~2 KB) at every call (measured: +25% time)
    @wp.func(inline=True)
    def mesh_query(s: Geometry, item: int, r: MeshRay, hit: Hit) -> Hit:
        if wp.static(warp_bvh):
            if not wp.static(wide) or s.mesh_root[item] < 0:
                q = wp.mesh_query_ray(s.mesh_ids[item], r.o, r.d, hit.t)
                if q.result:
                    hit.t = q.t
                    hit.kind = KIND_TRIANGLE
                    hit.index = item
                    hit.face = q.face
                    hit.u = q.u
                    hit.v = q.v
                    hit.normal = q.normal
                return hit
        if wp.static(wide):
            k, t, u, v = mesh_closest(s, item, r, hit.t)
            if k >= 0:
                hit.t = t
                hit.kind = KIND_TRIANGLE
                hit.index = item
                hit.face = s.tri_face[k]
                hit.u = u
                hit.v = v
                # as wp.mesh_query_ray's: the winding's cross product, normalised
                a = s.tri_v0[k]
                hit.normal = wp.normalize(wp.cross(s.tri_v1[k] - a, s.tri_v2[k] - a))
        return hit

    @wp.func(inline=True)
    def mesh_hit(s: Geometry, item: int, r: MeshRay, hit: Hit) -> Hit:
        if wp.static(instanced):
            ro = object_ray(s, item, r)
            # mesh_query sets the index only when it finds a closer hit: -1 marks "not found here"
            before = hit.index
            hit.index = -1
            hit = mesh_query(s, s.inst_mesh[item], ro, hit)
            if hit.index >= 0:
                hit.placed = item + 1
                hit.normal = wp.normalize(s.inst_normal[item] * hit.normal)
            else:
                hit.index = before
            return hit
        return mesh_query(s, item, r, hit)

    @wp.func(inline=True)
    def visit_item(s: Geometry, item: int, r: MeshRay, hit: Hit) -> Hit:
        o = r.o
        d = r.d
        n_mesh_items = s.num_meshes
        if wp.static(instanced):
            n_mesh_items = s.num_instances
        if item < n_mesh_items:
            if wp.static(features.meshes):
                hit = mesh_hit(s, item, r, hit)
        else:
            if wp.static(features.spheres):
                j = item - n_mesh_items
                sph = s.spheres[j]
                t = sphere_hit(sph, o, d, hit.t)
                if t < hit.t:
                    hit.t = t
                    hit.kind = KIND_SPHERE
                    hit.index = j
                    hit.normal = wp.normalize(o + d * t - wp.vec3(sph[0], sph[1], sph[2]))
        return hit

    @wp.func
    def closest_hit(s: Geometry, o: wp.vec3, d: wp.vec3, t_max: float) -> Hit:
        """Front-to-back traversal of our top-level BVH with closest-t pruning."""
        hit = Hit()
        hit.t = t_max
        hit.kind = KIND_MISS
        r = MeshRay()
        inv = wp.vec3()
        if wp.static(features.meshes and features.bvh_stack > 0):
            r = mesh_ray(o, d)
            inv = safe_inverse_from(r.inv, d)
        else:
            r.o = o
            r.d = d
            inv = safe_inverse(d)
        t_root = box_entry(s.node_lower[0], s.node_upper[0], o, inv, hit.t)
        if wp.static(small_scene > 0):
            n_items = s.items.shape[0]
            if n_items <= wp.static(small_scene):
                # the root box test stays: it rejects rays that miss the scene faster than the
                # items' own tests (a single mesh seen from afar: ~25% of closest-hit time)
                if t_root < NO_HIT:
                    # meshes, then spheres, in item order as before: one loop of visit_item, which
                    # branches on the kind per item, made a one-mesh closest hit ~9% slower
                    # (docs/performance.md, Where the time goes)
                    n_mesh_items = s.num_meshes
                    if wp.static(instanced):
                        n_mesh_items = s.num_instances
                    if wp.static(features.meshes):
                        for item in range(n_mesh_items):
                            hit = mesh_hit(s, item, r, hit)
                    if wp.static(features.spheres):
                        for item in range(n_mesh_items, n_items):
                            hit = visit_item(s, item, r, hit)
                return hit
        nodes = vec_stack_i()
        entries = vec_stack_f()
        sp = int(0)
        if t_root < NO_HIT:
            nodes[0] = 0
            entries[0] = t_root
            sp = 1
        while sp > 0:
            sp -= 1
            node = nodes[sp]
            if entries[sp] >= hit.t:
                continue
            left = s.node_left[node]
            if left < 0:
                first = s.node_first[node]
                for k in range(first, first + s.node_count[node]):
                    hit = visit_item(s, s.items[k], r, hit)
            else:
                right = s.node_right[node]
                tl = box_entry(s.node_lower[left], s.node_upper[left], o, inv, hit.t)
                tr = box_entry(s.node_lower[right], s.node_upper[right], o, inv, hit.t)
                # push the farther child first so the nearer one is visited first
                near_node = left
                near_t = tl
                far_node = right
                far_t = tr
                if tr < tl:
                    near_node = right
                    near_t = tr
                    far_node = left
                    far_t = tl
                if far_t < NO_HIT and sp < wp.static(STACK):
                    nodes[sp] = far_node
                    entries[sp] = far_t
                    sp += 1
                if near_t < NO_HIT and sp < wp.static(STACK):
                    nodes[sp] = near_node
                    entries[sp] = near_t
                    sp += 1
        return hit

    if not differentiable:
        return closest_hit
    # The traversal's result is detached (refine_hit gives the hit its derivative): its adjoint must be
    # nothing at all. Warp's own one would replay the traversal's loops and send what it made of them
    # back into the ray: with the wide traversal, values that changed with the thread count.
    zero_adjoint(closest_hit, (Hit,))
    refine_hit = make_refine_hit(features)

    @wp.func
    def closest_hit_diff(s: Geometry, o: wp.vec3, d: wp.vec3, t_max: float) -> Hit:
        # two calls, not one function: Warp's adjoint of a function skips its dynamic loops (the
        # traversal), while a caller's adjoint replays the whole call and hands its result on
        return refine_hit(s, closest_hit(s, o, d, t_max), o, d)

    return closest_hit_diff


def make_occluded(features: Features, small_scene: int = SMALL_SCENE):
    """An any-hit visibility test for shadow rays: True when something lies on the ray before t_max.

    Stops at the first blocker found (inside meshes: ``wide_traversal``'s any-hit query), so it is cheaper
    than a closest hit; the traversal order does not matter. Ready for light sampling. Small scenes
    skip the TLAS, as in make_closest_hit.
    """

    wide_any_hit = make_any_hit_query(max(features.bvh_stack, 1))
    wide, warp_bvh = features.bvh_stack > 0, features.warp_meshes
    instanced = features.instances and features.meshes
    object_ray = make_object_ray(wide)

    @wp.func(inline=True)
    def mesh_blocks(s: Geometry, item: int, r: MeshRay, t_max: float) -> bool:
        if wp.static(warp_bvh):
            if not wp.static(wide) or s.mesh_root[item] < 0:
                return wp.mesh_query_ray_anyhit(s.mesh_ids[item], r.o, r.d, t_max)
        if wp.static(wide):
            return wide_any_hit(s, item, r, t_max)
        return False

    @wp.func(inline=True)
    def mesh_any_hit(s: Geometry, item: int, r: MeshRay, t_max: float) -> bool:
        if wp.static(instanced):
            return mesh_blocks(s, s.inst_mesh[item], object_ray(s, item, r), t_max)
        return mesh_blocks(s, item, r, t_max)

    @wp.func(inline=True)
    def blocks(s: Geometry, item: int, r: MeshRay, t_max: float) -> bool:
        n_mesh_items = s.num_meshes
        if wp.static(instanced):
            n_mesh_items = s.num_instances
        if item < n_mesh_items:
            if wp.static(features.meshes):
                return mesh_any_hit(s, item, r, t_max)
        else:
            if wp.static(features.spheres):
                return sphere_hit(s.spheres[item - n_mesh_items], r.o, r.d, t_max) < t_max
        return False

    @wp.func
    def occluded(s: Geometry, o: wp.vec3, d: wp.vec3, t_max: float) -> bool:
        r = MeshRay()
        inv = wp.vec3()
        if wp.static(features.meshes and features.bvh_stack > 0):
            r = mesh_ray(o, d)
            inv = safe_inverse_from(r.inv, d)
        else:
            r.o = o
            r.d = d
            inv = safe_inverse(d)
        in_root = box_entry(s.node_lower[0], s.node_upper[0], o, inv, t_max) < NO_HIT
        if wp.static(small_scene > 0):
            n_items = s.items.shape[0]
            if n_items <= wp.static(small_scene):
                if in_root:
                    n_mesh_items = s.num_meshes
                    if wp.static(instanced):
                        n_mesh_items = s.num_instances
                    if wp.static(features.meshes):            # meshes, then spheres (as in closest_hit)
                        for item in range(n_mesh_items):
                            if mesh_any_hit(s, item, r, t_max):
                                return True
                    if wp.static(features.spheres):
                        for item in range(n_mesh_items, n_items):
                            if blocks(s, item, r, t_max):
                                return True
                return False
        nodes = vec_stack_i()
        sp = int(0)
        if in_root:
            nodes[0] = 0
            sp = 1
        while sp > 0:
            sp -= 1
            node = nodes[sp]
            left = s.node_left[node]
            if left < 0:
                first = s.node_first[node]
                for k in range(first, first + s.node_count[node]):
                    if blocks(s, s.items[k], r, t_max):
                        return True
            else:
                right = s.node_right[node]
                if box_entry(s.node_lower[left], s.node_upper[left], o, inv, t_max) < NO_HIT and sp < wp.static(STACK):
                    nodes[sp] = left
                    sp += 1
                if box_entry(s.node_lower[right], s.node_upper[right], o, inv, t_max) < NO_HIT and sp < wp.static(STACK):
                    nodes[sp] = right
                    sp += 1
        return False

    zero_adjoint(occluded, (bool,))      # visibility has no derivative here (as closest_hit's above)
    return occluded


# ------------------------------------------------------------------------------------------------
# Differentiable re-intersection (the differentiable kernel only)
#
# The traversal's result carries no derivative: it comes out of a dynamic loop, whose adjoint Warp
# drops. The hit primitive is known once it is found, and for one triangle or sphere the distance
# and barycentrics are closed-form, differentiable functions of the ray. ``with_derivative`` keeps
# the traversal's value and takes its derivative from the closed form, so the differentiable
# kernel's image stays bit-identical to the fast kernel's.


@wp.func
def detach(x: float) -> float:
    """``x``, with a zero derivative."""
    return x


@wp.func_grad(detach)
def adj_detach(x: float, adj_ret: float):
    wp.adjoint[x] += 0.0


@wp.func
def with_derivative(value: float, smooth: float) -> float:
    """``value`` (no derivative of its own), differentiated as ``smooth``, the same quantity in closed
    form: value + (smooth - smooth) is value exactly when smooth is finite."""
    if not wp.isfinite(smooth):
        return detach(value)
    return detach(value) + (smooth - detach(smooth))


@wp.func
def ray_triangle(p0: wp.vec3, p1: wp.vec3, p2: wp.vec3, o: wp.vec3, d: wp.vec3) -> wp.vec3:
    """(t, u, v) where the line o + t d meets the triangle's plane (Moller-Trumbore), barycentrics as
    wp.mesh_query_ray reports them (the point is u p0 + v p1 + (1 - u - v) p2); t is infinite for a
    ray parallel to the plane."""
    e1 = p1 - p0
    e2 = p2 - p0
    pv = wp.cross(d, e2)
    det = wp.dot(e1, pv)
    if det == 0.0:
        return wp.vec3(wp.inf, 0.0, 0.0)
    inv = 1.0 / det
    tv = o - p0
    b1 = wp.dot(tv, pv) * inv
    qv = wp.cross(tv, e1)
    b2 = wp.dot(d, qv) * inv
    return wp.vec3(wp.dot(e2, qv) * inv, 1.0 - b1 - b2, b1)


@wp.func
def ray_sphere(sph: wp.vec4, o: wp.vec3, d: wp.vec3, t_near: float) -> float:
    """The root of |o + t d - c| = r (unit d) closer to ``t_near``; infinite if the line misses."""
    c = wp.vec3(sph[0], sph[1], sph[2])
    oc = o - c
    b = wp.dot(oc, d)
    f = oc - d * b
    disc = sph[3] * sph[3] - wp.dot(f, f)
    if disc <= 0.0:
        return wp.inf
    s = wp.sqrt(disc)
    t0 = -b - s
    t1 = -b + s
    if wp.abs(t1 - t_near) < wp.abs(t0 - t_near):
        return t1
    return t0


@wp.func
def with_derivative_vec(value: wp.vec3, smooth: wp.vec3) -> wp.vec3:
    """:func:`with_derivative` per component."""
    return wp.vec3(with_derivative(value[0], smooth[0]), with_derivative(value[1], smooth[1]),
                   with_derivative(value[2], smooth[2]))


def make_refine_hit(features: Features):
    """``refine_hit(geo, hit, o, d) -> Hit``: ``hit`` with t, u, v and the normal differentiable in
    o and d and in the hit primitive (same values): a triangle's corners (``Geometry.corner_point``
    when the backward pass filled it, else the wp.Mesh's points, which carry no adjoint) and its
    instance's placement, or a sphere's centre and radius."""

    @wp.func
    def refine_hit(s: Geometry, h: Hit, o: wp.vec3, d: wp.vec3) -> Hit:
        r = Hit()
        r.kind = h.kind
        r.index = h.index
        r.face = h.face
        r.t = detach(h.t)
        r.u = detach(h.u)
        r.v = detach(h.v)
        r.normal = wp.vec3(detach(h.normal[0]), detach(h.normal[1]), detach(h.normal[2]))
        r.placed = h.placed
        if h.kind == KIND_TRIANGLE:
            if wp.static(features.meshes):
                p0 = wp.vec3()
                p1 = wp.vec3()
                p2 = wp.vec3()
                if s.has_corner_points != 0:
                    g = 3 * (s.face_offset[h.index] + h.face)
                    p0 = s.corner_point[g]
                    p1 = s.corner_point[g + 1]
                    p2 = s.corner_point[g + 2]
                else:
                    mesh = s.mesh_ids[h.index]
                    p0 = wp.mesh_get_point(mesh, 3 * h.face)
                    p1 = wp.mesh_get_point(mesh, 3 * h.face + 1)
                    p2 = wp.mesh_get_point(mesh, 3 * h.face + 2)
                if wp.static(features.instances):
                    if h.placed > 0:
                        a = s.inst_linear[h.placed - 1]
                        c = s.inst_offset[h.placed - 1]
                        p0 = a * p0 + c
                        p1 = a * p1 + c
                        p2 = a * p2 + c
                tuv = ray_triangle(p0, p1, p2, o, d)
                r.t = with_derivative(h.t, tuv[0])
                r.u = with_derivative(h.u, tuv[1])
                r.v = with_derivative(h.v, tuv[2])
                # the winding's normal of the placed corners (a mirroring placement flips the cross
                # product, not the traversal's A^-T normal: the sign follows the traversal's)
                n = wp.normalize(wp.cross(p1 - p0, p2 - p0))
                if wp.dot(n, h.normal) < 0.0:
                    n = -n
                r.normal = with_derivative_vec(h.normal, n)
        elif h.kind == KIND_SPHERE:
            if wp.static(features.spheres):
                r.t = with_derivative(h.t, ray_sphere(s.spheres[h.index], o, d, h.t))
        return r

    return refine_hit
