"""Many lights: the light tree against the power table it replaced, at equal error and with one light.

    python benchmarks/bench_many_lights.py            # about 5 minutes on 2 shared cores
    python benchmarks/bench_many_lights.py --quick    # smaller images, fewer samples

"Before" is the renderer at commit 35d081a (the last one without the tree: every emitting triangle
an entry of the light table, chosen in proportion to its power wherever the shading point is),
extracted with ``git archive`` and run in a subprocess exactly as "after" (this checkout) is.

* **A lit city** (the many-light scene): a 160 x 160 ground with a 48 x 48 grid of small lamps
  (4,608 emitting triangles, powers varying by 10x in a pattern), 0.4 above it, and a few blocks;
  the camera looks over it from a corner 3 units up, so most lamps are far from what it sees.
  A second view looks down on a street corner from 6 units up. Depth 3, black sky, nee + Sobol'. The reference is the tree at many samples (the mean of two
  halves with different seeds; its own MSE, a quarter of the halves' mean squared difference, is
  subtracted from each estimate's), MSE off-light: without the lamps' own pixels and their rim.
  Efficiency is 1 / (MSE x CPU seconds), CPU seconds of one
  render thread (``time.thread_time``; kernels compiled before), the least of three runs.
* **One light** (the cost where the tree cannot help): a room lit by one square lamp (2 triangles,
  below the tree's threshold, so the same code as before runs); CPU seconds before and after.

Figures are printed, never asserted.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
BEFORE = "35d081a"

WORKER = r"""
import json, sys, time
import numpy as np
from warp_spt.io.loader import load_scene
from warp_spt.upload.device_scene import DeviceScene
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky
a = json.loads(sys.argv[1])
dev = DeviceScene(load_scene(a["objs"], a["mtls"], warn=lambda m: None))
cam = Camera(**a["camera"])
def go(spp, seed):
    rs = RenderSettings(width=a["w"], height=a["h"], spp=spp, max_depth=a["depth"], sky=Sky.constant(0, 0, 0),
                        integrator="nee", sampler="sobol", seed=seed, threads=1)
    t = time.thread_time()
    img = render_scene(dev, cam, rs).image
    return img, time.thread_time() - t
go(1, 0)                                   # compile
out = {}
for name, spp, seed, runs in a["jobs"]:
    best, img = None, None
    for _ in range(runs):
        img, s = go(spp, seed)
        best = s if best is None else min(best, s)
    np.save(a["dir"] + "/" + name + ".npy", img)
    out[name] = best
