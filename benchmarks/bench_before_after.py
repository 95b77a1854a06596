"""Render CPU time of the seed's scenes in this checkout against another, interleaved in one run.

    python benchmarks/bench_before_after.py --other ../old-checkout [--rounds 5] [--size 160]

Each figure is the process CPU seconds of one ``render_scene`` (1 thread, depth 6, 8 spp, kernels
compiled by a warm-up render first), in a fresh process per measurement, alternating the two
checkouts round by round so that the machine's drift falls on both; the table gives the medians
and their ratio. Scenes: the built-in demo and the seed's demo (``../shared/seed/demo``, skipped
when absent), whose images the material contract keeps bit for bit, so any change is pure speed.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SEED_DEMO = REPO.parent / "shared" / "seed" / "demo"

WORKER = r'''
import sys, time
import warp as wp
wp.config.log_level = wp.LOG_WARNING
from warp_spt.upload.device_scene import DeviceScene
from warp_spt.io.loader import load_scene
from warp_spt.rendering import tiles as R
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky
which, size, seed_demo = sys.argv[1], int(sys.argv[2]), sys.argv[3]
if which == "demo":
    from warp_spt.demo import demo_files
    objs, mtls = demo_files()
else:
    objs, mtls = [seed_demo + "/cornell_export.obj", seed_demo + "/baller.obj"], [seed_demo + "/testMiku.mtl"]
dev = DeviceScene(load_scene(objs, mtls))
sky = Sky.gradient()
R.render_scene(dev, Camera(), RenderSettings(width=16, height=16, spp=1, max_depth=6, threads=1, sky=sky))
t0 = time.process_time()
R.render_scene(dev, Camera(), RenderSettings(width=size, height=size, spp=8, max_depth=6, seed=1, threads=1, sky=sky))
print(time.process_time() - t0)
'''


def measure(checkout: Path, scene: str, size: int) -> float:
    env = {**os.environ, "PYTHONPATH": str(checkout)}
    out = subprocess.run([sys.executable, "-c", WORKER, scene, str(size), str(SEED_DEMO)], env=env, cwd=SEED_DEMO
                         if scene == "seed-demo" else REPO, capture_output=True, text=True, check=True)
    return float(out.stdout.strip().splitlines()[-1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--other", required=True, type=Path, help="the other checkout (its repository root)")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--size", type=int, default=160)
    args = ap.parse_args()
    scenes = ["demo"] + (["seed-demo"] if (SEED_DEMO / "cornell_export.obj").is_file() else [])
    times = {(c, s): [] for c in ("this", "other") for s in scenes}
    for s in scenes:                        # warm both kernel caches
        measure(REPO, s, 16)
        measure(args.other, s, 16)
    for _ in range(args.rounds):
        for s in scenes:
            times[("other", s)].append(measure(args.other, s, args.size))
            times[("this", s)].append(measure(REPO, s, args.size))
    print(f"{args.size}x{args.size}, 8 spp, depth 6, 1 thread; CPU seconds, median of {args.rounds} interleaved")
    print("| scene | other | this | this / other |\n|---|---|---|---|")
    for s in scenes:
        a, b = statistics.median(times[("other", s)]), statistics.median(times[("this", s)])
        print(f"| {s} | {a:.3f} | {b:.3f} | {b / a:.3f} |")


if __name__ == "__main__":
    main()
