"""Geometry as named parameters: a mesh's vertex positions, an object's pose, a sphere's centre and radius.

* ``"<mesh>.positions"`` (V, 3): the mesh's vertices (one row per vertex: faces that share a vertex
  share its row). For a mesh placed by transforms (instances, glTF nodes) they are its own-space
  vertices, and moving them moves every placement.
* ``"<object>.translation"`` (3,), ``"<object>.rotation"`` (3,), ``"<object>.scale"`` (3,): the pose of
  one placement of a mesh relative to how it was loaded, about the centre of its bounds then: world
  point ``x -> c + t + R(r) diag(s) (x - c)`` applied after the placement's own transform. ``r`` is a
  rotation vector (axis times angle in radians, Rodrigues' formula): three numbers with no gimbal lock,
  whose gradient is defined everywhere (the map is smooth, and regular within |r| < 2 pi). An object is
  the mesh's name when it is placed once, ``"<mesh>[k]"`` for its k-th placement otherwise.
* ``"sphere<k>.center"`` (3,) and ``"sphere<k>.radius"`` () for the scene's k-th analytic sphere.

Setting one validates it (finite; coordinates within +-MAX_COORDINATE; no triangle of the result
degenerate or longer than MAX_TRIANGLE_EDGE, a scale component at least MIN_SCALE in magnitude; a
radius > 0) and uploads the changed geometry (:meth:`DeviceScene.update_geometry`): the meshes whose
triangles changed are rebuilt (their BVH), the rest keep theirs, and the top-level BVH and light table
are rebuilt. A mesh placed by transforms keeps its BVH when only its pose changes.

Gradients reach them through the differentiable kernel's closed-form re-intersection of each hit
(``accel.ray_queries.make_refine_hit``: corners from ``Geometry.corner_point``, the placement's maps,
the sphere's row) and through the primary-visibility boundary term (``diff.boundary``). The chain
rules from what the kernel reads (corners, corner normals, placements) to these parameters are here.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from warp_spt.scene.limits import MAX_COORDINATE, MAX_TRIANGLE_EDGE

MESH, POSE, SPHERE = "mesh", "pose", "sphere"
GEOMETRY_KINDS = (MESH, POSE, SPHERE)
POSE_FIELDS = ("translation", "rotation", "scale")
MIN_SCALE = 1e-6
FD_STEP = 1e-6           # central differences of the smooth pose maps (float64): ~1e-9 relative


@dataclass
class Pose:
    """One placement of mesh ``mesh`` (its ``placement``-th), its transform at load ``base`` (4, 4),
    the pivot ``pivot`` (3,) and the current pose values."""

    mesh: int
    placement: int
    base: np.ndarray
    pivot: np.ndarray
    translation: np.ndarray
    rotation: np.ndarray
    scale: np.ndarray

    def values(self) -> np.ndarray:
        return np.concatenate([self.translation, self.rotation, self.scale])


def rodrigues(r: np.ndarray) -> np.ndarray:
    """The rotation matrix of rotation vector ``r`` (float64)."""
    r = np.asarray(r, dtype=np.float64)
    a = float(np.linalg.norm(r))
    k = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
    if a < 1e-8:        # series: I + K + K^2 / 2, exact to float64 there
        return np.eye(3) + k + 0.5 * k @ k
    return np.eye(3) + np.sin(a) / a * k + (1.0 - np.cos(a)) / (a * a) * k @ k


def pose_matrix(pivot: np.ndarray, values: np.ndarray) -> np.ndarray:
    """(4, 4) world map of pose ``values`` (translation, rotation vector, scale; 9 numbers) about ``pivot``."""
    t, r, s = values[0:3], values[3:6], values[6:9]
    linear = rodrigues(r) @ np.diag(s)
    m = np.eye(4)
    m[:3, :3] = linear
    m[:3, 3] = pivot + t - linear @ pivot
    return m


def placement(pose: Pose, values: np.ndarray | None = None) -> np.ndarray:
    """The (4, 4) object-to-world map of ``pose`` (with pose ``values`` if given)."""
    return pose_matrix(pose.pivot, pose.values() if values is None else values) @ pose.base


def describe(scene, taken: set) -> tuple[dict, list[Pose]]:
    """(name -> (kind, field, index, shape), poses) for the geometry of ``scene`` (the device scene's
    host scene); names already in ``taken`` (materials, lights) get a ``geometry:`` prefix."""
    out: dict = {}
    poses: list[Pose] = []

    def add(name: str, kind: str, field: str, index: int, shape: tuple) -> None:
        n = name if name not in taken and name not in out else f"geometry:{name}"
        out[n] = (kind, field, index, shape)

    names = _object_names(scene)
    for k, m in enumerate(scene.meshes):
        if not len(m.indices):
            continue
        add(f"{names[k]}.positions", MESH, "positions", k, (len(m.positions), 3))
        bounds = m.placement_bounds()
        for j in range(m.placements):
            base = np.eye(4) if m.transforms is None else np.asarray(m.transforms[j], dtype=np.float64)
            pivot = 0.5 * (bounds[j, 0] + bounds[j, 1])
            poses.append(Pose(k, j, base, pivot, np.zeros(3), np.zeros(3), np.ones(3)))
            obj = names[k] if m.placements == 1 else f"{names[k]}[{j}]"
            for f in POSE_FIELDS:
                add(f"{obj}.{f}", POSE, f, len(poses) - 1, (3,))
    for j in range(len(scene.spheres)):
        add(f"sphere{j}.center", SPHERE, "center", j, (3,))
        add(f"sphere{j}.radius", SPHERE, "radius", j, ())
    return out, poses


def _object_names(scene) -> list[str]:
    """A unique name per mesh: its own, with ``#k`` added where two meshes share one."""
    raw = [m.name or f"mesh{k}" for k, m in enumerate(scene.meshes)]
    return [n if raw.count(n) == 1 else f"{n}#{k}" for k, n in enumerate(raw)]


