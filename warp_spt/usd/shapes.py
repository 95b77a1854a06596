"""UsdGeom's implicit shapes as polygons: a ``Sphere`` (``radius``) and a ``Cube`` (``size``), the
two that Warp's ``warp.render.UsdRenderer`` writes for bodies and particles, in the prim's own space
and counter-clockwise from outside as a mesh's faces are. A sphere placed by a similarity (no
instances, no non-uniform scale) is drawn as the renderer's exact sphere instead (``stage.py``);
these polygons serve the rest: prototypes of instances and PointInstancers, stretched spheres."""

from __future__ import annotations

import math

import numpy as np

SPHERE_SEGMENTS = 48        # around the axis; half as many rings: a silhouette within 0.2% of the radius
SPHERE_RINGS = 24


def sphere(radius: float, segments: int = SPHERE_SEGMENTS,
           rings: int = SPHERE_RINGS) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(points, faceVertexCounts, faceVertexIndices, vertex normals) of a UV sphere about +Y: triangles
    at the poles, quads between."""
    theta = np.linspace(0.0, math.pi, rings + 1)[1:-1]                   # the rings between the poles
    phi = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.cos(t), -np.sin(t) * np.sin(p)], axis=-1).reshape(-1, 3)
    unit = np.concatenate([[[0.0, 1.0, 0.0]], ring, [[0.0, -1.0, 0.0]]])
    top, bottom = 0, len(unit) - 1
    at = lambda r, s: 1 + r * segments + s % segments         # noqa: E731 - the point of ring r, segment s
    counts, indices = [], []
    for s in range(segments):
        counts.append(3)
        indices += [top, at(0, s), at(0, s + 1)]
    for r in range(rings - 2):
        for s in range(segments):
            counts.append(4)
            indices += [at(r, s), at(r + 1, s), at(r + 1, s + 1), at(r, s + 1)]
    for s in range(segments):
        counts.append(3)
        indices += [bottom, at(rings - 2, s + 1), at(rings - 2, s)]
    return unit * radius, np.array(counts, np.int64), np.array(indices, np.int64), unit


def cube(size: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points, faceVertexCounts, faceVertexIndices) of a cube of edge ``size`` centred on the origin."""
    h = size / 2.0
    points = np.array([(x, y, z) for x in (-h, h) for y in (-h, h) for z in (-h, h)], np.float64)
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return points, np.full(6, 4, np.int64), np.array([i for f in faces for i in f], np.int64)
