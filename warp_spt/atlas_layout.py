"""Where each texture goes in the one texture atlas: shelf packing, and the texel budget (no Warp).

The kernels sample a single 2-D float32 atlas through a tile table (x0, y0, w, h); textures are
stored unrotated. Shelves are filled tallest first, left to right. The shelf width is chosen among
a few candidates (the widest texture, and multiples of the square root of the total area) to
minimise the atlas's area, which then stays within a small factor of the textures' total area.

The one case no unrotated packing can help: a very wide texture and a very tall one need an atlas
at least (largest width) x (largest height). :func:`atlas_problem` reports such an atlas, and any
atlas beyond the budget, before a texel is allocated, naming the textures.
"""

from __future__ import annotations

import math

import numpy as np

# At most this many texels in the atlas: 2**26 = 67,108,864 (one 8192 x 8192 texture), 768 MiB as
# float32 RGB. The atlas exists up to three times while a scene is uploaded (decoded images, the
# packed atlas, Warp's copy), so this keeps a scene's textures within about 2.3 GiB.
TEXEL_BUDGET = 1 << 26
BYTES_PER_TEXEL = 12


def _shelves(sizes: list[tuple[int, int]], width: int) -> tuple[np.ndarray, int, int]:
    tiles = np.zeros((len(sizes), 4), dtype=np.int64)
    x = y = shelf_h = used_w = 0
    for k in sorted(range(len(sizes)), key=lambda i: (-sizes[i][0], -sizes[i][1], i)):
        h, w = sizes[k]
        if x + w > width and x > 0:
            x, y, shelf_h = 0, y + shelf_h, 0
        tiles[k] = (x, y, w, h)
        x += w
        used_w = max(used_w, x)
        shelf_h = max(shelf_h, h)
    return tiles, used_w, y + shelf_h


def shelf_layout(sizes: list[tuple[int, int]]) -> tuple[np.ndarray, int, int]:
    """Tiles (T, 4) int64 rows (x0, y0, w, h), atlas width and height for (h, w) texture sizes."""
    widest = max(w for _, w in sizes)
    side = math.isqrt(max(sum(h * w for h, w in sizes) - 1, 0)) + 1
    candidates = {widest} | {max(widest, int(side * f)) for f in (0.5, 0.71, 1.0, 1.41, 2.0)}
    best = None
    for width in sorted(candidates):
        tiles, w, h = _shelves(sizes, width)
        if best is None or w * h < best[1] * best[2]:
            best = (tiles, w, h)
    return best


def atlas_problem(sizes: list[tuple[int, int]], names: list[str], budget: int = TEXEL_BUDGET) -> str | None:
    """Why textures of these (h, w) sizes cannot share an atlas within ``budget`` texels, or None."""
    if not sizes:
        return None
    _, width, height = shelf_layout(sizes)
    if width * height <= budget:
        return None
    listed = ", ".join(f"{n} ({w}x{h})" for n, (h, w) in zip(names, sizes))
    total = sum(h * w for h, w in sizes)
    why = ""
    if width * height > 4 * total:
        why = (" (textures are stored unrotated, so the widest and the tallest texture together need "
               f"{max(w for _, w in sizes)}x{max(h for h, _ in sizes)} texels)")
    return (f"the texture atlas would need {width}x{height} = {width * height:,} texels "
            f"({width * height * BYTES_PER_TEXEL / 2**30:.1f} GiB), more than the budget of {budget:,} texels"
            f"{why}; textures: {listed}")
