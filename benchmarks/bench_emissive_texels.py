"""Emissive textures drawn by their texels (``emitters/emissive_texels.py``) against today's
selection before it (each textured triangle weighed by its mean, a point on it uniform by area or
solid angle), at equal error.

    python benchmarks/bench_emissive_texels.py            # a few minutes on 2 shared cores
    python benchmarks/bench_emissive_texels.py --quick

"Before" is the renderer at commit a2bfe33 (the last one without cells), extracted with
``git archive`` and run in a subprocess exactly as "after" (this checkout) is
(``bench_many_lights.run``).

The scene: a room at night lit by a TV screen (a 4 x 2 quad) behind the camera, whose texture
(256 x 128 texels, ``map_Kl``) is dim (8/255) but for a bright patch (255) of 32 x 16 texels in one
corner: 1.6% of its area, most of its light. The camera sees the floor, the back wall and a block,
never the screen. Two versions: the screen as 2 triangles (each of 16,384 texels: 32 x 32 cells
a triangle) and tessellated into 16 x 8 quads (256 triangles, so the light tree chooses among them;
each of 128 texels, 12 x 12 cells). Depth 3, black sky, nee + Sobol'. MSE against a reference of
many samples by this checkout (the mean of two halves with different seeds; its own MSE, a quarter
of the halves' mean squared difference, subtracted). Efficiency is 1 / (MSE x CPU seconds), CPU
seconds of one render thread, the least of three runs. Figures are printed, never asserted.
"""

from __future__ import annotations

import argparse
import subprocess
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

from bench_many_lights import REPO, quad, run

BEFORE = "a2bfe33"


def write_room(folder: Path, tiles: tuple[int, int]) -> tuple[list[str], list[str]]:
    tex = np.full((128, 256, 3), 8, np.uint8)
    tex[8:24, 16:48] = 255                        # near the top left, as seen from the room
    Image.fromarray(tex).save(folder / "tv.png")
    verts, uvs, faces = [], [], []

    def add(mat, corners, uv=None):
        b = len(verts) + 1
        verts.extend(corners)
        if uv is None:
            faces.extend([f"usemtl {mat}", f"f {b} {b + 1} {b + 2}", f"f {b} {b + 2} {b + 3}"])
            return
        t = len(uvs) + 1
        uvs.extend(uv)
        faces.extend([f"usemtl {mat}", f"f {b}/{t} {b + 1}/{t + 1} {b + 2}/{t + 2}",
                      f"f {b}/{t} {b + 2}/{t + 2} {b + 3}/{t + 3}"])

    add("white", quad(-4, -4, 4, 4, 0.0))
    add("white", [(-4, 4, 0), (4, 4, 0), (4, 4, 3), (-4, 4, 3)])
    add("white", [(-4, -4, 0), (-4, 4, 0), (-4, 4, 3), (-4, -4, 3)])
    for c in [quad(0.5, 0.5, 1.5, 1.5, 1.0), [(0.5, 0.5, 0), (1.5, 0.5, 0), (1.5, 0.5, 1), (0.5, 0.5, 1)],
              [(0.5, 0.5, 0), (0.5, 1.5, 0), (0.5, 1.5, 1), (0.5, 0.5, 1)]]:
        add("white", c)
    nx, nz = tiles                                 # the screen: x in [-2, 2], z in [0.5, 2.5], at y = -3
    for i in range(nx):
        for k in range(nz):
            u0, u1, v0, v1 = i / nx, (i + 1) / nx, k / nz, (k + 1) / nz
            x0, x1, z0, z1 = -2 + 4 * u0, -2 + 4 * u1, 0.5 + 2 * v0, 0.5 + 2 * v1
            add("tv", [(x0, -3, z0), (x1, -3, z0), (x1, -3, z1), (x0, -3, z1)],
                [(u0, v0), (u1, v0), (u1, v1), (u0, v1)])
    lines = ([f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in verts]
             + [f"vt {u!r} {v!r}" for u, v in uvs] + faces)
    name = f"room_{nx}x{nz}"
    (folder / f"{name}.obj").write_text("\n".join(lines) + "\n")
    (folder / f"{name}.mtl").write_text("newmtl white\nKd 0.7 0.7 0.7\nRoughness 1\n"
                                        f"newmtl tv\nKd 0 0 0\nKl 1 1 1\nmap_Kl {folder / 'tv.png'}\n")
    return [str(folder / f"{name}.obj")], [str(folder / f"{name}.mtl")]


def measure(out: Path, before: Path, base: dict, label: str, spp: int, ref_spp: int) -> None:
    out.mkdir()
    run(REPO, dict(base, dir=str(out), jobs=[["ref_a", ref_spp // 2, 1001, 1], ["ref_b", ref_spp // 2, 2002, 1]]))
    a, b = np.load(out / "ref_a.npy").astype(np.float64), np.load(out / "ref_b.npy").astype(np.float64)
    ref = 0.5 * (a + b)
    ref_mse = 0.25 * np.mean((a - b) ** 2)
    rows = []
    for name, code in [("before: uniform on a triangle", before), ("after: by texels", REPO)]:
        d = out / name.split(":")[0]
        d.mkdir()
        secs = run(code, dict(base, dir=str(d), jobs=[["est", spp, 7, 3]]))["est"]
        img = np.load(d / "est.npy").astype(np.float64)
        mse = max(np.mean((img - ref) ** 2) - ref_mse, 1e-30)
        rows.append((name, mse, secs, 1.0 / (mse * secs)))
    print(f"{label}: {base['w']}x{base['h']}, {spp} spp, depth 3; reference {ref_spp} spp (its own MSE "
          f"{ref_mse:.3g} subtracted)")
    print(f"{'':32s} {'MSE':>10s} {'CPU s':>8s} {'1/(MSE s)':>10s}")
    for name, mse, secs, eff in rows:
        print(f"{name:32s} {mse:10.4g} {secs:8.3f} {eff:10.4g}")
    print(f"efficiency after / before: {rows[1][3] / rows[0][3]:.2f}x")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    q = ap.parse_args().quick
    w, h = (48, 32) if q else (96, 64)
    spp, ref_spp = (16, 2048) if q else (32, 8192)
    cam = dict(position=(0.0, -2.5, 1.6), direction=(0.0, 1.0, -0.3), fov=60.0, aperture=0.0, focus=5.0)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        before = tmp / "before"
        before.mkdir()
        archive = subprocess.run(["git", "-C", str(REPO), "archive", BEFORE], capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(before)], input=archive, check=True)
        out = tmp / "out"
        out.mkdir()
        for tiles, label in [((1, 1), "TV screen, 2 triangles"), ((16, 8), "TV screen, 256 triangles (light tree)")]:
            objs, mtls = write_room(tmp, tiles)
            measure(out / f"{tiles[0]}x{tiles[1]}", before, dict(objs=objs, mtls=mtls, camera=cam, w=w, h=h, depth=3),
                    label, spp, ref_spp)


if __name__ == "__main__":
    main()
