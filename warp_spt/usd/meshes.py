"""UsdGeom meshes to triangles: faces (quads and n-gons fanned, holes left out, a left-handed mesh's
winding reversed), their primvars by interpolation (vertex, varying, face-varying, uniform,
constant; indexed ones flattened), and their material subsets."""

from __future__ import annotations

import numpy as np

from warp_spt.scene.errors import SceneError


def fan(counts: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(corners (T, 3) into the flat face-vertex list, face (T,) of each triangle): each face of
    ``counts[k]`` corners as a fan from its first corner (USD's polygons are planar and, as in
    Hydra's own triangulation, taken to be convex)."""
    counts = np.asarray(counts, np.int64)
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]]).astype(np.int64)
    per = np.maximum(counts - 2, 0)
    face = np.repeat(np.arange(len(counts)), per)
    k = np.arange(len(face)) - np.repeat(np.cumsum(per) - per, per)      # the triangle's place in its fan
    first = starts[face]
    return np.stack([first, first + k + 1, first + k + 2], axis=1), face


def corner_values(values: np.ndarray, interpolation: str, corners: np.ndarray, face: np.ndarray,
                  vertex_of_corner: np.ndarray, where: str, name: str) -> tuple[np.ndarray, np.ndarray]:
    """(values, (T, 3) index per triangle corner) of a primvar by its interpolation."""
    if interpolation in ("vertex", "varying"):
        index = vertex_of_corner[corners]
    elif interpolation == "faceVarying":
        index = corners
    elif interpolation == "uniform":
        index = np.repeat(face[:, None], 3, axis=1)
    elif interpolation == "constant":
        index = np.zeros_like(corners)
    else:
        raise SceneError(where, 0, f"{name}: unknown interpolation {interpolation!r}")
    if len(index) and (index.max() >= len(values) or len(values) == 0):
        raise SceneError(where, 0, f"{name} has {len(values)} values, too few for its {interpolation} "
                         f"interpolation (index {int(index.max())} is needed)")
    return values, index.astype(np.int32)


def triangulate(points: np.ndarray, counts: np.ndarray, indices: np.ndarray, holes: np.ndarray,
                left_handed: bool, where: str) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(triangles (T, 3) into points, corners (T, 3) into the face-vertex list, face of each): a mesh's
    faces checked (counts sum to the indices, every index a point) and fanned, holes dropped."""
    counts, indices = np.asarray(counts, np.int64), np.asarray(indices, np.int64)
    if (counts < 0).any() or counts.sum() != len(indices):
        raise SceneError(where, 0, f"faceVertexCounts sum to {int(counts.sum())} but faceVertexIndices has "
                         f"{len(indices)} entries")
    if len(indices) and (indices.min() < 0 or indices.max() >= len(points)):
        raise SceneError(where, 0, f"faceVertexIndices names point {int(indices.max())}, but the mesh has "
                         f"{len(points)} points")
    corners, face = fan(counts)
    if len(holes):
        keep = ~np.isin(face, np.asarray(holes, np.int64))
        corners, face = corners[keep], face[keep]
    if left_handed:                  # USD's default is right-handed (counter-clockwise) winding
        corners = corners[:, ::-1]
    return indices[corners].astype(np.int32), corners, face
