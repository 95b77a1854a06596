"""Instanced meshes on the device: each distinct mesh uploaded once, placed by affine transforms.

A glTF mesh that several nodes use (``io.gltf.GltfExtras.instances``) need not be copied per node:
:func:`upload_instances` uploads the distinct meshes once (one ``wp.Mesh`` and one wide BVH each,
through :class:`~warp_spt.core.device_scene.DeviceScene`, in object space) and builds a top-level
BVH over the instances' world boxes. :func:`make_instance_closest_hit` traverses it: at an instance
the ray goes into object space (``o' = A^-1 (o - c)``, ``d' = A^-1 d``, left unnormalised so that
the hit's ``t`` is the world ``t``), the mesh is queried as the renderer's closest hit queries it,
and the geometric normal comes back through the inverse transpose ``A^-T``, normalised.

This is the intersection half of instancing. Rendering an instanced scene also needs the surface
lookup (``core/surface.py``: the hit point, shading normals and tangents through the transform) and
the emissive-triangle light table in world space; until those read instances the renderer flattens
(docs/formats.md, "Instances").
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_spt.core.bvh import Tlas, build_tlas
from warp_spt.core.device_scene import DeviceScene, Geometry
from warp_spt.core.geometry import KIND_MISS, KIND_TRIANGLE, NO_HIT, STACK, Hit, box_entry, safe_inverse
from warp_spt.core.wide_traversal import make_any_hit_query, make_closest_query, mesh_ray
from warp_spt.scene.model import CHECKER_NAME, Material, MaterialTable, MeshData, Scene

vec_stack_i = wp.types.vector(length=STACK, dtype=wp.int32)
vec_stack_f = wp.types.vector(length=STACK, dtype=wp.float32)


@wp.struct
class Instances:
    """Per instance: its mesh, the world-to-object map (``inv_linear @ p + inv_offset``) and the
    normal map ``A^-T``; and the top-level BVH over the instances' world boxes."""

    mesh: wp.array(dtype=wp.int32)
    inv_linear: wp.array(dtype=wp.mat33)
    inv_offset: wp.array(dtype=wp.vec3)
    normal_to_world: wp.array(dtype=wp.mat33)
    node_lower: wp.array(dtype=wp.vec3)
    node_upper: wp.array(dtype=wp.vec3)
    node_left: wp.array(dtype=wp.int32)
    node_right: wp.array(dtype=wp.int32)
    node_first: wp.array(dtype=wp.int32)
    node_count: wp.array(dtype=wp.int32)
    items: wp.array(dtype=wp.int32)


INSTANCE_ARRAYS = ("mesh", "inv_linear", "inv_offset", "normal_to_world", "node_lower", "node_upper", "node_left",
                   "node_right", "node_first", "node_count", "items")


@dataclass
class InstancedScene:
    """The distinct meshes on the device (object space) and their instances."""

    meshes: DeviceScene
    instances: Instances
    tlas: Tlas
    transforms: np.ndarray       # (I, 4, 4) float64 object-to-world
    mesh_of: np.ndarray          # (I,) int32

    def device_bytes(self) -> int:
        """Bytes of the device arrays that hold geometry: the meshes' and the instances'."""
        g = self.meshes.geometry
        arrays = [getattr(g, name) for name in ("bvh_box", "bvh_child", "tri_v0", "tri_v1", "tri_v2", "tri_face",
                                                "face_material", "corner_uv", "corner_normal")]
        arrays += [getattr(self.instances, name) for name in INSTANCE_ARRAYS]
        total = sum(a.capacity for a in arrays if a is not None)
        for m in self.meshes._meshes:       # each wp.Mesh's points and indices (its own BVH is extra)
            total += m.points.capacity + m.indices.capacity
        return int(total)


def object_box_corners(lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """The 8 corners of a box (8, 3)."""
    return np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])