print(json.dumps(out))
"""


def quad(x0, y0, x1, y1, z):
    return [(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)]


def write_city(folder: Path, n: int = 48) -> tuple[list[str], list[str]]:
    verts, faces = [], []

    def add(mat, corners):
        b = len(verts) + 1
        verts.extend(corners)
        faces.extend([f"usemtl {mat}", f"f {b} {b + 1} {b + 2}", f"f {b} {b + 2} {b + 3}"])

    add("ground", quad(-80, -80, 80, 80, 0.0))
    xs = np.linspace(-75, 75, n)
    for i, x in enumerate(xs):
        for j, y in enumerate(xs):
            add(f"lamp{(i * 7 + j * 3) % 4}", quad(x - 0.15, y - 0.15, x + 0.15, y + 0.15, 0.4))
    for cx, cy in [(-70, -66), (-64, -72), (-58, -60)]:         # blocks near the camera: shadows
        for c in [quad(cx - 1, cy - 1, cx + 1, cy + 1, 2.0)]:
            add("block", c)
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in verts] + faces
    (folder / "city.obj").write_text("\n".join(lines) + "\n")
    mtl = "newmtl ground\nKd 0.5 0.5 0.5\nRoughness 1\nnewmtl block\nKd 0.7 0.7 0.7\nRoughness 1\n"
    for k, p in enumerate([1.0, 3.0, 6.0, 10.0]):
        mtl += f"newmtl lamp{k}\nKd 0 0 0\nKl {p * 20:g} {p * 16:g} {p * 10:g}\n"
    (folder / "city.mtl").write_text(mtl)
    return [str(folder / "city.obj")], [str(folder / "city.mtl")]


def write_room(folder: Path) -> tuple[list[str], list[str]]:
    verts, faces = [], []

    def add(mat, corners):
        b = len(verts) + 1
        verts.extend(corners)
        faces.extend([f"usemtl {mat}", f"f {b} {b + 1} {b + 2}", f"f {b} {b + 2} {b + 3}"])

    s = 16.0
    add("white", quad(-s, 0, s, 2 * s, 0.0))
    add("white", [(-s, 0, 2 * s), (s, 0, 2 * s), (s, 2 * s, 2 * s), (-s, 2 * s, 2 * s)])
    add("white", [(-s, 2 * s, 0), (s, 2 * s, 0), (s, 2 * s, 2 * s), (-s, 2 * s, 2 * s)])
    add("red", [(-s, 0, 0), (-s, 2 * s, 0), (-s, 2 * s, 2 * s), (-s, 0, 2 * s)])
    add("green", [(s, 0, 0), (s, 2 * s, 0), (s, 2 * s, 2 * s), (s, 0, 2 * s)])
    add("lamp", quad(-4, s - 4, 4, s + 4, 2 * s - 0.25))
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in verts] + faces
    (folder / "room.obj").write_text("\n".join(lines) + "\n")
    (folder / "room.mtl").write_text("newmtl white\nKd 0.7 0.7 0.7\nRoughness 1\nnewmtl red\nKd 0.6 0.1 0.1\n"
                                     "Roughness 1\nnewmtl green\nKd 0.1 0.6 0.1\nRoughness 1\n"
                                     "newmtl lamp\nKd 0 0 0\nKl 17 17 17\n")
    return [str(folder / "room.obj")], [str(folder / "room.mtl")]


def run(code: Path, args: dict) -> dict:
    env = dict(os.environ, PYTHONPATH=str(code))
    out = subprocess.run([sys.executable, "-c", WORKER, json.dumps(args)], env=env, cwd=str(code),
                         capture_output=True, text=True)
    if out.returncode:
        raise SystemExit(f"the render in {code} failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def city(out: Path, before: Path, base: dict, view: str, spp: int, ref_spp: int) -> None:
    out.mkdir()
    t_ref = run(REPO, dict(base, dir=str(out), jobs=[["ref_a", ref_spp // 2, 1001, 1], ["ref_b", ref_spp // 2, 2002, 1]]))
    a, b = np.load(out / "ref_a.npy").astype(np.float64), np.load(out / "ref_b.npy").astype(np.float64)
    ref = 0.5 * (a + b)
    # off-light: without the lamps' own pixels and a 1-pixel rim (there the error is the pixel
    # sampling of an edge between radiance 20-200 and the dark ground, not the light choice)
    lamp = (ref.max(axis=2) > 5.0)
    rim = lamp.copy()
    for dy, dx in [(-1, 0), (1, 0), (0, -1), (0, 1), (-1, -1), (-1, 1), (1, -1), (1, 1)]:
        rim |= np.roll(np.roll(lamp, dy, 0), dx, 1)
    off = ~rim
    ref_mse = 0.25 * np.mean(((a - b) ** 2)[off])
    rows = []
    for label, code in [("before: power table", before), ("after: light tree", REPO)]:
        d = out / label.split(":")[0]
        d.mkdir()
        secs = run(code, dict(base, dir=str(d), jobs=[["est", spp, 7, 3]]))["est"]
        img = np.load(d / "est.npy").astype(np.float64)
        mse = max(np.mean(((img - ref) ** 2)[off]) - ref_mse, 1e-30)
        rows.append((label, mse, secs, 1.0 / (mse * secs)))
    print(f"lit city, {view}: {base['w']}x{base['h']}, {spp} spp, depth 3, 4,608 emitting triangles; reference "
          f"{ref_spp} spp (its own MSE {ref_mse:.3g} subtracted; {t_ref['ref_a'] + t_ref['ref_b']:.0f} CPU s); "
          f"MSE off-light ({off.mean():.0%} of the pixels)")
    print(f"{'':24s} {'MSE':>10s} {'CPU s':>8s} {'1/(MSE s)':>10s}")
    for label, mse, secs, eff in rows:
        print(f"{label:24s} {mse:10.4g} {secs:8.3f} {eff:10.4g}")
    print(f"efficiency after / before: {rows[1][3] / rows[0][3]:.2f}x")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    q = ap.parse_args().quick
    w, h = (64, 40) if q else (96, 64)
    spp, ref_spp = (32, 4096) if q else (64, 16384)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        before = tmp / "before"
        before.mkdir()
        archive = subprocess.run(["git", "-C", str(REPO), "archive", BEFORE], capture_output=True, check=True).stdout
        subprocess.run(["tar", "-x", "-C", str(before)], input=archive, check=True)
        out = tmp / "out"
        out.mkdir()
        objs, mtls = write_city(tmp)
        views = [("over the city", (-76.0, -76.0, 3.0), (1.0, 1.0, -0.25)),
                 ("a street corner from above", (-70.0, -70.0, 6.0), (1.0, 1.0, -1.2))]
        for view, position, direction in views:
            cam = dict(position=position, direction=direction, fov=60.0, aperture=0.0, focus=10.0)
            city(out / view.replace(" ", "_"), before, dict(objs=objs, mtls=mtls, camera=cam, w=w, h=h, depth=3),
                 view, spp, ref_spp)

        objs, mtls = write_room(tmp)
        cam = dict(position=(0.0, -40.0, 16.0), direction=(0.0, 1.0, 0.0), fov=45.0, aperture=0.0, focus=40.0)
        base = dict(objs=objs, mtls=mtls, camera=cam, w=w, h=h, depth=6)
        print(f"one light (a room, 2 emitting triangles: no tree): {w}x{h}, {spp} spp, depth 6, CPU s, least of 5")
        times = {}
        for label, code in [("before", before), ("after", REPO)]:
            d = out / f"room_{label}"
            d.mkdir()
            times[label] = run(code, dict(base, dir=str(d), jobs=[["est", spp, 7, 5]]))["est"]
            print(f"  {label:8s} {times[label]:.3f}")
        same = np.array_equal(np.load(out / "room_before" / "est.npy"), np.load(out / "room_after" / "est.npy"))
        print(f"  after / before: {times['after'] / times['before']:.3f}; images bit-identical: {same}")


if __name__ == "__main__":
    main()
