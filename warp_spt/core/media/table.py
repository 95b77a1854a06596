"""The media table kernels read (:class:`Media`, nested in ``Geometry``) and its upload.

Row k of every array is medium k: the scene's fog first (when it has one), then each distinct
interior medium. ``mat_medium[row]`` is the interior medium of material row ``row`` (-1: its
surface is no medium boundary: crossing it keeps the ray's medium), ``outer`` the medium outside
every closed mesh (the fog, or -1), which is also where camera rays start. A scene without media
uploads one-element dummies and ``count`` 0: its kernels compile no media code
(``Features.media`` is empty) and never read them.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_spt.scene.media import MEDIUM_KINDS, Medium


@wp.struct
class Media:
    kind: wp.array(dtype=wp.int32)        # index into MEDIUM_KINDS
    sigma_a: wp.array(dtype=wp.vec3)
    sigma_s: wp.array(dtype=wp.vec3)
    g: wp.array(dtype=wp.float32)
    emission: wp.array(dtype=wp.vec3)
    majorant: wp.array(dtype=wp.vec3)     # per channel, >= sigma_a + sigma_s
    mat_medium: wp.array(dtype=wp.int32)
    outer: int
    count: int


def media_of(scene) -> tuple[list[Medium], int, np.ndarray]:
    """(media in row order, the outer medium's row or -1, per material row its medium or -1)."""
    media: list[Medium] = []
    outer = -1
    fog = getattr(scene, "fog", None)
    if fog is not None:
        media.append(fog.check("fog"))
        outer = 0
    rows = np.full(len(scene.materials), -1, np.int32)
    names = {n: i for i, n in enumerate(scene.materials.names)}
    for name, medium in (getattr(scene, "interiors", None) or {}).items():
        if name not in names:
            raise ValueError(f"interior medium of material {name!r}: the scene has no such material")
        medium.check(f"interior medium of material {name!r}")
        if medium not in media:
            media.append(medium)
        rows[names[name]] = media.index(medium)
    return media, outer, rows


def media_features(scene) -> tuple[str, ...]:
    """``Features.media``: the medium kinds the scene uses (sorted), and "emission" where some
    medium emits; () for a scene without media."""
    media, _, _ = media_of(scene)
    if not media:
        return ()
    kinds = sorted({m.kind for m in media})
    if any(max(m.emission) > 0 and max(m.sigma_a) > 0 for m in media):
        kinds.append("emission")
    return tuple(kinds)


def upload_media(scene, device: str) -> Media:
    """The scene's media as a :class:`Media` struct on ``device``."""
    media, outer, rows = media_of(scene)
    s = Media()
    n = max(len(media), 1)

    def col(fn, width):
        out = np.zeros((n, width) if width else n, np.float32)
        for i, m in enumerate(media):
            out[i] = fn(m)
        return out

    s.kind = wp.array(np.asarray([MEDIUM_KINDS.index(m.kind) for m in media] or [0], np.int32), dtype=wp.int32,
                      device=device)
    s.sigma_a = wp.array(col(lambda m: m.sigma_a, 3), dtype=wp.vec3, device=device)
    s.sigma_s = wp.array(col(lambda m: m.sigma_s, 3), dtype=wp.vec3, device=device)
    s.g = wp.array(col(lambda m: m.g, 0), dtype=wp.float32, device=device)
    s.emission = wp.array(col(lambda m: m.emission, 3), dtype=wp.vec3, device=device)
    s.majorant = wp.array(col(lambda m: np.asarray(m.sigma_t) * m.majorant, 3), dtype=wp.vec3, device=device)
    s.mat_medium = wp.array(rows if len(rows) else np.full(1, -1, np.int32), dtype=wp.int32, device=device)
    s.outer = outer
    s.count = len(media)
    return s
