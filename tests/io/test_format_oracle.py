"""trimesh (MIT, a test-only dependency) as an independent oracle: the same world-space triangles
from our readers and from trimesh's, on files without sparse accessors or strips."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support.format_files import binary_ply_mesh, gltf_box, gltf_two_instances
from warp_spt.io.gltf import load_gltf, world_triangles
from warp_spt.io.ply import load_ply

trimesh = pytest.importorskip("trimesh")


def _triangle_set(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Triangles as rows of 9 coordinates (float32), each rotated to start at its smallest corner (the
    winding kept), rows sorted: comparable whatever the vertex order and sharing."""
    t = np.asarray(positions, np.float64)[faces].astype(np.float32)          # (F, 3, 3)
    key = [tuple(c) for tri in t for c in tri]
    first = np.array([min(range(3), key=lambda k, i=i: key[3 * i + k]) for i in range(len(t))])
    rolled = np.stack([np.roll(tri, -f, axis=0) for tri, f in zip(t, first)]).reshape(len(t), 9)
    return rolled[np.lexsort(rolled.T[::-1])]


def _trimesh_world(path) -> tuple[np.ndarray, np.ndarray]:
    loaded = trimesh.load(path, process=False)
    mesh = loaded.to_geometry() if hasattr(loaded, "to_geometry") else loaded.dump(concatenate=True)
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


def test_binary_ply_agrees_with_trimesh(tmp_path):
    rng = np.random.default_rng(5)
    pos = rng.random((300, 3)).astype(np.float32)
    faces = rng.integers(0, 300, (900, 3)).astype(np.int32)
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    for big in (False, True):
        path = tmp_path / f"m{big}.ply"
        path.write_bytes(binary_ply_mesh(pos, faces, big))
        ours = load_ply(path)
        theirs = trimesh.load(path, process=False)
        assert np.array_equal(ours.positions, np.asarray(theirs.vertices, np.float64))
        assert np.array_equal(ours.faces, np.asarray(theirs.faces))


@pytest.mark.parametrize("make", [gltf_box, gltf_two_instances])
def test_gltf_node_transforms_agree_with_trimesh(tmp_path, make):
    path = tmp_path / "scene.glb"
    path.write_bytes(make().glb())
    ours = world_triangles(load_gltf(path))
    v, f = _trimesh_world(path)
    a, b = _triangle_set(*ours), _triangle_set(v, f)
    assert a.shape == b.shape and np.allclose(a, b, atol=1e-6)