# ------------------------------------------------------------------------------------------------
# Setting values: a new host scene


def check_positions(name: str, m, positions: np.ndarray, linear: np.ndarray | None = None) -> None:
    """Refuse positions outside +-MAX_COORDINATE, or a triangle they make degenerate or too long (in
    world space: ``linear`` maps them there for a placed mesh)."""
    if np.any(np.abs(positions) > MAX_COORDINATE):
        raise ValueError(f"{name}: coordinates must lie within +-{MAX_COORDINATE:g}")
    p = positions if linear is None else positions @ linear.T
    tri = p[m.indices]
    e1, e2 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    area = np.linalg.norm(np.cross(e1, e2), axis=1)
    longest = np.max(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2), axis=1)
    bad = np.flatnonzero(~(area > 1e-30 * np.maximum(longest, 1e-30)))
    if len(bad):
        raise ValueError(f"{name}: the new positions make {len(bad)} triangle(s) degenerate (zero area), "
                         f"the first face {int(bad[0])}; a degenerate triangle is never hit and has no normal")
    if np.any(longest > MAX_TRIANGLE_EDGE):
        raise ValueError(f"{name}: a triangle's edge would exceed {MAX_TRIANGLE_EDGE:g}")


def with_pose(scene, base_meshes: list, poses: list[Pose], k: int):
    """``scene`` with mesh ``k`` placed as its poses say: a mesh placed by transforms gets new
    transforms (its own-space positions and BVH stay); a world-space mesh gets its base positions and
    corner normals moved (normals by the inverse transpose, renormalised)."""
    m = scene.meshes[k]
    base = base_meshes[k]
    mine = [p for p in poses if p.mesh == k]
    if m.transforms is not None:
        xf = np.stack([placement(p) for p in mine])
        meshes = list(scene.meshes)
        meshes[k] = replace(m, transforms=xf)
        return replace(scene, meshes=meshes)
    x = placement(mine[0])
    linear = x[:3, :3]
    pos = np.asarray(base.positions, dtype=np.float64) @ linear.T + x[:3, 3]
    normals = base.corner_normal
    if normals is not None:
        n = normals.astype(np.float64) @ np.linalg.inv(linear)        # A^-T n, as row vectors
        normals = (n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)).astype(np.float32)
    indices, uv = base.indices, base.corner_uv
    if np.linalg.det(linear) < 0:        # a mirror reverses the winding (MeshData.placed's rule)
        indices, uv = indices[:, ::-1].copy(), uv[:, ::-1].copy()
        normals = None if normals is None else normals[:, ::-1].copy()
    meshes = list(scene.meshes)
    meshes[k] = replace(m, positions=pos.astype(np.float32), indices=indices, corner_uv=uv, corner_normal=normals)
    return replace(scene, meshes=meshes)


def check_pose(name: str, field: str, v: np.ndarray) -> None:
    if field == "scale" and np.any(np.abs(v) < MIN_SCALE):
        raise ValueError(f"{name}: each scale component must be at least {MIN_SCALE:g} in magnitude "
                         f"(a zero scale flattens the object: its triangles would be degenerate)")
    if field == "translation" and np.any(np.abs(v) > MAX_COORDINATE):
        raise ValueError(f"{name}: coordinates must lie within +-{MAX_COORDINATE:g}")


def check_sphere(name: str, field: str, v: np.ndarray) -> None:
    if field == "radius" and not float(v) > 0.0:
        raise ValueError(f"{name}: the radius must be > 0, got {float(v)}")
    if np.any(np.abs(v) > MAX_COORDINATE):
        raise ValueError(f"{name}: values must lie within +-{MAX_COORDINATE:g}")


# ------------------------------------------------------------------------------------------------
# What the kernels read, and the chain rules back to the parameters


