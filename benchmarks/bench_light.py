"""Light transport efficiency: 1 / (MSE x seconds) for each integrator x sampler on a Cornell box.

    python benchmarks/bench_light.py             # 256^2 and 512^2 (about 10 minutes on 2 cores)
    python benchmarks/bench_light.py --quick     # 128^2 only

The last row of each table is the renderer as it was when issue 8 was filed (commit 2f89ff6,
extracted with ``git archive`` and timed in a subprocess the same way); its images must be
bit-identical to today's seed + independent row.

The scene is the classic layout: a 32-unit room open at the front, white/red/green walls, two white blocks, a
small square light (8 x 8 units, 6% of the ceiling) 0.25 below the ceiling, black sky, depth 6,
every surface diffuse. The reference is NEE + Sobol' at high spp, as the mean of two halves with
different seeds; its own MSE (a quarter of the halves' mean squared difference) is subtracted from
each estimate's measured MSE, so reference noise does not flatter the slower estimators. Every
estimate uses the same spp and a seed the reference does not use. Seconds are CPU seconds of one
render thread (``time.thread_time``; kernels compiled before), the least of three runs whose MSEs
are averaged: wall time on a machine shared with other jobs measured the load, not the renderer.

Efficiency is 1 / (MSE x CPU seconds) in linear radiance, over all pixels and "off-light": without
the emitter's own pixels and their 1-pixel rim. There the error is the anti-aliasing of an edge
between radiance 17 and the dark ceiling, which only the pixel sampling (not the light transport)
can reduce, and which dominates the whole image's MSE once the rest converges.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING   # no banner or module-load lines (Warp 1.19 dropped config.quiet)

from warp_spt import Camera, RenderSettings, Sky, load_scene, render_scene  # noqa: E402
from warp_spt.upload.device_scene import DeviceScene  # noqa: E402

S = 32.0
COMBOS = [("seed", "independent", 0), ("seed", "sobol", 0), ("nee", "independent", 0), ("nee", "sobol", 0),
          ("nee", "sobol", 3)]


def cornell(folder: Path) -> DeviceScene:
    """The classic Cornell box as OBJ/MTL text (open at the front, y = 0, where the camera looks in)."""
    quads = [("white", [(0, 0, 0), (S, 0, 0), (S, S, 0), (0, S, 0)]),
             ("white", [(0, 0, S), (0, S, S), (S, S, S), (S, 0, S)]),
             ("white", [(0, S, 0), (S, S, 0), (S, S, S), (0, S, S)]),
             ("red", [(0, 0, 0), (0, S, 0), (0, S, S), (0, 0, S)]),
             ("green", [(S, 0, 0), (S, 0, S), (S, S, S), (S, S, 0)]),
             ("light", [(12, 12, S - 0.25), (20, 12, S - 0.25), (20, 20, S - 0.25), (12, 20, S - 0.25)])]
    for lo, hi in (((6, 16, 0), (14, 24, 16)), ((18, 6, 0), (26, 14, 8))):
        (x0, y0, z0), (x1, y1, z1) = lo, hi
        quads += [("white", q) for q in (
            [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)],
            [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)], [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)],
            [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)])]
    lines, faces = [], []
    for k, (mat, corners) in enumerate(quads):
        lines += [f"v {x} {y} {z}" for x, y, z in corners]
        faces += [f"usemtl {mat}", f"f {4 * k + 1} {4 * k + 2} {4 * k + 3}", f"f {4 * k + 1} {4 * k + 3} {4 * k + 4}"]
    (folder / "cornell.obj").write_text("\n".join(lines + faces) + "\n")
    (folder / "cornell.mtl").write_text(
        "newmtl white\nKd 0.73 0.73 0.73\nRoughness 1\nnewmtl red\nKd 0.65 0.05 0.05\nRoughness 1\n"
        "newmtl green\nKd 0.12 0.45 0.15\nRoughness 1\nnewmtl light\nKd 0.78 0.78 0.78\nKl 17 12 4\nRoughness 1\n")
    return DeviceScene(load_scene([str(folder / "cornell.obj")], [str(folder / "cornell.mtl")]))


CAMERA_ARGS = dict(position=(S / 2, -38.0, S / 2), direction=(0.0, 1.0, 0.0), fov=40.0, aperture=0.0, focus=40.0)
CAMERA = Camera(**CAMERA_ARGS)
SEEDS = (7, 8, 9)
OLD = "2f89ff6"       # main when issue 8 was filed
# Run in a subprocess on an extracted copy of OLD (its package has the same name as ours)
OLD_RUN = """
import sys, time, numpy as np, warp as wp
wp.config.log_level = wp.LOG_WARNING   # no banner or module-load lines (Warp 1.19 dropped config.quiet)
from warp_spt import Camera, Sky, load_scene, render
from warp_spt.device_scene import DeviceScene
folder, size, spp, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
scene = DeviceScene(load_scene([folder + '/cornell.obj'], [folder + '/cornell.mtl']))
cam = Camera(**{cam!r})
kw = dict(width=size, height=size, max_depth=6, sky=Sky.constant(0, 0, 0), threads=1)
render(scene, cam, **dict(kw, width=8, height=8, spp=1))          # compile outside the timings
imgs, secs = [], []
for seed in {seeds!r}:
    t = time.thread_time()
    imgs.append(render(scene, cam, **dict(kw, spp=spp, seed=seed)))
    secs.append(time.thread_time() - t)
