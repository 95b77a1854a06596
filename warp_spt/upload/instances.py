"""Instanced meshes on the device, from a list of meshes and placements.

The renderer's own upload and traversal do the work: a ``MeshData`` with ``transforms`` is uploaded
once (one ``wp.Mesh`` and one wide BVH, in object space) and :mod:`warp_spt.accel.ray_queries`'s
top-level BVH holds one item per placement (``Features.instances``). :func:`upload_instances` is the
list-of-placements front end the tests and ``benchmarks/bench_formats.py`` use: instance ``i`` of mesh
``mesh_of[i]`` placed by ``transforms[i]``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.scene.model import CHECKER_NAME, Material, MaterialTable, MeshData, Scene


@dataclass
class InstancedScene:
    """The distinct meshes on the device (object space) and their placements, as the renderer holds them."""

    device: DeviceScene
    transforms: np.ndarray       # (I, 4, 4) float64 object-to-world, in the order given
    mesh_of: np.ndarray          # (I,) int32
    item_of: np.ndarray          # (I,) int32: the top-level item (Hit.placed - 1) of each instance

    def device_bytes(self) -> int:
        """Bytes of the device arrays that hold geometry: the meshes' and the instances'."""
        return geometry_bytes(self.device)


def geometry_bytes(dev: DeviceScene) -> int:
    """Bytes of a device scene's geometry arrays: per-triangle data, each ``wp.Mesh``'s points and
    indices (its own BVH, one leaf for meshes with our wide BVH, is not counted), the instances'."""
    g = dev.geometry
    names = ("bvh_box", "bvh_child", "tri_v0", "tri_v1", "tri_v2", "tri_face", "face_material", "corner_uv",
             "corner_normal", "corner_tangent", "inst_mesh", "inst_linear", "inst_offset", "inst_to_object",
             "inst_to_object_offset", "inst_normal", "node_lower", "node_upper", "node_left", "node_right",
             "node_first", "node_count", "items")
    total = sum(getattr(g, name).capacity for name in names if getattr(g, name) is not None)
    for m in dev._meshes:
        total += m.points.capacity + m.indices.capacity
    return int(total)


def instanced_scene(meshes: list[MeshData], mesh_of, transforms) -> tuple[Scene, np.ndarray]:
    """A Scene whose mesh k is ``meshes[k]`` placed by every ``transforms[i]`` with ``mesh_of[i] == k``
    (4x4 object-to-world affine maps; meshes placed by none are left out), and the top-level item of
    each instance (items are numbered mesh by mesh)."""
    mesh_of = np.asarray(mesh_of, dtype=np.int32)
    transforms = np.asarray(transforms, dtype=np.float64).reshape(-1, 4, 4)
    if len(mesh_of) != len(transforms) or len(mesh_of) == 0:
        raise ValueError(f"upload_instances: {len(mesh_of)} mesh indices for {len(transforms)} transforms")
    if mesh_of.min() < 0 or mesh_of.max() >= len(meshes):
        raise ValueError(f"upload_instances: mesh index out of range 0..{len(meshes) - 1}")
    det = np.linalg.det(transforms[:, :3, :3])
    if not np.all(np.isfinite(det)) or np.any(np.abs(det) < 1e-30):
        raise ValueError("upload_instances: every transform's linear part must be invertible")
    objects, item_of, first = [], np.zeros(len(mesh_of), np.int32), 0
    for k, m in enumerate(meshes):
        mine = np.flatnonzero(mesh_of == k)
        if not len(mine):
            continue
        item_of[mine] = first + np.arange(len(mine))
        first += len(mine)
        objects.append(MeshData(name=m.name, positions=m.positions, indices=m.indices, corner_uv=m.corner_uv,
                                corner_normal=m.corner_normal,
                                face_material=np.zeros(len(m.indices), np.int32),
                                transforms=transforms[mine]))
    table = MaterialTable.from_rows([Material(CHECKER_NAME)])
    scene = Scene(meshes=objects, spheres=np.zeros((0, 4)), sphere_material=np.zeros(0, np.int32),
                  materials=table, textures=[])
    return scene, item_of


def upload_instances(meshes: list[MeshData], mesh_of, transforms, device: str = "cpu") -> InstancedScene:
    """Upload each of ``meshes`` once (object space; every face with the default material) and place
    instance i of mesh ``mesh_of[i]`` by the 4x4 affine ``transforms[i]`` (object to world; its linear
    part must be invertible)."""
    scene, item_of = instanced_scene(meshes, mesh_of, transforms)
    return InstancedScene(DeviceScene(scene, device), np.asarray(transforms, np.float64).reshape(-1, 4, 4),
                          np.asarray(mesh_of, np.int32), item_of)