def corner_points(scene) -> np.ndarray:
    """(3 F, 3) float32: every mesh's corners in its own space, in the kernels' face order
    (``Geometry.face_offset``): what ``Geometry.corner_point`` holds for the backward pass."""
    parts = [np.asarray(m.positions, dtype=np.float32)[m.indices].reshape(-1, 3) for m in scene.meshes]
    return np.concatenate(parts) if parts else np.zeros((0, 3), np.float32)


def face_ranges(scene) -> list[tuple[int, int]]:
    """(first, end) face of each mesh in the kernels' per-face arrays."""
    out, k = [], 0
    for m in scene.meshes:
        out.append((k, k + len(m.indices)))
        k += len(m.indices)
    return out


def item_of(scene, pose: Pose) -> int:
    """The top-level item (``Geometry.inst_*`` row) of ``pose``'s placement."""
    return sum(m.placements for m in scene.meshes[:pose.mesh]) + pose.placement


def vertex_gradient(scene, k: int, corner_grad: np.ndarray) -> np.ndarray:
    """(V, 3) float64: the gradient of mesh ``k``'s vertices from its corners' (F, 3, 3)."""
    m = scene.meshes[k]
    g = np.zeros((len(m.positions), 3))
    np.add.at(g, m.indices.reshape(-1), corner_grad.reshape(-1, 3))
    return g


def flat_normal_gradient(scene, k: int, normal_grad: np.ndarray) -> np.ndarray:
    """(V, 3): the vertices' gradient through mesh ``k``'s corner normals when they are its flat face
    normals (a mesh without vertex normals in a scene whose kernels read corner normals): each face's
    three corners hold normalize((p1 - p0) x (p2 - p0))."""
    m = scene.meshes[k]
    p = np.asarray(m.positions, dtype=np.float64)[m.indices]
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    c = np.cross(e1, e2)
    ln = np.maximum(np.linalg.norm(c, axis=1, keepdims=True), 1e-300)
    n = c / ln
    gn = normal_grad.sum(axis=1)                                 # (F, 3): all three corners hold n
    gc = (gn - n * np.sum(gn * n, axis=1, keepdims=True)) / ln   # through the normalisation
    # c = e1 x e2: dc = de1 x e2 + e1 x de2, so d/de1 = e2 x gc and d/de2 = gc x e1
    g1, g2 = np.cross(e2, gc), np.cross(gc, e1)
    corner = np.stack([-g1 - g2, g1, g2], axis=1)
    return vertex_gradient(scene, k, corner)


def pose_derivative(pose: Pose, objective) -> np.ndarray:
    """(9,): d objective(x) / d (translation, rotation, scale), x = placement(pose, values) (4, 4), by
    central differences of the smooth float64 map (FD_STEP: ~1e-9 relative)."""
    v0 = pose.values()
    out = np.zeros(9)
    for i in range(9):
        h = FD_STEP * max(1.0, abs(v0[i]))
        vp, vm = v0.copy(), v0.copy()
        vp[i] += h
        vm[i] -= h
        out[i] = (objective(placement(pose, vp)) - objective(placement(pose, vm))) / (2.0 * h)
    return out


def pose_gradient_world(pose: Pose, base_mesh, world_grad: np.ndarray, normal_grad: np.ndarray | None) -> np.ndarray:
    """(9,) d/d(translation, rotation, scale) of a world-space mesh's pose from the gradient of its
    world vertices (V, 3) and, where the kernels read its corner normals (moved by the inverse
    transpose and renormalised), of those (F, 3, 3)."""
    base = np.asarray(base_mesh.positions, dtype=np.float64)
    n0 = None if normal_grad is None else _base_normals(base_mesh)

    def objective(x):
        val = np.sum(world_grad * (base @ x[:3, :3].T + x[:3, 3]))
        if n0 is not None:
            n = n0 @ np.linalg.inv(x[:3, :3])
            n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)
            val += np.sum(normal_grad * n)
        return val

    return pose_derivative(pose, objective)


def _base_normals(m) -> np.ndarray:
    """(F, 3, 3) float64 corner normals the kernels read for mesh ``m`` (its own, or its flat ones)."""
    if m.corner_normal is not None:
        return m.corner_normal.astype(np.float64)
    p = np.asarray(m.positions, dtype=np.float64)[m.indices]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    return np.repeat(n[:, None, :], 3, axis=1)


def pose_gradient_placed(pose: Pose, g_linear: np.ndarray, g_offset: np.ndarray, g_normal: np.ndarray) -> np.ndarray:
    """(9,) d/d(translation, rotation, scale) of an instance's pose from the gradients of its row of
    ``inst_linear`` (3, 3), ``inst_offset`` (3,) and ``inst_normal`` (3, 3) (= A^-T)."""
    return pose_derivative(pose, lambda x: np.sum(g_linear * x[:3, :3]) + np.dot(g_offset, x[:3, 3])
                           + np.sum(g_normal * np.linalg.inv(x[:3, :3]).T))


def pose_slice(field: str) -> slice:
    k = POSE_FIELDS.index(field)
    return slice(3 * k, 3 * k + 3)
