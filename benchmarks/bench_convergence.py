"""The speed/accuracy trade: error against a high-sample reference, per samples and per second.

    python benchmarks/bench_convergence.py            # 128x128 demo, reference 1024 spp (a few minutes)
    python benchmarks/bench_convergence.py --quick    # 64x64, reference 256 spp

The reference uses a different seed from the estimates, so they share no random numbers. RMSE of a
Monte Carlo estimate should halve for every 4x samples (slope -0.5 on a log-log plot); the table
prints the measured slope. Reference noise inflates the error of the largest spp slightly; its own
RMSE estimate (half the RMSE between two half-sample references) is printed too.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING   # no banner or module-load lines (Warp 1.19 dropped config.quiet)

from warp_spt import Sky, load_scene, render  # noqa: E402
from warp_spt.upload.device_scene import DeviceScene  # noqa: E402
from warp_spt.demo import demo_files  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    size, ref_spp = (64, 256) if args.quick else (128, 1024)
    scene = DeviceScene(load_scene(*demo_files()))
    kw = dict(width=size, height=size, max_depth=8, sky=Sky.gradient())
    render(scene, width=8, height=8, spp=1, max_depth=2)          # compile outside the timings
    half_a = render(scene, spp=ref_spp // 2, seed=1001, **kw)
    half_b = render(scene, spp=ref_spp // 2, seed=2002, **kw)
    ref = 0.5 * (half_a + half_b)
    ref_rmse = 0.5 * float(np.sqrt(np.mean((half_a - half_b) ** 2)))
    print(f"demo scene {size}x{size}, depth 8; reference {ref_spp} spp (its own RMSE ~{ref_rmse:.4f})")
    print("| spp | seconds | RMSE | relative RMSE | RMSE x sqrt(seconds) |")
    print("|---|---|---|---|---|")
    spps, errs = [], []
    for spp in (1, 2, 4, 8, 16, 32, 64):
        t = time.perf_counter()
        est = render(scene, spp=spp, seed=7, **kw)
        secs = time.perf_counter() - t
        rmse = float(np.sqrt(np.mean((est - ref) ** 2)))
        rel = rmse / float(np.sqrt(np.mean(ref ** 2)))
        spps.append(spp)
        errs.append(rmse)
        print(f"| {spp} | {secs:.2f} | {rmse:.4f} | {rel:.3f} | {rmse * np.sqrt(secs):.4f} |")
    slope = np.polyfit(np.log(spps), np.log(errs), 1)[0]
    print(f"log-log slope of RMSE against spp: {slope:.3f} (Monte Carlo theory: -0.5)")


if __name__ == "__main__":
    main()