np.savez(out, images=np.stack(imgs), secs=np.array(secs))
""".format(cam=CAMERA_ARGS, seeds=SEEDS)


def old_code(folder: Path, size: int, spp: int):
    """(images, CPU seconds) of the renderer at commit OLD, or None where git cannot provide it."""
    root = Path(__file__).resolve().parents[1]
    old = folder / "old"
    old.mkdir(exist_ok=True)
    try:
        tar = subprocess.run(["git", "-C", str(root), "archive", OLD, "warp_spt"], check=True, capture_output=True).stdout
        subprocess.run(["tar", "-x", "-C", str(old)], input=tar, check=True)
        out = folder / f"old_{size}.npz"
        subprocess.run([sys.executable, "-c", OLD_RUN, str(folder), str(size), str(spp), str(out)], check=True,
                       cwd=old, env=dict(os.environ, PYTHONPATH=str(old)), capture_output=True)   # Warp's banner
    except (OSError, subprocess.CalledProcessError) as e:
        print(f"(commit {OLD} not measured: {e})")
        return None
    z = np.load(out)
    return z["images"], z["secs"]


def run(scene: DeviceScene, size: int, ref_spp: int, spp: int, folder: Path) -> None:
    base = dict(width=size, height=size, max_depth=6, sky=Sky.constant(0, 0, 0))

    def go(integrator, sampler, n, seed, roulette=0, threads=None):
        return render_scene(scene, CAMERA, RenderSettings(spp=n, seed=seed, integrator=integrator, sampler=sampler,
                                                          roulette_depth=roulette, threads=threads, **base))

    a = go("nee", "sobol", ref_spp // 2, 1001).image.astype(np.float64)
    b = go("nee", "sobol", ref_spp // 2, 2002).image.astype(np.float64)
    ref, ref_mse = 0.5 * (a + b), float(np.mean((a - b) ** 2)) / 4
    bright = ref.max(axis=2) > 1.5          # the emitter itself (radiance 17) and its 1-pixel rim
    rim = bright.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            rim |= np.roll(np.roll(bright, dy, 0), dx, 1)
    print(f"\n## Cornell box {size}x{size}, depth 6, black sky; reference NEE + Sobol' {ref_spp} spp "
          f"(its MSE {ref_mse:.2e}, subtracted); estimates {spp} spp; 'off-light' leaves out the "
          f"{rim.sum()} pixels of the emitter and its rim")
    print("| integrator | sampler | roulette | CPU s | camera samples/CPU-s | RMSE | efficiency | vs seed+indep. "
          "| RMSE off-light | efficiency off-light | vs seed+indep. |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    ref_mse_off = float(np.mean(((a - b) ** 2)[~rim])) / 4

    def errors(image):
        sq = (image - ref) ** 2
        return float(np.mean(sq)) - ref_mse, float(np.mean(sq[~rim])) - ref_mse_off

    first, seed_images, same = None, None, True
    old = old_code(folder, size, spp)
    for integrator, sampler, roulette in COMBOS + [(f"commit {OLD}", "(seed)", 0)] * (old is not None):
        errs, secs = [], []
        for k, seed in enumerate(SEEDS):   # three estimates: mean MSE, least time (others share the machine)
            if integrator.startswith("commit"):
                image, sec = old[0][k], float(old[1][k])
                same = same and np.array_equal(image, seed_images[k])
            else:
                t = time.thread_time()
                image = go(integrator, sampler, spp, seed, roulette, threads=1).image   # launched from this thread
                sec = time.thread_time() - t
            secs.append(sec)
            errs.append(errors(image))
            if (integrator, sampler) == ("seed", "independent"):
                seed_images = (seed_images or []) + [image]
        if integrator.startswith("commit"):
            sampler += " bit-identical to seed+independent" if same else " NOT identical to seed+independent"
        mse, mse_off = np.mean(errs, axis=0)
        sec = float(np.min(secs))
        eff, eff_off = 1.0 / (mse * sec), 1.0 / (mse_off * sec)
        first = first or (eff, eff_off)
        print(f"| {integrator} | {sampler} | {roulette or 'off'} | {sec:.2f} | {size * size * spp / sec:,.0f} | "
              f"{np.sqrt(mse):.4f} | {eff:,.1f} | {eff / first[0]:.2f}x | {np.sqrt(mse_off):.4f} | {eff_off:,.1f} | "
              f"{eff_off / first[1]:.2f}x |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="128^2 only, small reference")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        scene = cornell(Path(tmp))
        for integrator, sampler, _ in COMBOS:     # compile outside the timings
            render_scene(scene, CAMERA, RenderSettings(width=8, height=8, spp=1, integrator=integrator,
                                                       sampler=sampler, sky=Sky.constant(0, 0, 0)))
        plan = [(128, 256, 8)] if args.quick else [(256, 256, 8), (512, 64, 4)]
        for size, ref_spp, spp in plan:
            run(scene, size, ref_spp, spp, Path(tmp))


if __name__ == "__main__":
    main()
