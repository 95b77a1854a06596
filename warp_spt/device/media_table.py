"""The media table kernels read (:class:`Media`, nested in ``Geometry``) and its upload.

Row k of every array is medium k: the scene's fog first (when it has one), then each distinct
interior medium. ``mat_medium[row]`` is the interior medium of material row ``row`` (-1: its
surface is no medium boundary: crossing it keeps the ray's medium), ``outer`` the medium outside
every closed mesh (the fog, or -1), which is also where camera rays start. A scene without media
uploads one-element dummies and ``count`` 0: its kernels compile no media code
(``Features.media``, declared by ``media.registry``, is empty) and never read them. The upload is
``media.upload``.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_spt.scene.media import Medium, interface_rows


@wp.struct
class Media:
    kind: wp.array(dtype=wp.int32)        # index into scene.families.MEDIUM_KINDS
    sigma_a: wp.array(dtype=wp.vec3)
    sigma_s: wp.array(dtype=wp.vec3)
    g: wp.array(dtype=wp.float32)
    emission: wp.array(dtype=wp.vec3)
    majorant: wp.array(dtype=wp.vec3)     # per channel, >= sigma_a + sigma_s
    mat_medium: wp.array(dtype=wp.int32)
    mat_interface: wp.array(dtype=wp.int32)    # 1: a pass-through boundary (scene.media.interface_rows)
    outer: int
    count: int
    # grids (media.grid; dummies elsewhere): the wp.Volume, scene points to its index space,
    # and the majorant grid: its lower corner and cell size (index space), resolution, first value
    volume: wp.array(dtype=wp.uint64)
    to_grid: wp.array(dtype=wp.mat44)
    mg_lo: wp.array(dtype=wp.vec3)
    mg_cell: wp.array(dtype=wp.vec3)
    mg_res: wp.array(dtype=wp.vec3i)
    mg_offset: wp.array(dtype=wp.int32)
    mg_values: wp.array(dtype=wp.float32)      # the largest density per cell, x fastest


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
        # grids by identity (their data is no part of equality), homogeneous media by value
        same = [i for i, x in enumerate(media) if x is medium or (medium.density is None and x == medium)]
        if not same:
            media.append(medium)
            same = [len(media) - 1]
        rows[names[name]] = same[0]
    return media, outer, rows


def interface_media(scene) -> set[int]:
    """The media rows behind pass-through (``index_matched``) boundaries."""
    _, _, rows = media_of(scene)
    return {int(r) for r in rows[interface_rows(scene.materials) & (rows >= 0)]}