def upload_instances(meshes: list[MeshData], mesh_of, transforms, device: str = "cpu") -> InstancedScene:
    """Upload each of ``meshes`` once (object space) and place instance i of mesh ``mesh_of[i]`` by the
    4x4 affine ``transforms[i]`` (object to world; its linear part must be invertible)."""
    mesh_of = np.asarray(mesh_of, dtype=np.int32)
    transforms = np.asarray(transforms, dtype=np.float64).reshape(-1, 4, 4)
    if len(mesh_of) != len(transforms) or len(mesh_of) == 0:
        raise ValueError(f"upload_instances: {len(mesh_of)} mesh indices for {len(transforms)} transforms")
    if mesh_of.min() < 0 or mesh_of.max() >= len(meshes):
        raise ValueError(f"upload_instances: mesh index out of range 0..{len(meshes) - 1}")
    linear = transforms[:, :3, :3]
    det = np.linalg.det(linear)
    if not np.all(np.isfinite(det)) or np.any(np.abs(det) < 1e-30):
        raise ValueError("upload_instances: every transform's linear part must be invertible")
    inv = np.linalg.inv(linear)
    inv_offset = -np.einsum("nij,nj->ni", inv, transforms[:, :3, 3])
    table = MaterialTable.from_rows([Material(CHECKER_NAME)])
    objects = [MeshData(name=m.name, positions=m.positions, indices=m.indices, corner_uv=m.corner_uv,
                        corner_normal=m.corner_normal, face_material=np.zeros(len(m.indices), np.int32))
               for m in meshes]
    scene = Scene(meshes=objects, spheres=np.zeros((0, 4)), sphere_material=np.zeros(0, np.int32),
                  materials=table, textures=[])
    ds = DeviceScene(scene, device)
    # world boxes: the object box's corners transformed (float64), padded by float32 rounding of the
    # ray's transform so that no hit the object-space query finds lies outside its instance's box
    lowers, uppers = [], []
    for lo, hi in ds._mesh_bounds:
        lowers.append(lo)
        uppers.append(hi)
    corners = np.stack([object_box_corners(lowers[m], uppers[m]) for m in range(len(meshes))])   # (M, 8, 3)
    world = np.einsum("nij,nkj->nki", linear, corners[mesh_of]) + transforms[:, None, :3, 3]
    wlo, whi = world.min(1), world.max(1)
    pad = 1e-6 * (whi - wlo).max(1, keepdims=True) + 1e-6 * np.abs(world).max(axis=(1, 2))[:, None]
    tlas = build_tlas(wlo - pad, whi + pad)
    inst = Instances()
    f32 = np.float32
    inst.mesh = wp.array(mesh_of, dtype=wp.int32, device=device)
    inst.inv_linear = wp.array(inv.astype(f32), dtype=wp.mat33, device=device)
    inst.inv_offset = wp.array(inv_offset.astype(f32), dtype=wp.vec3, device=device)
    inst.normal_to_world = wp.array(np.transpose(inv, (0, 2, 1)).astype(f32), dtype=wp.mat33, device=device)
    inst.node_lower = wp.array(tlas.lower, dtype=wp.vec3, device=device)
    inst.node_upper = wp.array(tlas.upper, dtype=wp.vec3, device=device)
    inst.node_left = wp.array(tlas.left, dtype=wp.int32, device=device)
    inst.node_right = wp.array(tlas.right, dtype=wp.int32, device=device)
    inst.node_first = wp.array(tlas.first, dtype=wp.int32, device=device)
    inst.node_count = wp.array(tlas.count, dtype=wp.int32, device=device)
    inst.items = wp.array(tlas.items, dtype=wp.int32, device=device)
    return InstancedScene(ds, inst, tlas, transforms, mesh_of)


