"""Where each texture goes in the texture atlas, and the texel budget (no Warp).

The atlas is ONE flat array of texels. Each texture is its own tile, stored row by row (row 0 the
image's top row) right after the previous one, and described by a row (offset, w, h, stride) of the
tile table: texel (row, col) of the texture is element ``offset + row * stride + col``. The atlas
therefore holds exactly the sum of the textures' areas whatever their shapes. (A 2-D atlas of
unrotated tiles needs at least the largest width x the largest height: a 1 x 20000 and a 20000 x 1
texture took 20000^2 texels instead of 40000.)

:func:`atlas_problem` reports textures beyond the budget before a texel is allocated, naming them.
"""

from __future__ import annotations

import numpy as np

# At most this many texels in the atlas: 2**26 = 67,108,864 (one 8192 x 8192 texture), 768 MiB as
# float32 RGB. The texels exist up to three times while a scene is uploaded (decoded images, the
# packed atlas, Warp's copy), so this keeps a scene's textures within about 2.3 GiB.
TEXEL_BUDGET = 1 << 26
BYTES_PER_TEXEL = 12


def flat_layout(sizes: list[tuple[int, int]]) -> tuple[np.ndarray, int]:
    """Tiles (T, 4) int64 rows (offset, w, h, stride) for (h, w) texture sizes, and the total texels."""
    tiles = np.zeros((len(sizes), 4), dtype=np.int64)
    offset = 0
    for k, (h, w) in enumerate(sizes):
        tiles[k] = (offset, w, h, w)
        offset += h * w
    return tiles, offset


def atlas_problem(sizes: list[tuple[int, int]], names: list[str], budget: int = TEXEL_BUDGET) -> str | None:
    """Why textures of these (h, w) sizes cannot share an atlas within ``budget`` texels, or None."""
    total = sum(h * w for h, w in sizes)
    if total <= budget:
        return None
    listed = ", ".join(f"{n} ({w}x{h})" for n, (h, w) in zip(names, sizes))
    return (f"the textures hold {total:,} texels together ({total * BYTES_PER_TEXEL / 2**30:.1f} GiB), "
            f"more than the budget of {budget:,} texels; textures: {listed}")
