"""The scene graph: the default scene's node tree walked from its roots, each node's world transform
(TRS or matrix, posed by the animation), and every mesh a node names either flattened into world
space or, where it is placed more than once or moves, kept in its own space with its placements
(the instances of the top-level BVH)."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np

from warp_spt.gltf.animation import Animation
from warp_spt.gltf.cameras_lights import CamerasLights
from warp_spt.gltf.document import _err
from warp_spt.gltf.meshes import GltfExtras
from warp_spt.scene.media import open_edges
from warp_spt.scene.model import CHECKER_NAME, Material, ObjData
from warp_spt.scene.validate import MAX_COORDINATE

MAX_NODE_DEPTH = 256                   # nesting of nodes below a root


def world_triangles(d: ObjData) -> tuple[np.ndarray, np.ndarray]:
    """(positions (V, 3) float64, triangles (F, 3) int32): a read file's triangles all in world space,
    its flattened ones first, then every placement of each instanced mesh (``GltfExtras.placed``; a
    mirroring placement reverses the winding, as flattening does)."""
    positions, faces, n = [d.positions], [d.faces], len(d.positions)
    for sub, transforms in getattr(d.extras, "placed", ()):
        for x in transforms:
            positions.append(sub.positions @ x[:3, :3].T + x[:3, 3])
            faces.append((sub.faces[:, ::-1] if np.linalg.det(x[:3, :3]) < 0 else sub.faces) + n)
            n += len(sub.positions)
    return np.concatenate(positions), np.concatenate(faces).astype(np.int32)


class Reader(Animation, CamerasLights):
    def run(self) -> ObjData:
        nodes = self.get(self.doc, "nodes", list, "", [])
        roots = self._roots(len(nodes))
        channels, time_range = self._animation(len(nodes))
        parts: list[tuple] = []           # (positions, triangles, uv or None, normals or None, material row)
        extras = GltfExtras(time_range=time_range)
        material_rows: dict[int | None, int] = {}
        names = [CHECKER_NAME]
        materials: dict[str, Material] = {}
        seen: set[int] = set()
        # The walk checks each node and keeps its local transform (3 x 4, row-major) and its parent's
        # place in the walk; the world matrices are then composed level by level in whole arrays, and
        # cameras and lights read after: per-node numpy calls were most of a 200,000-node file's
        # reading time (64 of its 100 us per node; benchmarks/bench_instances.py)
        order: list[int] = []
        local_rows: list[list[float]] = []
        parent_at: list[int] = []         # the parent's position in ``order`` (-1: a root)
        depth_at: list[int] = []
        attached: list[tuple] = []        # (position in order, "camera" or "light", what, pointer)
        scene_ptr = f"/scenes/{self._scene_index()}/nodes"
        stack = [(k, -1, 0, scene_ptr, False) for k in reversed(roots)]
        moving: dict[int, bool] = {}      # the node or an ancestor has a TRS channel
        for_mesh: list[int | None] = []
        while stack:
            k, parent, depth, via, parent_moves = stack.pop()
            ptr = f"/nodes/{k}"
            if k in seen:
                raise _err(self.path, via, f"node {k} is reached twice: the nodes form a cycle or a node has two "
                           "parents")
            seen.add(k)
            if depth > MAX_NODE_DEPTH:
                raise _err(self.path, ptr, f"nodes nest more than {MAX_NODE_DEPTH} deep")
            node = self.item("nodes", k)
            at = len(order)
            local_rows.append(self._local_rows(node, ptr, channels.get(k)))
            parent_at.append(parent)
            depth_at.append(depth)
            moving[k] = parent_moves or (self.time is not None and any(
                c in channels.get(k, {}) for c in ("translation", "rotation", "scale")))
            order.append(k)
            for_mesh.append(self.index(node, "mesh", ptr, "meshes"))
            cam = self.index(node, "camera", ptr, "cameras")
            if cam is not None:
                attached.append((at, "camera", cam, ptr))
            if "extensions" in node:
                light = self.get(self.obj(node, "extensions", ptr), "KHR_lights_punctual", dict, f"{ptr}/extensions")
                if light is not None:
                    attached.append((at, "light", light, f"{ptr}/extensions/KHR_lights_punctual"))
            children = self.get(node, "children", list, ptr, [])
            for c, child in reversed(list(enumerate(children))):
                if not isinstance(child, int) or isinstance(child, bool) or not 0 <= child < len(nodes):
                    raise _err(self.path, f"{ptr}/children/{c}", f"expected a node index in 0..{len(nodes) - 1}, got "
                               f"{json.dumps(child)[:40]}")
                stack.append((child, at, depth + 1, f"{ptr}/children/{c}", moving[k]))
        world_at = _compose(local_rows, parent_at, depth_at)
        worlds: dict[int, np.ndarray] = dict(zip(order, world_at))
        for at, what, ref, ptr in attached:       # in the walk's order, as the file lists them
            if what == "camera":
                extras.cameras.append(self._camera(ref, order[at], world_at[at]))
            else:
                extras.lights.append(self._light(ref, ptr, world_at[at]))
        # a node scaled to nothing (a common way to hide one) draws nothing, as its flattened
        # triangles of zero area would not be drawn
        visible = np.abs(np.linalg.det(world_at[:, :3, :3])) > 1e-30 if len(order) else np.zeros(0, bool)
        # meshes after the walk: a skin needs its joints' world matrices, wherever they are in the tree
        users: dict[int, int] = {}
        for mesh in for_mesh:
            if mesh is not None:
                users[mesh] = users.get(mesh, 0) + 1
        placed: dict[int, tuple[list, list]] = {}        # mesh -> (object-space parts, world matrices)
        for at, k in enumerate(order):
            mesh = for_mesh[at]
            if mesh is None:
                continue
            node, ptr = self.item("nodes", k), f"/nodes/{k}"
            world = world_at[at]
            extras.instances.append((k, mesh, world))
            skin = self._skin(node, ptr, worlds)
            weights = self._morph_weights(node, ptr, mesh, channels.get(k, {}).get("weights"))
            if (users[mesh] > 1 or moving[k]) and skin is None and weights is None:
                if mesh not in placed:
                    placed[mesh] = (self._object_parts(mesh, material_rows, names, materials), [])
                if placed[mesh][0] is not None:
                    if visible[at]:
                        placed[mesh][1].append(world)
                    else:
                        extras.hidden += 1
                    continue
            for prim_k, prim in enumerate(self._primitives(mesh)):
                pptr = f"/meshes/{mesh}/primitives/{prim_k}"
                mat = self.index(prim, "material", pptr, "materials")
                row = self._row(mat, material_rows, names, materials)
                parts.append((*self._primitive(prim, pptr, world, mat, skin, weights), row))
        extras.materials = [self._material_record(m) for m in range(len(self.get(self.doc, "materials", list, "", [])))]
        for mesh, (mesh_parts, xf) in placed.items():
            if mesh_parts is None or not xf:
                continue
            sub = self._object(mesh_parts, names, materials, GltfExtras())
            sub.path = f"{self.path}#mesh{mesh}"
            transforms = np.stack(xf)
            self._check_placed(sub, transforms, f"/meshes/{mesh}")
            if len(sub.faces):
                extras.placed.append((sub, transforms))
        out = self._object(parts, names, materials, extras)
        self._open_volumes(out, materials)
        return out

    def _open_volumes(self, out: ObjData, materials: dict[str, Material]) -> None:
        """A thick material (KHR_materials_volume) whose surfaces do not close has no inside for its
        medium to fill, and a ray that entered one would never leave it: drawn thin-walled instead,
        with a warning. Each placed mesh is closed or not in its own space, as every copy is."""
        pieces = [out] + [sub for sub, _ in out.extras.placed]
        for row, name in enumerate(out.material_names):
            m = materials.get(name)
            if m is None or m.interior is None:
                continue
            n_open = sum(open_edges(p.positions, p.faces[p.face_material == row]) for p in pieces)
            if n_open:
                materials[name] = replace(m, interior=None, thin=True)
                out.warnings.append(f"{self.path}: material {name!r} has KHR_materials_volume but its surfaces are "
                                    f"not closed ({n_open} edges not shared by two triangles): drawn thin-walled, "
                                    "without its attenuation")

    def _object_parts(self, mesh: int, material_rows: dict, names: list, materials: dict) -> list | None:
        """Mesh ``mesh``'s primitives in its own object space, to be instanced; None where it cannot be
        (vertex colours: they are baked into a texture of the whole file's triangles)."""
        out = []
        for prim_k, prim in enumerate(self._primitives(mesh)):
            pptr = f"/meshes/{mesh}/primitives/{prim_k}"
            mat = self.index(prim, "material", pptr, "materials")
            part = self._primitive(prim, pptr, np.eye(4), mat)
            if part[4] is not None:
                return None
            out.append((*part, self._row(mat, material_rows, names, materials)))
        return out

    def _row(self, mat: int | None, material_rows: dict, names: list, materials: dict) -> int:
        """The material row of glTF material ``mat`` (None: the default), made on its first use."""
        if mat not in material_rows:
            name, material = self._checked_material(mat, names)
            material_rows[mat] = len(names)
            names.append(name)
            materials[name] = material
        return material_rows[mat]

    def _check_placed(self, sub: ObjData, transforms: np.ndarray, ptr: str) -> None:
        """Every placement of an instanced mesh within the coordinate range, as flattened vertices are."""
        if not len(sub.positions):
            return
        lo, hi = sub.positions.min(0), sub.positions.max(0)
        corners = np.array([[(hi if (i >> a) & 1 else lo)[a] for a in range(3)] for i in range(8)])
        world = np.einsum("nij,kj->nki", transforms[:, :3, :3], corners) + transforms[:, None, :3, 3]
        if not np.abs(world).max() <= MAX_COORDINATE:
            raise _err(self.path, ptr, f"an instance's vertex lies near {np.abs(world).max():g}, beyond the "
                       f"supported range of +-{MAX_COORDINATE:g}")

    def _scene_index(self) -> int:
        scenes = self.get(self.doc, "scenes", list, "", [])
        k = self.get(self.doc, "scene", int, "", 0 if scenes else None)
        if k is not None and not 0 <= k < max(len(scenes), 1):
            raise _err(self.path, "/scene", f"scene index {k} is out of range: the file has {len(scenes)} scenes")
        return k or 0

    def _roots(self, n_nodes: int) -> list[int]:
        scenes = self.get(self.doc, "scenes", list, "", [])
        if not scenes:          # no scene: every node that is nobody's child
            children = set()
            for k in range(n_nodes):
                children.update(c for c in self.get(self.item("nodes", k), "children", list, f"/nodes/{k}", [])
                                if isinstance(c, int))
            return [k for k in range(n_nodes) if k not in children]
        s = self._scene_index()
        roots = self.get(self.item("scenes", s), "nodes", list, f"/scenes/{s}", [])
        for r, k in enumerate(roots):
            if not isinstance(k, int) or isinstance(k, bool) or not 0 <= k < n_nodes:
                raise _err(self.path, f"/scenes/{s}/nodes/{r}", f"expected a node index in 0..{n_nodes - 1}, got "
                           f"{json.dumps(k)[:40]}")
        return roots

    def _local_rows(self, node: dict, ptr: str, animated: dict | None = None) -> list[float]:
        """The node's local transform's top three rows, row-major (12 floats): in Python floats, the
        same operations in the same order as a 4 x 4 array's, so the same bits."""
        matrix = self.numbers(node, "matrix", ptr, 16, None)
        if matrix is not None and animated:
            raise _err(self.path, f"{ptr}/matrix", "a node with a matrix cannot be animated (glTF: use TRS)")
        if matrix is not None:
            if matrix[3] != 0 or matrix[7] != 0 or matrix[11] != 0 or matrix[15] != 1:   # column-major
                if not np.allclose(np.array(matrix, np.float64)[3::4], [0, 0, 0, 1]):
                    raise _err(self.path, f"{ptr}/matrix", "the last row must be 0, 0, 0, 1 (an affine transform)")
            return [matrix[c * 4 + r] for r in range(3) for c in range(4)]
        t = self.numbers(node, "translation", ptr, 3, None) if "translation" in node else [0.0, 0.0, 0.0]
        q = self.numbers(node, "rotation", ptr, 4, None) if "rotation" in node else [0.0, 0.0, 0.0, 1.0]
        s = self.numbers(node, "scale", ptr, 3, None) if "scale" in node else [1.0, 1.0, 1.0]
        if animated and self.time is not None:
            t = animated["translation"](self.time) if "translation" in animated else t
            q = animated["rotation"](self.time) if "rotation" in animated else q
            s = animated["scale"](self.time) if "scale" in animated else s
        q0, q1, q2, q3 = float(q[0]), float(q[1]), float(q[2]), float(q[3])
        norm = math.sqrt(q0 * q0 + q1 * q1 + q2 * q2 + q3 * q3)
        if not norm > 0:
            raise _err(self.path, f"{ptr}/rotation", "a rotation quaternion must not be zero")
        r = quaternion_rows(q0 / norm, q1 / norm, q2 / norm, q3 / norm)
        s0, s1, s2 = float(s[0]), float(s[1]), float(s[2])
        rows = [r[0] * s0, r[1] * s1, r[2] * s2, float(t[0]),
                r[3] * s0, r[4] * s1, r[5] * s2, float(t[1]),
                r[6] * s0, r[7] * s1, r[8] * s2, float(t[2])]
        if not all(map(math.isfinite, rows)):              # animated values far out of range
            raise _err(self.path, ptr, "the node's transform is not finite")
        return rows


def _compose(local_rows: list, parent_at: list, depth_at: list) -> np.ndarray:
    """(N, 4, 4) world matrices of the walked nodes from their local rows, level by level: a node's
    world is its parent's times its own (a root's its own)."""
    n = len(local_rows)
    world = np.zeros((n, 4, 4))
    if not n:
        return world
    world[:, :3] = np.asarray(local_rows, np.float64).reshape(n, 3, 4)
    world[:, 3, 3] = 1.0
    parent = np.asarray(parent_at, np.int64)
    depth = np.asarray(depth_at, np.int64)
    for d in range(1, int(depth.max()) + 1):
        (rows,) = np.nonzero(depth == d)
        world[rows] = np.matmul(world[parent[rows]], world[rows])
    return world


def quaternion_rows(x: float, y: float, z: float, w: float) -> tuple:
    """The rotation matrix of a unit quaternion (x, y, z, w), row-major, in Python floats."""
    return (1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w),
            2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w),
            2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y))


def quaternion_matrix(q: np.ndarray) -> np.ndarray:
    """The rotation matrix (3, 3) of a unit quaternion (x, y, z, w): :func:`quaternion_rows` as an array."""
    return np.array(quaternion_rows(*(float(v) for v in q))).reshape(3, 3)


