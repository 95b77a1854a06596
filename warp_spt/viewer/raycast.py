"""The first surface along one ray, in numpy on the host: where a double-click points.

Why not a 1x1 render: a render returns radiance, not a distance, and a depth-like probe would need
engine internals. One ray against every triangle is a vectorised Moller-Trumbore test, about 10 ms
per 100,000 triangles here, which is fast enough for a click and exact to float64.
"""

from __future__ import annotations

import numpy as np

CHUNK = 1 << 16      # triangles tested at once: bounds the temporary arrays to a few MB


def triangles_hit(origin: np.ndarray, direction: np.ndarray, v0: np.ndarray, v1: np.ndarray,
                  v2: np.ndarray) -> float:
    """Nearest distance t > 0 along the ray to the triangles (v0, v1, v2: (N, 3)), or inf."""
    e1, e2 = v1 - v0, v2 - v0
    p = np.cross(direction, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-12 * np.maximum(np.einsum("ij,ij->i", e1, e1), 1e-300)
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = origin - v0
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ direction) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hit = ok & (u >= 0.0) & (v >= 0.0) & (u + v <= 1.0) & (t > 1e-9)
    return float(t[hit].min()) if hit.any() else np.inf


def spheres_hit(origin: np.ndarray, direction: np.ndarray, spheres: np.ndarray) -> float:
    """Nearest distance t > 0 to the spheres ((S, 4): centre, radius), or inf; seen from inside,
    the far side counts."""
    if len(spheres) == 0:
        return np.inf
    c = spheres[:, :3].astype(np.float64) - origin
    r = spheres[:, 3].astype(np.float64)
    b = c @ direction
    disc = b * b - (np.einsum("ij,ij->i", c, c) - r * r)
    root = np.sqrt(np.maximum(disc, 0.0))
    near, far = b - root, b + root
    t = np.where(near > 1e-9, near, far)
    hit = (disc >= 0.0) & (t > 1e-9)
    return float(t[hit].min()) if hit.any() else np.inf


def first_hit(scene, origin, direction) -> float | None:
    """Distance along the unit ``direction`` from ``origin`` to the nearest surface of ``scene``
    (a :class:`warp_spt.Scene`), or None when the ray hits nothing."""
    o = np.asarray(origin, dtype=np.float64)
    d = np.asarray(direction, dtype=np.float64)
    best = spheres_hit(o, d, np.asarray(scene.spheres))
    for mesh in scene.meshes:
        pos = np.asarray(mesh.positions, dtype=np.float64)
        idx = np.asarray(mesh.indices)
        for oo, dd in _placed_rays(mesh, o, d):
            for lo in range(0, len(idx), CHUNK):
                tri = idx[lo:lo + CHUNK]
                best = min(best, triangles_hit(oo, dd, pos[tri[:, 0]], pos[tri[:, 1]], pos[tri[:, 2]]))
    return None if not np.isfinite(best) else best


def _placed_rays(mesh, o: np.ndarray, d: np.ndarray):
    """The ray in the object space of each placement of an instanced mesh (``MeshData.transforms``),
    or the ray itself: the direction is mapped, not renormalised, so a hit's parameter t is the
    world distance along the unit ``d``."""
    if getattr(mesh, "transforms", None) is None:
        yield o, d
        return
    for x in np.asarray(mesh.transforms, dtype=np.float64):
        try:
            inv = np.linalg.inv(x)
        except np.linalg.LinAlgError:      # a placement scaled to nothing is not drawn
            continue
        yield inv[:3, :3] @ o + inv[:3, 3], inv[:3, :3] @ d
