"""Write a procedural smoke plume as a NanoVDB grid, and three small media scenes to render.

    python scripts/make_smoke.py OUT_DIR [--res 64]

OUT_DIR receives (Z up, the seed's convention, so ``-cam`` places the camera):

* ``smoke.nvdb``: a rising, curling plume (Gaussian puffs along a helix, thinned by value noise),
  ``res`` voxels a side over [-1, 1] x [-1, 1] x [0, 2] (voxel size 2/res), float densities in [0, 1];
* ``smoke.obj``/``smoke.mtl``: the plume's box (an index-matched boundary whose interior is the
  grid, ``medium_density smoke.nvdb``), a floor and an area light;
* ``shafts.obj``/``shafts.mtl``: a floor and a slatted roof under a closed attic with a bright panel
  inside, whose light leaves through the gaps alone, for ``--fog``;
* ``liquid.obj``/``liquid.mtl``: a glass cylinder whose interior absorbs green and blue (a red
  drink: ``medium_sigma_a``), on a floor under a light.

The grid is deterministic (a fixed seed): the same bytes every run. docs/volumes.md gives the
commands that render each scene.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing


def value_noise(shape: tuple[int, int, int], cells: int, rng: np.random.Generator) -> np.ndarray:
    """Smooth noise in [0, 1]: random values on a coarse lattice, interpolated (smoothstep) up."""
    lattice = rng.uniform(0.0, 1.0, (cells + 1,) * 3)
    axes = [np.linspace(0.0, cells, n, endpoint=False) for n in shape]
    idx = [np.minimum(a.astype(int), cells - 1) for a in axes]
    frac = [a - i for a, i in zip(axes, idx)]
    w = [f * f * (3.0 - 2.0 * f) for f in frac]
    out = np.zeros(shape)
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                v = lattice[np.ix_(idx[0] + dx, idx[1] + dy, idx[2] + dz)]
                out += (v * (w[0] if dx else 1 - w[0])[:, None, None] * (w[1] if dy else 1 - w[1])[None, :, None]
                        * (w[2] if dz else 1 - w[2])[None, None, :])
    return out


def plume(res: int = 64, seed: int = 35) -> np.ndarray:
    """(res, res, res) float32 densities in [0, 1] over [-1, 1]^2 x [0, 2]: x, y, z index order."""
    rng = np.random.default_rng(seed)
    c = (np.arange(res) + 0.5) / res
    x, y, z = np.meshgrid(c * 2 - 1, c * 2 - 1, c * 2, indexing="ij")
    rho = np.zeros((res, res, res))
    for k in range(24):                       # puffs up a helix, widening as they rise
        h = 0.1 + 1.6 * k / 23
        cx, cy = 0.35 * h * np.cos(2.5 * h), 0.35 * h * np.sin(2.5 * h)
        r = 0.12 + 0.12 * h
        rho += np.exp(-((x - cx) ** 2 + (y - cy) ** 2 + (z - h) ** 2) / (2 * r * r))
    n = 0.6 * value_noise(rho.shape, 6, rng) + 0.4 * value_noise(rho.shape, 14, rng)
    rho *= np.clip(2.2 * n - 0.5, 0.0, None)
    rho /= rho.max()
    return np.ascontiguousarray(rho.astype(np.float32))


def box(lo, hi, material: str, start: int) -> tuple[list[str], int]:
    """OBJ lines of a closed box (outward winding), vertex numbers from ``start``."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0), (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    quads = [(1, 4, 3, 2), (5, 6, 7, 8), (1, 2, 6, 5), (2, 3, 7, 6), (3, 4, 8, 7), (4, 1, 5, 8)]
    lines = [f"v {a:g} {b:g} {c:g}" for a, b, c in v] + [f"usemtl {material}"]
    lines += [f"f {start + a - 1} {start + b - 1} {start + c - 1} {start + d - 1}" for a, b, c, d in quads]
    return lines, start + 8


