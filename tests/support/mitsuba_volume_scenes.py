"""The scenes of the comparison against Mitsuba 3's volpath (tests/media/test_volumes_mitsuba.py), for both.

Each scene is a cube, [-0.8, 0.8]^3, whose surface is a pass-through boundary (ours: MTL
``index_matched``; Mitsuba: the ``null`` BSDF) around a medium, under the area light and the grey sky
of tests/support/mitsuba_scenes.py, seen by its camera:

* ``homogeneous``: a chromatic scattering medium (sigma_t and albedo per channel, HG g = 0.4);
* ``grid``: a 20^3 density grid (a smooth blob thinned by a few holes, zero in its outer two voxel
  layers so that the two renderers' rules at a grid's edge, ours 0 beyond it, Mitsuba's clamped,
  agree), sigma_t = 6 x density, albedo per channel, HG g = -0.2.

Placement of the grid: Mitsuba's ``gridvolume`` spreads voxel i's value at (i + 0.5) / n of its unit
cube, which ``to_world`` maps onto the cube; ours puts voxel i at ``origin + i * voxel_size``, so
origin = -0.8 + voxel_size / 2 with voxel_size = 1.6 / n. This module imports neither renderer.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

HALF = 0.8
MAX_DEPTH = 100
HOMOGENEOUS = dict(sigma_t=(1.2, 2.0, 3.0), albedo=(0.9, 0.7, 0.95), g=0.4)
GRID = dict(scale=6.0, albedo=(0.8, 0.9, 0.95), g=-0.2, n=20)
SCENES = ("homogeneous", "grid")


def density(n: int = GRID["n"]) -> np.ndarray:
    """(n, n, n) float32 densities in [0, 1], x, y, z index order, zero in the outer two layers."""
    c = (np.arange(n) + 0.5) / n * 2 - 1
    x, y, z = np.meshgrid(c, c, c, indexing="ij")
    rho = np.exp(-(x**2 + 1.5 * y**2 + (z - 0.1) ** 2) / 0.25)
    rng = np.random.default_rng(35)
    holes = rng.uniform(-0.5, 0.5, (6, 3))
    for h in holes:
        rho *= 1.0 - 0.8 * np.exp(-((x - h[0]) ** 2 + (y - h[1]) ** 2 + (z - h[2]) ** 2) / 0.02)
    rho[:2], rho[-2:], rho[:, :2], rho[:, -2:], rho[:, :, :2], rho[:, :, -2:] = 0, 0, 0, 0, 0, 0
    return np.ascontiguousarray((rho / rho.max()).astype(np.float32))


def cube_obj() -> str:
    """The cube as OBJ text, outward winding (two triangles a face)."""
    h = HALF
    v = [(-h, -h, -h), (h, -h, -h), (h, h, -h), (-h, h, -h), (-h, -h, h), (h, -h, h), (h, h, h), (-h, h, h)]
    quads = [(1, 4, 3, 2), (5, 6, 7, 8), (1, 2, 6, 5), (2, 3, 7, 6), (3, 4, 8, 7), (4, 1, 5, 8)]
    lines = [f"v {a:g} {b:g} {c:g}" for a, b, c in v] + ["usemtl m"]
    lines += [f"f {a} {b} {c}\nf {a} {c} {d}" for a, b, c, d in quads]
    return "\n".join(lines) + "\n"


def homogeneous_mtl() -> str:
    st, al = np.asarray(HOMOGENEOUS["sigma_t"]), np.asarray(HOMOGENEOUS["albedo"])
    return ("newmtl m\nindex_matched\n"
            f"medium_sigma_s {' '.join(f'{v:.9g}' for v in st * al)}\n"
            f"medium_sigma_a {' '.join(f'{v:.9g}' for v in st * (1 - al))}\n"
            f"medium_g {HOMOGENEOUS['g']}\n")


def write_files(folder: Path, name: str) -> tuple[list[str], list[str]]:
    """([cube, light] OBJ paths, [MTL path]) of scene ``name`` (the grid's medium is set by the API)."""
    from tests.support import mitsuba_scenes as MS

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "cube.obj").write_text(cube_obj())
    (folder / "light.obj").write_text(MS.light_obj())
    mtl = homogeneous_mtl() if name == "homogeneous" else "newmtl m\nindex_matched\n"
    mtl += f"\nnewmtl light\nKd 0 0 0\nKs 0\nKe {MS.LIGHT} {MS.LIGHT} {MS.LIGHT}\n"
    (folder / f"{name}.mtl").write_text(mtl)
    return [str(folder / "cube.obj"), str(folder / "light.obj")], [str(folder / f"{name}.mtl")]


def grid_medium():
    """Our grid medium (warp_spt.scene.media.Medium) of the ``grid`` scene."""
    from warp_spt.scene.media import Medium

    n, al = GRID["n"], np.asarray(GRID["albedo"])
    vs = 2 * HALF / n
    return Medium(sigma_s=tuple(GRID["scale"] * al), sigma_a=tuple(GRID["scale"] * (1 - al)), g=GRID["g"],
                  density=density(n), origin=(-HALF + vs / 2,) * 3, voxel_size=vs)
