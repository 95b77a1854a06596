"""Cost per sample of participating media: the built-in demo scene with and without a fog.

    python benchmarks/bench_volumes.py [--size 96] [--spp 8] [--repeats 3]

Renders the demo (depth 6, Sobol', one thread, kernels compiled before timing) as:
``nee`` without media (today's renderer), ``volpath`` without media (must be the same kernel: the
same image, the same time), ``volpath`` in a grey fog (sigma_s 0.01, sigma_a 0.002 per unit of the
seed's scene, a mean free path of about the Cornell box's size), the same fog at majorant 2, and a
chromatic fog. Prints microseconds per sample (the median of ``repeats`` launches' kernel time
over samples) and closest-hit rays per sample. Figures only: nothing is asserted.
"""

from __future__ import annotations

import argparse
import statistics
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from warp_spt.upload.device_scene import DeviceScene  # noqa: E402
from warp_spt.demo import demo_files  # noqa: E402
from warp_spt.io.loader import load_scene  # noqa: E402
from warp_spt.rendering.settings import RenderSettings  # noqa: E402
from warp_spt.rendering.tiles import render_scene  # noqa: E402
from warp_spt.scene.camera import Camera  # noqa: E402
from warp_spt.scene.media import Medium  # noqa: E402
from warp_spt.scene.sky import Sky  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    base = load_scene(*demo_files())
    cases = [
        ("nee, no medium", base, "nee"),
        ("volpath, no medium", base, "volpath"),
        ("volpath, grey fog", replace(base, fog=Medium(sigma_s=0.01, sigma_a=0.002)), "volpath"),
        ("volpath, grey fog, majorant 2", replace(base, fog=Medium(sigma_s=0.01, sigma_a=0.002, majorant=2.0)),
         "volpath"),
        ("volpath, chromatic fog", replace(base, fog=Medium(sigma_s=(0.006, 0.01, 0.016), sigma_a=0.002)),
         "volpath"),
    ]
    images = {}
    for label, scene, integrator in cases:
        dev = DeviceScene(scene)
        rs = RenderSettings(width=args.size, height=args.size, spp=args.spp, max_depth=6, seed=1, threads=1,
                            integrator=integrator, sampler="sobol", sky=Sky.gradient())
        render_scene(dev, Camera(), replace(rs, spp=1))          # compile outside the timing
        times, rays = [], 0
        for _ in range(args.repeats):
            res = render_scene(dev, Camera(), rs)
            times.append(res.stats.render_seconds)
            rays = res.stats.rays
            images[label] = res.image
        samples = args.size * args.size * args.spp
        print(f"{label:<32} {statistics.median(times) / samples * 1e6:8.2f} us/sample   "
              f"{rays / samples:5.2f} rays/sample   mean {images[label].mean():.4f}")
    same = np.array_equal(images["nee, no medium"], images["volpath, no medium"])
    print(f"volpath without media renders nee's image bit for bit: {same}")


if __name__ == "__main__":
    main()
