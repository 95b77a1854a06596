"""The media table's upload: host media to a :class:`Media` struct (grids read and checked here)."""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_spt.media.grid import grid_index_transform, load_grid, majorant_grid
from warp_spt.device.media_table import Media, media_of
from warp_spt.scene.media import MEDIUM_KINDS, interface_rows


def upload_media(scene, device: str) -> tuple[Media, list]:
    """(the scene's media as a :class:`Media` struct on ``device``, the wp.Volume objects it refers
    to: keep them alive as long as the struct)."""
    media, outer, rows = media_of(scene)
    n = max(len(media), 1)
    cols = {k: np.zeros((n, 3), np.float32) for k in ("sigma_a", "sigma_s", "emission", "majorant",
                                                       "mg_lo", "mg_cell")}
    g = np.zeros(n, np.float32)
    kind = np.zeros(n, np.int32)
    ids = np.zeros(n, np.uint64)
    to_grid = np.tile(np.eye(4, dtype=np.float32), (n, 1, 1))
    res = np.ones((n, 3), np.int32)
    offset = np.zeros(n, np.int32)
    values = [np.zeros(1, np.float32)]
    volumes = []
    for i, m in enumerate(media):
        scale = m.density_scale if m.density is not None else 1.0
        cols["sigma_a"][i] = np.asarray(m.sigma_a) * scale
        cols["sigma_s"][i] = np.asarray(m.sigma_s) * scale
        cols["emission"][i] = m.emission
        cols["majorant"][i] = np.asarray(m.sigma_t) * scale * m.majorant
        g[i] = m.g
        kind[i] = MEDIUM_KINDS.index(m.kind)
        if m.density is not None:
            vol, ijk, vals = load_grid(m, device, f"medium {i}")
            volumes.append(vol)
            ids[i] = vol.id
            to_grid[i] = grid_index_transform(vol, m)
            lo, cs, r, mv = majorant_grid(ijk, vals, m.majorant_cells)
            cols["mg_lo"][i], cols["mg_cell"][i], res[i] = lo, cs, r
            offset[i] = sum(len(v) for v in values)
            values.append(mv)
    s = Media()
    s.kind = wp.array(kind, dtype=wp.int32, device=device)
    for name in ("sigma_a", "sigma_s", "emission", "majorant", "mg_lo", "mg_cell"):
        setattr(s, name, wp.array(cols[name], dtype=wp.vec3, device=device))
    s.g = wp.array(g, dtype=wp.float32, device=device)
    s.mat_medium = wp.array(rows if len(rows) else np.full(1, -1, np.int32), dtype=wp.int32, device=device)
    passes = (interface_rows(scene.materials) & (rows >= 0)).astype(np.int32)
    s.mat_interface = wp.array(passes if len(passes) else np.zeros(1, np.int32), dtype=wp.int32, device=device)
    s.outer = outer
    s.count = len(media)
    s.volume = wp.array(ids, dtype=wp.uint64, device=device)
    s.to_grid = wp.array(to_grid, dtype=wp.mat44, device=device)
    s.mg_res = wp.array(res, dtype=wp.vec3i, device=device)
    s.mg_offset = wp.array(offset, dtype=wp.int32, device=device)
    s.mg_values = wp.array(np.concatenate(values).astype(np.float32), dtype=wp.float32, device=device)
    return s, volumes
