"""Ray-scene intersection on the device: our top-level BVH over per-OBJ ``wp.Mesh`` BVHs and spheres.

``make_closest_hit(features)`` returns a Warp function specialised to the scene's features (no mesh
code in a spheres-only scene and vice versa).
"""

from __future__ import annotations

import warp as wp

from .device_scene import Features, Geometry

STACK = 64                 # traversal stack; bvh.build_tlas guarantees depth < 64
NO_HIT = wp.constant(3.0e38)
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


@wp.func
def safe_inverse(d: wp.vec3) -> wp.vec3:
    """1/d with zero components replaced by a huge finite value, so the slab test never sees 0*inf."""
    x = wp.where(wp.abs(d[0]) > 1.0e-30, d[0], wp.where(d[0] >= 0.0, 1.0e-30, -1.0e-30))
    y = wp.where(wp.abs(d[1]) > 1.0e-30, d[1], wp.where(d[1] >= 0.0, 1.0e-30, -1.0e-30))
    z = wp.where(wp.abs(d[2]) > 1.0e-30, d[2], wp.where(d[2] >= 0.0, 1.0e-30, -1.0e-30))
    return wp.vec3(1.0 / x, 1.0 / y, 1.0 / z)


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


def make_closest_hit(features: Features):
    """The closest-hit function for scenes with these features."""

    @wp.func
    def visit_item(s: Geometry, item: int, o: wp.vec3, d: wp.vec3, hit: Hit) -> Hit:
        if item < s.num_meshes:
            if wp.static(features.meshes):
                q = wp.mesh_query_ray(s.mesh_ids[item], o, d, hit.t)
                if q.result:
                    hit.t = q.t
                    hit.kind = KIND_TRIANGLE
                    hit.index = item
                    hit.face = q.face
                    hit.u = q.u
                    hit.v = q.v
                    hit.normal = q.normal
        else:
            if wp.static(features.spheres):
                j = item - s.num_meshes
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
        inv = safe_inverse(d)
        nodes = vec_stack_i()
        entries = vec_stack_f()
        sp = int(0)
        t_root = box_entry(s.node_lower[0], s.node_upper[0], o, inv, hit.t)
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
                    hit = visit_item(s, s.items[k], o, d, hit)
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

    return closest_hit


def make_occluded(features: Features):
    """An any-hit visibility test for shadow rays: True when something lies on the ray before t_max.

    Stops at the first blocker found (``wp.mesh_query_ray_anyhit`` inside meshes), so it is cheaper
    than a closest hit; the traversal order does not matter. Ready for light sampling.
    """

    @wp.func
    def blocks(s: Geometry, item: int, o: wp.vec3, d: wp.vec3, t_max: float) -> bool:
        if item < s.num_meshes:
            if wp.static(features.meshes):
                return wp.mesh_query_ray_anyhit(s.mesh_ids[item], o, d, t_max)
        else:
            if wp.static(features.spheres):
                return sphere_hit(s.spheres[item - s.num_meshes], o, d, t_max) < t_max
        return False

    @wp.func
    def occluded(s: Geometry, o: wp.vec3, d: wp.vec3, t_max: float) -> bool:
        inv = safe_inverse(d)
        nodes = vec_stack_i()
        sp = int(0)
        if box_entry(s.node_lower[0], s.node_upper[0], o, inv, t_max) < NO_HIT:
            nodes[0] = 0
            sp = 1
        while sp > 0:
            sp -= 1
            node = nodes[sp]
            left = s.node_left[node]
            if left < 0:
                first = s.node_first[node]
                for k in range(first, first + s.node_count[node]):
                    if blocks(s, s.items[k], o, d, t_max):
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

    return occluded
