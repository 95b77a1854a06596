"""Scenes for the geometry-gradient tests, built in Python with one feature set between them.

Every scene is its subject (a square, a cube, a sphere, a mesh ball) plus the same out-of-view kit,
which uses every material and every kind of geometry the subjects use (an instanced mesh with vertex
normals, an emitting triangle, an analytic sphere): all of them then have the same ``Features``, and
the tests compile one fast kernel, one tape kernel and one boundary kernel between them (a scene's
kernels are specialised to what it uses). The kit lies 27 units behind the camera, which looks down
-z from +z, under a constant sky: a path reaches it only through the sky's solid angle it covers
(about 1e-7: its parts are 0.01 across), the same in a render and in its finite differences.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from warp_spt.scene.camera import Camera
from warp_spt.scene.model import CHECKER_NAME, Material, MaterialTable, MeshData, Scene
from warp_spt.scene.sky import Sky

WHITE, RED, GLOW, LAMP, MIRROR = 1, 2, 3, 4, 5
SKY = Sky.constant(0.25, 0.25, 0.25)
CAMERA = Camera(position=(0.0, 0.0, 3.0), direction=(0.0, 0.0, -1.0), fov=40.0, aperture=0.0, focus=3.0,
                up=(0.0, 1.0, 0.0))


def materials() -> MaterialTable:
    return MaterialTable.from_rows([
        Material(CHECKER_NAME),
        Material("white", diffuse=(0.8, 0.8, 0.8), roughness=1.0),
        Material("red", diffuse=(0.8, 0.3, 0.2), roughness=1.0),
        Material("glow", diffuse=(0.0, 0.0, 0.0), emission=(1.0, 1.0, 1.0), roughness=1.0),
        Material("lamp", diffuse=(0.0, 0.0, 0.0), emission=(6.0, 6.0, 6.0), roughness=1.0),
        # the seed's model: no diffuse lobe, no fuzz, a perfect mirror
        Material("mirror", diffuse=(0.0, 0.0, 0.0), reflect=(0.9, 0.9, 0.9), roughness=0.0, fuzz=0.0),
    ])


def mesh(name: str, positions, faces, material, normals: bool = False) -> MeshData:
    p = np.asarray(positions, np.float64)
    f = np.asarray(faces, np.int32)
    mat = np.broadcast_to(np.asarray(material, np.int32), (len(f),)).copy()
    n = None
    if normals:        # the vertex normals of a ball centred on the origin
        c = p - p.mean(0)
        n = (c / np.linalg.norm(c, axis=1, keepdims=True))[f].astype(np.float32)
    return MeshData(name, p, f, np.zeros((len(f), 3, 2), np.float32), n, mat)


def square(half: float = 0.5, z: float = 0.0, material: int = GLOW, name: str = "square",
           transform: np.ndarray | None = None) -> MeshData:
    h = half
    p = np.array([(-h, -h, z), (h, -h, z), (h, h, z), (-h, h, z)], np.float64)
    if transform is not None:
        p = p @ transform[:3, :3].T + transform[:3, 3]
    return mesh(name, p, [(0, 1, 2), (0, 2, 3)], material)


CUBE_P = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)], np.float64)
CUBE_F = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                   [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.int32)


def cube(name: str = "cube", transform: np.ndarray | None = None, material=None) -> MeshData:
    """A unit cube: faces alternately white and red (a crease between two materials on each edge of a
    face pair), in world space moved by ``transform`` or, with ``placed``, left to MeshData.transforms."""
    mat = material if material is not None else np.where(np.arange(12) // 2 % 2 == 0, WHITE, RED)
    p = CUBE_P if transform is None else CUBE_P @ transform[:3, :3].T + transform[:3, 3]
    return mesh(name, p, CUBE_F, mat)


def ball(n: int = 2, radius: float = 0.6) -> MeshData:
    """An icosphere (welded: one row per vertex) of 20 * 4^n faces with vertex normals."""
    t = (1 + 5 ** 0.5) / 2
    v = [(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
         (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]
    f = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4), (11, 10, 2),
         (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9), (4, 9, 5),
         (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    verts = [np.array(x, np.float64) / np.linalg.norm(x) for x in v]
    for _ in range(n):
        mid: dict = {}
        out = []

        def m(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                c = verts[a] + verts[b]
                verts.append(c / np.linalg.norm(c))
                mid[key] = len(verts) - 1
            return mid[key]

        for a, b, c in f:
            ab, bc, ca = m(a, b), m(b, c), m(c, a)
            out += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        f = out
    return mesh("ball", np.array(verts) * radius, f, WHITE, normals=True)


def placement(rotation_vector=(0.0, 0.0, 0.0), offset=(0.0, 0.0, 0.0), scale=1.0) -> np.ndarray:
    from warp_spt.diff.geometry_params import rodrigues

    x = np.eye(4)
    x[:3, :3] = rodrigues(np.asarray(rotation_vector, np.float64)) * scale
    x[:3, 3] = offset
    return x


def kit() -> tuple[list[MeshData], np.ndarray, np.ndarray]:
    """(meshes, spheres (S, 4), sphere materials): the out-of-view objects every scene carries."""
    far = np.array([0.0, 0.0, 30.0])
    tiny = ball(2, 0.01)
    tiny = replace(tiny, name="kit_ball", face_material=np.resize(np.array([WHITE, RED, MIRROR], np.int32), len(tiny.indices)),
                   transforms=np.stack([placement(offset=far), placement(offset=far + [0.1, 0, 0])]))
    lamp = mesh("kit_lamp", far + [[0, 0.1, 0], [0.01, 0.1, 0], [0, 0.11, 0], [0.01, 0.11, 0]], [(0, 1, 2), (1, 3, 2)],
                [GLOW, LAMP])
    spheres = np.array([[0.0, -0.1, 30.0, 0.01]])
    return [tiny, lamp], spheres, np.array([WHITE], np.int32)


def scene(meshes: list[MeshData], spheres=None, sphere_materials=None) -> Scene:
    """The subject's meshes (and spheres, (S, 4) with their materials) with the kit."""
    k_meshes, k_spheres, k_mats = kit()
    s = np.zeros((0, 4)) if spheres is None else np.asarray(spheres, np.float64).reshape(-1, 4)
    sm = np.zeros(0, np.int32) if sphere_materials is None else np.asarray(sphere_materials, np.int32)
    return Scene(meshes=list(meshes) + k_meshes, spheres=np.concatenate([s, k_spheres]),
                 sphere_material=np.concatenate([sm, k_mats]).astype(np.int32), materials=materials(),
                 textures=[], seed_dialect=False)
