"""The medium kinds, one line each (their index is ``scene.media.MEDIUM_KINDS``'s)."""

from warp_spt.media import grid, homogeneous

KINDS = {homogeneous.NAME: homogeneous, grid.NAME: grid}