def cylinder(radius: float, height: float, material: str, start: int, sides: int = 48) -> tuple[list[str], int]:
    """A closed cylinder on z = 0 (outward winding)."""
    lines = []
    for z in (0.0, height):
        for k in range(sides):
            a = 2 * np.pi * k / sides
            lines.append(f"v {radius * np.cos(a):.6f} {radius * np.sin(a):.6f} {z:g}")
    lines += [f"v 0 0 0", f"v 0 0 {height:g}", f"usemtl {material}"]
    bot_c, top_c = start + 2 * sides, start + 2 * sides + 1
    for k in range(sides):
        a, b = start + k, start + (k + 1) % sides
        lines.append(f"f {a} {b} {b + sides} {a + sides}")
        lines.append(f"f {bot_c} {b} {a}")
        lines.append(f"f {top_c} {a + sides} {b + sides}")
    return lines, start + 2 * sides + 2


def write_scenes(out: Path, res: int) -> None:
    import warp as wp

    from warp_spt.runtime.warp_init import init_warp

    out.mkdir(parents=True, exist_ok=True)
    init_warp()                  # quietly: no banner
    rho = plume(res)
    # voxel (i, j, k) at (-1, -1, 0) + (i, j, k) * 2 / res in the grid's own space (= the scene's)
    wp.Volume.load_from_numpy(rho, min_world=(-1.0, -1.0, 0.0), voxel_size=2.0 / res, bg_value=0.0,
                              device="cpu").save_to_nvdb(str(out / "smoke.nvdb"))
    floor = ["v -6 -6 0", "v 6 -6 0", "v 6 6 0", "v -6 6 0", "usemtl floor", "f 1 2 3 4"]
    light = ["v -1 -1 4.5", "v -1 1 4.5", "v 1 1 4.5", "v 1 -1 4.5", "usemtl light", "f 5 6 7 8"]
    lines, _ = box((-1.0, -1.0, 0.001), (1.0, 1.0, 2.0), "smoke", 9)
    (out / "smoke.obj").write_text("\n".join(floor + light + lines) + "\n")
    (out / "smoke.mtl").write_text(
        "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl light\nKd 0 0 0\nKe 12 11 10\n"
        "newmtl smoke\nindex_matched\nmedium_density smoke.nvdb\nmedium_density_scale 12\n"
        "medium_sigma_s 1 1 1\nmedium_sigma_a 0.15 0.15 0.15\nmedium_g 0.4\nmedium_majorant 2\n")
    n = 11
    lines = floor + ["v -2 -2 5", "v -2 2 5", "v 2 2 5", "v 2 -2 5", "usemtl light", "f 5 6 7 8"]
    start = 9
    for k in range(0, n, 2):                 # slats across x with gaps between them: sheets of light
        x0, x1 = -4 + 8 * k / n, -4 + 8 * (k + 1) / n
        b, start = box((x0, -4.0, 3.0), (x1, 4.0, 3.1), "slat", start)
        lines += b
    # the attic: walls and a lid around the panel, so that its light leaves through the gaps alone
    lines += [f"v {x:g} {y:g} {z:g}" for z in (3.05, 5.5) for x, y in ((-4, -4), (4, -4), (4, 4), (-4, 4))]
    a = start
    lines += ["usemtl slat"] + [f"f {a + i} {a + (i + 1) % 4} {a + 4 + (i + 1) % 4} {a + 4 + i}" for i in range(4)]
    lines.append(f"f {a + 4} {a + 5} {a + 6} {a + 7}")
    start += 8
    (out / "shafts.obj").write_text("\n".join(lines) + "\n")
    (out / "shafts.mtl").write_text("newmtl floor\nKd 0.6 0.6 0.6\nnewmtl light\nKd 0 0 0\nKe 25 24 21\n"
                                    "newmtl slat\nKd 0.2 0.2 0.2\n")
    cyl, _ = cylinder(0.6, 1.6, "glass", 9)
    (out / "liquid.obj").write_text("\n".join(floor + light + cyl) + "\n")
    (out / "liquid.mtl").write_text(
        "newmtl floor\nKd 0.7 0.7 0.7\nnewmtl light\nKd 0 0 0\nKe 12 12 12\n"
        "newmtl glass\nKd 1 1 1\nNi 1.33\nillum 7\nmedium_sigma_a 0.15 2.5 3.5\n")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path)
    ap.add_argument("--res", type=int, default=64)
    args = ap.parse_args()
    write_scenes(args.out, args.res)
    print(f"wrote {args.out}/smoke.nvdb ({args.res}^3), smoke, shafts and liquid .obj/.mtl")


if __name__ == "__main__":
    main()
