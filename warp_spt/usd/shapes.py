"""UsdGeom's implicit shapes as polygons: a ``Sphere`` (``radius``), a ``Cube`` (``size``) and the
shapes about an ``axis`` (``Capsule``, ``Cylinder``, ``Cone``: ``radius``, ``height``), the ones Warp's
``warp.render.UsdRenderer`` writes for bodies and particles, in the prim's own space and
counter-clockwise from outside as a mesh's faces are. A sphere placed by a similarity (no instances,
no non-uniform scale) is drawn as the renderer's exact sphere instead (``stage.py``); these polygons
serve the rest: prototypes of instances and PointInstancers, stretched spheres, the other shapes.
The shapes about an axis are profiles turned about it (``lathe``), with no normals of their own: the
loader's smoothing by angle keeps a cylinder's rims sharp and its side round."""

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


def lathe(profile: list[tuple[float, float]], axis: str = "Z",
          segments: int = SPHERE_SEGMENTS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(points, faceVertexCounts, faceVertexIndices) of ``profile``, (radius, height) pairs from the
    bottom up, turned about ``axis`` (X, Y or Z); a radius of 0 is one point (a pole or an apex)."""
    phi = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
    points, rings = [], []
    for r, z in profile:
        start = len(points)
        if r > 0:
            points += [(r * math.cos(p), r * math.sin(p), z) for p in phi]
            rings.append([start + k for k in range(segments)])
        else:
            points.append((0.0, 0.0, z))
            rings.append([start] * segments)
    counts, indices = [], []
    for lo, hi in zip(rings[:-1], rings[1:]):
        for k in range(segments):
            quad = [lo[k], lo[(k + 1) % segments], hi[(k + 1) % segments], hi[k]]
            face = [v for j, v in enumerate(quad) if v != quad[j - 1]]          # a pole's quad is a triangle
            if len(face) >= 3:
                counts.append(len(face))
                indices += face
    p = np.array(points, np.float64)
    # a cyclic turn of the coordinates (no mirror) takes the lathe's z to the axis
    p = {"X": p[:, [2, 0, 1]], "Y": p[:, [1, 2, 0]]}.get(str(axis).upper(), p)
    return p, np.array(counts, np.int64), np.array(indices, np.int64)


def capsule(radius: float, height: float, axis: str = "Z") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A cylinder of ``height`` (the spine, without the caps) with a half sphere at each end."""
    a = np.linspace(-0.5 * math.pi, 0.5 * math.pi, SPHERE_RINGS + 1)
    below = [(radius * math.cos(t), -height / 2 + radius * math.sin(t)) for t in a[: SPHERE_RINGS // 2 + 1]]
    above = [(radius * math.cos(t), height / 2 + radius * math.sin(t)) for t in a[SPHERE_RINGS // 2:]]
    return lathe([(0.0 if k in (0, len(below) + len(above) - 1) else r, z)
                  for k, (r, z) in enumerate(below + above)], axis)


def cylinder(radius: float, height: float, axis: str = "Z") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    h = height / 2
    return lathe([(0.0, -h), (radius, -h), (radius, h), (0.0, h)], axis)


def cone(radius: float, height: float, axis: str = "Z") -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The base of ``radius`` at -height/2 along the axis, the apex at +height/2."""
    h = height / 2
    return lathe([(0.0, -h), (radius, -h), (0.0, h)], axis)
