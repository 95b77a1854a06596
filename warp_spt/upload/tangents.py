"""Per-corner tangent frames from a mesh's uv, for tangent-space normal maps and anisotropy.

Normal maps baked by Blender, Substance or xNormal are in MikkTSpace's frame: per corner, the
direction in which u grows (the tangent) and the sign of the bitangent, accumulated over the faces
that share a vertex (with the same position, uv and normal) weighted by the face's angle at the
vertex, then made orthogonal to the normal. This is that scheme, vectorised in numpy (it agrees with
MikkTSpace wherever the uv layout has no degenerate or mirrored-within-a-face triangles, the cases
where MikkTSpace's own splitting rules decide). The kernel interpolates the corners' tangents over the
face and makes the result orthogonal to the shading normal again (``accel.surface``).
"""

from __future__ import annotations

import numpy as np


def corner_tangents(positions: np.ndarray, indices: np.ndarray, corner_uv: np.ndarray,
                    corner_normal: np.ndarray) -> np.ndarray:
    """(F, 3, 4) float32: per corner a unit tangent (xyz, orthogonal to that corner's normal) and the
    bitangent's sign (w, +1 or -1: bitangent = w * cross(normal, tangent)). Faces whose uv are
    degenerate get a tangent from the normal alone (any direction in the plane, sign +1)."""
    idx = np.asarray(indices, dtype=np.int64)
    p = np.asarray(positions, dtype=np.float64)[idx]                   # (F, 3, 3)
    uv = np.asarray(corner_uv, dtype=np.float64)                       # (F, 3, 2)
    n = np.asarray(corner_normal, dtype=np.float64)                    # (F, 3, 3)
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    d1, d2 = uv[:, 1] - uv[:, 0], uv[:, 2] - uv[:, 0]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    ok = np.abs(det) > 1e-20
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)[:, None]
    t_face = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * inv                # dp/du
    b_face = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * inv                # dp/dv
    # angle of the face at each corner: MikkTSpace's weight
    ang = np.empty(idx.shape)
    for k in range(3):
        a = p[:, (k + 1) % 3] - p[:, k]
        b = p[:, (k + 2) % 3] - p[:, k]
        den = np.linalg.norm(a, axis=1) * np.linalg.norm(b, axis=1)
        ang[:, k] = np.arccos(np.clip(np.einsum("ij,ij->i", a, b) / np.maximum(den, 1e-300), -1.0, 1.0))
    ang *= ok[:, None]
    # vertices: corners with the same position index, uv and normal share one accumulated frame
    key = np.concatenate([idx.reshape(-1, 1).astype(np.float64), uv.reshape(-1, 2), n.reshape(-1, 3)], axis=1)
    _, vert = np.unique(key, axis=0, return_inverse=True)
    vert = vert.reshape(-1)
    nv = int(vert.max()) + 1 if len(vert) else 0
    t_acc = np.zeros((nv, 3))
    b_acc = np.zeros((nv, 3))
    w = ang.reshape(-1, 1)
    np.add.at(t_acc, vert, np.repeat(t_face, 3, axis=0) * w)
    np.add.at(b_acc, vert, np.repeat(b_face, 3, axis=0) * w)
    t = t_acc[vert]
    b = b_acc[vert]
    nn = n.reshape(-1, 3)
    t = t - nn * np.einsum("ij,ij->i", t, nn)[:, None]               # Gram-Schmidt against the normal
    length = np.linalg.norm(t, axis=1)
    fallback = _any_tangent(nn)
    good = length > 1e-12
    t = np.where(good[:, None], t / np.maximum(length, 1e-300)[:, None], fallback)
    sign = np.where(np.einsum("ij,ij->i", np.cross(nn, t), b) < 0.0, -1.0, 1.0)
    sign = np.where(good, sign, 1.0)
    return np.concatenate([t, sign[:, None]], axis=1).reshape(-1, 3, 4).astype(np.float32)


def _any_tangent(n: np.ndarray) -> np.ndarray:
    """A unit vector orthogonal to each row of ``n`` (Duff et al. 2017's branchless basis)."""
    s = np.where(n[:, 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (s + n[:, 2])
    b = n[:, 0] * n[:, 1] * a
    return np.stack([1.0 + s * n[:, 0] * n[:, 0] * a, s * b, -s * n[:, 0]], axis=1)