def make_instance_closest_hit(features):
    """``closest(g, inst, o, d, t_max) -> Hit`` over instances (``Hit.index`` is the instance,
    ``Hit.face`` the triangle within its mesh, ``Hit.normal`` the world geometric normal)."""
    mesh_closest = make_closest_query(max(features.bvh_stack, 1))
    wide, warp_bvh = features.bvh_stack > 0, features.warp_meshes

    @wp.func(inline=True)
    def visit(g: Geometry, inst: Instances, i: int, o: wp.vec3, d: wp.vec3, hit: Hit) -> Hit:
        m = inst.mesh[i]
        a = inst.inv_linear[i]
        oo = a * o + inst.inv_offset[i]
        dd = a * d
        n = wp.vec3(0.0)
        found = False
        if wp.static(warp_bvh):
            if not wp.static(wide) or g.mesh_root[m] < 0:
                q = wp.mesh_query_ray(g.mesh_ids[m], oo, dd, hit.t)
                if q.result:
                    hit.t = q.t
                    hit.face = q.face
                    hit.u = q.u
                    hit.v = q.v
                    n = q.normal
                    found = True
        if wp.static(wide):
            if g.mesh_root[m] >= 0:
                r = mesh_ray(oo, dd)
                k, t, u, v = mesh_closest(g, m, r, hit.t)
                if k >= 0:
                    hit.t = t
                    hit.face = g.tri_face[k]
                    hit.u = u
                    hit.v = v
                    p0 = g.tri_v0[k]
                    n = wp.cross(g.tri_v1[k] - p0, g.tri_v2[k] - p0)
                    found = True
        if found:
            hit.kind = KIND_TRIANGLE
            hit.index = i
            hit.normal = wp.normalize(inst.normal_to_world[i] * n)
        return hit

    @wp.func
    def closest(g: Geometry, inst: Instances, o: wp.vec3, d: wp.vec3, t_max: float) -> Hit:
        hit = Hit()
        hit.t = t_max
        hit.kind = KIND_MISS
        inv = safe_inverse(d)
        nodes = vec_stack_i()
        entries = vec_stack_f()
        sp = int(0)
        t_root = box_entry(inst.node_lower[0], inst.node_upper[0], o, inv, hit.t)
        if t_root < NO_HIT:
            nodes[0] = 0
            entries[0] = t_root
            sp = 1
        while sp > 0:
            sp -= 1
            node = nodes[sp]
            if entries[sp] >= hit.t:
                continue
            left = inst.node_left[node]
            if left < 0:
                first = inst.node_first[node]
                for k in range(first, first + inst.node_count[node]):
                    hit = visit(g, inst, inst.items[k], o, d, hit)
            else:
                right = inst.node_right[node]
                tl = box_entry(inst.node_lower[left], inst.node_upper[left], o, inv, hit.t)
                tr = box_entry(inst.node_lower[right], inst.node_upper[right], o, inv, hit.t)
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

    return closest


def make_instance_occluded(features):
    """``occluded(g, inst, o, d, t_max) -> bool``: something of some instance lies on the ray before
    ``t_max`` (shadow rays; the first blocker found ends the search)."""
    wide_any_hit = make_any_hit_query(max(features.bvh_stack, 1))
    wide, warp_bvh = features.bvh_stack > 0, features.warp_meshes

    @wp.func(inline=True)
    def blocks(g: Geometry, inst: Instances, i: int, o: wp.vec3, d: wp.vec3, t_max: float) -> bool:
        m = inst.mesh[i]
        a = inst.inv_linear[i]
        oo = a * o + inst.inv_offset[i]
        dd = a * d
        if wp.static(warp_bvh):
            if not wp.static(wide) or g.mesh_root[m] < 0:
                return wp.mesh_query_ray_anyhit(g.mesh_ids[m], oo, dd, t_max)
        if wp.static(wide):
            return wide_any_hit(g, m, mesh_ray(oo, dd), t_max)
        return False

    @wp.func
    def occluded(g: Geometry, inst: Instances, o: wp.vec3, d: wp.vec3, t_max: float) -> bool:
        inv = safe_inverse(d)
        nodes = vec_stack_i()
        sp = int(0)
        if box_entry(inst.node_lower[0], inst.node_upper[0], o, inv, t_max) < NO_HIT:
            nodes[0] = 0
            sp = 1
        while sp > 0:
            sp -= 1
            node = nodes[sp]
            left = inst.node_left[node]
            if left < 0:
                first = inst.node_first[node]
                for k in range(first, first + inst.node_count[node]):
                    if blocks(g, inst, inst.items[k], o, d, t_max):
                        return True
            else:
                right = inst.node_right[node]
                if box_entry(inst.node_lower[left], inst.node_upper[left], o, inv, t_max) < NO_HIT \
                        and sp < wp.static(STACK):
                    nodes[sp] = left
                    sp += 1
                if box_entry(inst.node_lower[right], inst.node_upper[right], o, inv, t_max) < NO_HIT \
                        and sp < wp.static(STACK):
                    nodes[sp] = right
                    sp += 1
        return False

    return occluded
