"""Smooth normals by angle for meshes that come without any (``vn``), on the host, vectorised.

A mesh exported without normals is faceted at any sample count. :func:`smooth_normals` gives each
face corner the mean of the normals of the faces around its vertex that make at most ``angle``
degrees with the corner's own face (as Blender's auto smooth does): curved surfaces shade smooth,
creases sharper than ``angle`` (a cube's edges at the default 30) stay sharp. Each face's normal is
weighted by its corner angle at the vertex, so the result does not depend on how a surface is cut
into triangles. Vertices are welded by position first, so a surface split at a UV seam (the same
point written twice) is smooth across it.
"""

from __future__ import annotations

import numpy as np

DEFAULT_SMOOTH_ANGLE = 30.0     # degrees, as Blender's auto smooth
MAX_SMOOTH_ANGLE = 180.0
# Corner pairs (corner, neighbouring face corner) formed at once: bounds the memory to a few
# hundred MB whatever the mesh (a cone's apex of n faces alone makes n^2 pairs).
PAIR_CHUNK = 4_000_000


def check_smooth_angle(angle: float | None) -> float | None:
    """``angle`` as a float in [0, 180] degrees (0 or None: off); ValueError otherwise."""
    if angle is None:
        return None
    if isinstance(angle, bool) or not isinstance(angle, (int, float, np.integer, np.floating)):
        raise TypeError(f"smooth_angle must be a number of degrees or None, got {angle!r}")
    a = float(angle)
    if not 0.0 <= a <= MAX_SMOOTH_ANGLE:      # NaN fails too
        raise ValueError(f"smooth_angle must lie in [0, {MAX_SMOOTH_ANGLE:g}] degrees (0: off), got {angle!r}")
    return a or None


