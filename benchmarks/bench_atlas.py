"""Texture atlas memory: the flat atlas against the least any 2-D atlas of unrotated tiles needs.

    python benchmarks/bench_atlas.py

Prints, per texture set, the texels the flat atlas allocates (``pack_atlas``: every texture its own
tile of rows, one after another), the sum of the textures' areas, and the lower bound of a 2-D
atlas of unrotated tiles, max(sum of areas, widest width x tallest height), which is what the
previous shelf packing could at best reach. Sizes are array sizes (bytes of float32 RGB), not times.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from warp_spt.device.textures import pack_atlas  # noqa: E402


def row(label: str, sizes: list[tuple[int, int]]) -> None:
    imgs = [np.broadcast_to(np.float32(0.5), (h, w, 3)) for h, w in sizes]     # no texel memory until packed
    atlas = pack_atlas(imgs)
    area = sum(h * w for h, w in sizes)
    bound_2d = max(area, max(w for _, w in sizes) * max(h for h, _ in sizes))
    print(f"{label:<34} flat {len(atlas.texels):>12,} texels ({atlas.texels.nbytes / 2**20:9.2f} MiB)   "
          f"sum of areas {area:>12,}   2-D unrotated >= {bound_2d:>14,} ({bound_2d * 12 / 2**30:7.2f} GiB)")
    assert len(atlas.texels) == area


def main() -> None:
    row("1x20000 + 20000x1", [(20000, 1), (1, 20000)])
    row("1x40000 + 40000x1", [(40000, 1), (1, 40000)])
    row("seed demo-like: 1024^2 + 512^2 x 3", [(1024, 1024)] + [(512, 512)] * 3)
    rng = np.random.default_rng(5)
    worst = 0.0
    for _ in range(200):
        sizes = [(int(rng.integers(1, 300)), int(rng.integers(1, 300))) for _ in range(int(rng.integers(1, 12)))]
        atlas = pack_atlas([np.broadcast_to(np.float32(0.0), (h, w, 3)) for h, w in sizes])
        worst = max(worst, len(atlas.texels) / sum(h * w for h, w in sizes))
    print(f"200 random sets of 1-11 textures up to 300x300: flat atlas / sum of areas, worst {worst:.3f}")


if __name__ == "__main__":
    main()
