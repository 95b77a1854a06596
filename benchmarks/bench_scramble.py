"""Error at equal samples, and speed, of the Sobol' scrambles on whole renders (issue 33).

    python benchmarks/bench_scramble.py                       # 3 scenes, 48x48, 4/16/64 spp, 8 seeds
    python benchmarks/bench_scramble.py --size 32 --seeds 6 --spp 4 16

Scenes: bench_vs_mitsuba.py's Cornell box (diffuse, one area light), indirect room (lit after two
or more bounces) and caustics room (glass and mirror balls, a small light, a dim sky), rendered by
``nee`` (depth 6, default roulette) with each sampler and ``--seeds`` seeds.

Error without a reference image: both samplers are unbiased, so a pixel's mean squared error is its
variance across independent seeds (Sobol' renders of different seeds are independent; renders of
one seed are not). Per pixel, the sample variance over the seeds (averaged over the colour
channels) estimates it without bias; the table's RMSE is the square root of its mean over pixels,
and its error (+-) is one standard error of that mean over pixels (which includes the estimate's
own noise), carried through the square root. The ratio to the first sampler's RMSE is estimated
pixel by pixel (``rmse_ratio``), which cancels the spread of the pixels' own variances. Bias check:
the images' means over seeds, against the first sampler's, in units of the difference's standard error
(|z| above ~4 would be suspect).

Speed: every render single-threaded (threads=1), wall time, the samplers alternated per seed, the
first render of each scene and sampler (the kernel's compile) left out; median per render. The
machine may be loaded: compare the samplers within one run only.
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING

SCENES = ("cornell", "indirect", "caustics")


def render(scene, desc, size: int, spp: int, sampler: str, seed: int) -> tuple[np.ndarray, float]:
    import bench_vs_mitsuba as mb
    t = time.perf_counter()
    img = mb.warp_render(scene, desc, size, spp, "nee", sampler, seed, threads=1)
    return img, time.perf_counter() - t


def pixel_variance(images: np.ndarray) -> np.ndarray:
    """Per-pixel variance across seeds (averaged over the channels) of (seeds, H, W, 3) renders."""
    return images.var(axis=0, ddof=1).mean(axis=-1).ravel()


def error_stats(images: np.ndarray) -> tuple[float, float]:
    """(RMSE, its standard error) from (seeds, H, W, 3) renders of one sampler and spp."""
    v = pixel_variance(images)
    mse, se = v.mean(), v.std(ddof=1) / math.sqrt(v.size)
    return math.sqrt(mse), 0.5 * se / math.sqrt(mse)


def rmse_ratio(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """RMSE(a) / RMSE(b) and its standard error, pixel by pixel: the pixels' own variances (a few
    bright edges dominate) cancel in the per-pixel comparison, so the ratio is known far better
    than either RMSE (delta method on the paired per-pixel variances)."""
    va, vb = pixel_variance(a), pixel_variance(b)
    r = va.mean() / vb.mean()
    se = (va - r * vb).std(ddof=1) / math.sqrt(va.size) / vb.mean()
    return math.sqrt(r), 0.5 * se / math.sqrt(r)


def bias_z(a: np.ndarray, b: np.ndarray) -> float:
    """The difference of the two samplers' mean images (over seeds and pixels) in standard errors."""
    da, db = a.mean(axis=(1, 2, 3)), b.mean(axis=(1, 2, 3))      # one number per seed: independent
    return (da.mean() - db.mean()) / math.sqrt(da.var(ddof=1) / da.size + db.var(ddof=1) / db.size)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=48)
    ap.add_argument("--spp", type=int, nargs="+", default=[4, 16, 64])
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--samplers", nargs="+", default=["sobol", "sobol-affine", "independent"])
    ap.add_argument("--scenes", nargs="+", default=list(SCENES), choices=SCENES)
    args = ap.parse_args()
    import bench_vs_mitsuba as mb

    base = args.samplers[0]
    print(f"nee, {args.size}x{args.size}, depth {mb.DEPTH}, {args.seeds} seeds per sampler and spp; RMSE from the "
          f"variance across seeds (+- one standard error); time: median wall seconds per single-threaded render")
    print(f"| scene | spp | sampler | RMSE | over {base}'s | mean vs {base}'s (z) | s per render | "
          f"efficiency over {base}'s |")
    print("|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.scenes:
            desc = mb.SCENES[name]
            folder = Path(tmp) / name
            folder.mkdir()
            scene = mb.warp_scene(desc, folder)
            for s in args.samplers:                     # compile outside the timings
                render(scene, desc, 8, 1, s, 0)
            for spp in args.spp:
                imgs = {s: [] for s in args.samplers}
                secs = {s: [] for s in args.samplers}
                for seed in range(args.seeds):
                    order = args.samplers if seed % 2 == 0 else args.samplers[::-1]
                    for s in order:
                        img, dt = render(scene, desc, args.size, spp, s, 1000 + seed)
                        imgs[s].append(img)
                        secs[s].append(dt)
                ref = np.stack(imgs[base])
                r0, _ = error_stats(ref)
                t0 = statistics.median(secs[base])
                for s in args.samplers:
                    a = np.stack(imgs[s])
                    r, e = error_stats(a)
                    t = statistics.median(secs[s])
                    ratio, ratio_se = rmse_ratio(a, ref) if s != base else (1.0, 0.0)
                    z = "" if s == base else f"{bias_z(a, ref):+.1f}"
                    eff = (r0 * r0 * t0) / (r * r * t)
                    print(f"| {name} | {spp} | {s} | {r:.4g} +- {e:.2g} | {ratio:.3f} +- {ratio_se:.3f} | {z} | "
                          f"{t:.3f} | {eff:.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