def smooth_normals(positions: np.ndarray, faces: np.ndarray, angle: float = DEFAULT_SMOOTH_ANGLE) -> np.ndarray:
    """(F, 3, 3) float32 unit normals per face corner of the triangles ``faces`` (F, 3) over
    ``positions`` (V, 3): at each corner, the corner-angle-weighted mean of the unit normals of the
    faces that share its vertex (by position) and make at most ``angle`` degrees with its own face.
    A corner whose mean vanishes keeps its face's normal."""
    p = np.asarray(positions, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if not len(f):
        return np.zeros((0, 3, 3), np.float32)
    tri = p[f]                                                     # (F, 3, 3)
    n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    length = np.linalg.norm(n, axis=1)
    n = n / np.where(length > 0, length, 1.0)[:, None]             # zero-area faces: a zero normal
    weight = _corner_angles(tri)                                   # (F, 3)
    vert = _weld(p)[f].reshape(-1)                                 # corner c = 3 * face + k: its vertex
    corner_n = np.repeat(n, 3, axis=0)                             # each corner's face normal
    # Most vertices are smooth: all their faces lie within a cone of half the angle around their
    # mean normal, so every two of them are within the angle and each corner takes the vertex's
    # whole sum. Only the others (creases, corners of a box) pair their faces one by one.
    wn = corner_n * weight.reshape(-1, 1)
    count = int(vert.max()) + 1
    total = np.stack([np.bincount(vert, weights=wn[:, k], minlength=count) for k in range(3)], axis=1)
    size = np.linalg.norm(total, axis=1)
    mean = total / np.where(size > 1e-300, size, 1.0)[:, None]
    cone = np.full(count, np.inf)
    np.minimum.at(cone, vert, np.einsum("ij,ij->i", corner_n, mean[vert]))
    smooth = (size > 1e-12) & (cone >= np.cos(min(np.radians(angle) / 2.0, np.pi / 2)) + 1e-12)
    out = np.where(smooth[vert][:, None], mean[vert], corner_n)
    rough = np.flatnonzero(~smooth[vert])
    if len(rough):
        acc = np.zeros((len(vert), 3))
        _pair_up(acc, rough[np.argsort(vert[rough], kind="stable")], vert, n, weight,
                 np.cos(np.radians(angle)) - 1e-12)
        norm = np.linalg.norm(acc[rough], axis=1)
        ok = norm > 1e-12
        out[rough[ok]] = acc[rough[ok]] / norm[ok, None]
    return out.reshape(-1, 3, 3).astype(np.float32)


def _weld(p: np.ndarray) -> np.ndarray:
    """Per point, the index of its position among the distinct positions (exact equality)."""
    order = np.lexsort(p.T[::-1])
    sp = p[order]
    new = np.r_[True, np.any(sp[1:] != sp[:-1], axis=1)]
    ids = np.empty(len(p), dtype=np.int64)
    ids[order] = np.cumsum(new) - 1
    return ids


def _pair_up(acc: np.ndarray, order: np.ndarray, vert: np.ndarray, n: np.ndarray, weight: np.ndarray,
             cos_limit: float) -> None:
    """For the corners ``order`` (sorted by vertex), add to each the weighted normals of the faces of
    its vertex within the angle of its own face; vertex groups in chunks of PAIR_CHUNK pairs."""
    v = vert[order]
    starts = np.flatnonzero(np.r_[True, v[1:] != v[:-1]])
    counts = np.diff(np.r_[starts, len(order)])
    pairs = np.cumsum(counts.astype(np.int64) ** 2)               # each corner pairs with its group's
    g0 = 0
    while g0 < len(counts):
        if counts[g0] ** 2 > PAIR_CHUNK:                            # one huge fan: its corners in slices
            fan = order[starts[g0]:starts[g0] + counts[g0]]
            step = max(1, PAIR_CHUNK // len(fan))
            for i in range(0, len(fan), step):
                a = fan[i:i + step]
                _add(acc, np.repeat(a, len(fan)), np.tile(fan, len(a)), n, weight, cos_limit)
            g0 += 1
            continue
        done = pairs[g0 - 1] if g0 else 0
        g1 = max(g0 + 1, int(np.searchsorted(pairs, done + PAIR_CHUNK, "right")))
        while g1 > g0 + 1 and counts[g1 - 1] ** 2 > PAIR_CHUNK:
            g1 -= 1
        c, first = counts[g0:g1], starts[g0:g1]
        reps = np.repeat(c, c)                                       # per corner: its group's size
        at = np.repeat(first, c) + np.arange(len(reps)) - np.repeat(np.cumsum(c) - c, c)
        within = np.arange(int(reps.sum())) - np.repeat(np.cumsum(reps) - reps, reps)
        _add(acc, np.repeat(order[at], reps), order[np.repeat(np.repeat(first, c), reps) + within],
             n, weight, cos_limit)
        g0 = g1


def _add(acc: np.ndarray, a: np.ndarray, b: np.ndarray, n: np.ndarray, weight: np.ndarray,
         cos_limit: float) -> None:
    """Add to corner ``a``'s sum the weighted normal of corner ``b``'s face (same vertex) where the
    two faces make at most the angle."""
    fa, fb = a // 3, b // 3
    close = np.einsum("ij,ij->i", n[fa], n[fb]) >= cos_limit
    a, fb, kb = a[close], fb[close], (b % 3)[close]
    w = weight[fb, kb]
    for k in range(3):
        acc[:, k] += np.bincount(a, weights=n[fb, k] * w, minlength=len(acc))


def _corner_angles(tri: np.ndarray) -> np.ndarray:
    """(F, 3) interior angle of each triangle at each corner, radians (0 for a degenerate one)."""
    out = np.zeros(tri.shape[:2])
    for k in range(3):
        e1 = tri[:, (k + 1) % 3] - tri[:, k]
        e2 = tri[:, (k + 2) % 3] - tri[:, k]
        out[:, k] = np.arctan2(np.linalg.norm(np.cross(e1, e2), axis=1), np.einsum("ij,ij->i", e1, e2))
    return out
