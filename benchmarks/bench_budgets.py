"""Budgets and adaptive sampling, measured: is the time budget met, does a target error land near
the target, and what does adaptive sampling gain at equal time?

    python benchmarks/bench_budgets.py             # 64x64, three scenes (about 10 minutes on 2 busy cores)
    python benchmarks/bench_budgets.py --quick     # 32x32, fewer budgets

1. Time budget (CLI): ``python -m warp_spt ... --time-budget T`` as a subprocess; its whole wall time
   (interpreter start, Warp import, load, compile, render, save, exit) over T.
2. Time budget (API): render_progressive(time_budget=T) on an uploaded scene; elapsed over T.
3. Target error: render_progressive(target_error=E); the measured relative error (docs/error.md)
   against a reference of many more samples, with the reference's own estimated error removed in
   quadrature, over E.
4. Adaptive at equal time: uniform and adaptive renders with the same time budget, adaptive once per
   metric (``--metrics relative,rmse``: what it minimises); RMSE and relative error against the
   reference (its noise removed); gain = uniform / adaptive. Also at equal work
   (the adaptive render given the uniform one's pixel-samples), which separates the allocation
   from the throughput (adaptive passes go to costly pixels).
5. Sample cost (``--parts cost``): what a sample costs beyond its rays (progressive.SAMPLE_COST_RAYS).

Scenes: the built-in demo (gradient sky, depth 8); a closed Cornell room with a small light, a glossy
and a glass ball (tests/stability_scenes); an open scene (a floor and two balls under a uniform sky,
where pixels that see only sky are exact: uneven noise).
"""

from __future__ import annotations

import argparse
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING   # no banner or module-load lines (Warp 1.19 dropped config.quiet)

from warp_spt import Camera, Sky, load_scene  # noqa: E402
from warp_spt.upload.device_scene import DeviceScene  # noqa: E402
from warp_spt.demo import demo_files  # noqa: E402
from warp_spt.rendering.progressive import render_progressive  # noqa: E402
from warp_spt.rendering.result import relative_error  # noqa: E402


def scenes(tmp: Path):
    from tests.support.scenes import material
    from tests.support.stability_scenes import (
        cornell_camera,
        cornell_files,
        quads_obj,
        write_scene_files,
    )

    demo = (demo_files(), None, dict(max_depth=8, sky=Sky.gradient()), [])
    cornell = (cornell_files(tmp), cornell_camera(), dict(max_depth=6, sky=Sky.constant(0, 0, 0)),
               ["-cam", "16", "1", "16", "0", "1", "-0.05", "75", "1", "0", "--sky-color", "0", "0", "0", "-depth", "6"])
    obj = quads_obj([("floor", [(-8, -8, 0), (8, -8, 0), (8, 8, 0), (-8, 8, 0)])],
                    spheres=[("ball", (-1.2, 0.0, 1.0), 1.0), ("glass", (1.3, 0.5, 0.8), 0.8)])
    mtl = (material("floor", Kd=(0.6, 0.6, 0.6), Roughness=1) + material("ball", Kd=(0.8, 0.3, 0.2), Roughness=1)
           + material("glass", Kd=(0.95, 0.95, 0.95), Kt=(0.95, 0.95, 0.95), Roughness=0, Fuzz=0, Kn=1.5,
                      Refractable=True))
    open_files = write_scene_files(tmp, "open", obj, mtl)
    cam = Camera(position=(0.0, -7.0, 2.0), direction=(0.0, 1.0, -0.2), fov=50.0, aperture=0.0, focus=7.0)
    open_ = (open_files, cam, dict(max_depth=6, sky=Sky.constant(1, 1, 1)),
             ["-cam", "0", "-7", "2", "0", "1", "-0.2", "50", "7", "0", "--sky-color", "1", "1", "1", "-depth", "6"])
    return {"demo": demo, "cornell": cornell, "open": open_}


def cli_wall_time(files, cli_cam, size: int, budget: float, out: Path) -> tuple[float, int, bool]:
    """The CLI's whole wall time from the shell's point of view, its spp, and whether it said the budget
    is shorter than start-up plus one pass."""
    objs, mtls = files
    args = [a for o in objs for a in ("-obj", o)] + [a for m in mtls for a in ("-mtl", m)] if cli_cam else []
    cmd = [sys.executable, "-m", "warp_spt", *args, *cli_cam, "-res", str(size), str(size), "--time-budget",
           str(budget), "-out", str(out)]
    if not cli_cam:
        cmd += ["-sky", "1", "-depth", "8"]
    t = time.perf_counter()
    err = subprocess.run(cmd, check=True, env=dict(os.environ, PYTHONPATH=str(ROOT)), capture_output=True,
                         text=True).stderr
    wall = time.perf_counter() - t
    wrote = [line for line in err.splitlines() if " wrote " in line]
    spp = int(wrote[-1].split("(")[1].split(" spp")[0].split("..")[-1]) if wrote else 0
    return wall, spp, "is less than start-up" in err


def ceiling(ref) -> tuple[float, float]:
    """The most any allocation can gain at equal work: RMSE and relative-error ratio (uniform over optimal)
    for an oracle that knows every pixel's variance (from the reference's batches) and gives each pixel
    samples in proportion to its standard deviation (not its cost): sqrt(mean v) / mean sqrt(v).

    The variances are the reference's estimates (8 batches: 7 degrees of freedom per channel), whose
    noise widens the spread the oracle sees: mean sqrt(v_hat) falls short of mean sqrt(v) by
    E sqrt(chi2_nu / nu), 0.965 for nu = 7 and 0.988 for nu = 21 (three independent channels), so
    the figure overstates the true ceiling by 1-4% (docs/error.md)."""
    var = np.nan_to_num(ref.std_error.astype(np.float64) ** 2 * ref.spp[..., None]).mean(axis=2)
    img = ref.image.astype(np.float64)
    rel = np.nan_to_num(ref.std_error.astype(np.float64) ** 2 * ref.spp[..., None]
                        / np.maximum(img, 0.1 * img.mean()) ** 2).mean(axis=2)
    return tuple(math.sqrt(v.mean()) / np.sqrt(v).mean() for v in (var, rel))


def sample_cost(dev, cam: Camera, kw: dict) -> tuple[float, float, float, float]:
    """What a sample costs beyond its rays: one thread, 64 spp, best of 3, of the scene's view and of a
    view straight up (every sample one ray that misses, or one hit on the demo's sky box). Fits
    seconds per sample = a x rays per sample + b through the two; returns (rays per sample of the
    scene, us per sample of each view, b / a: the per-sample cost in rays that progressive.
    SAMPLE_COST_RAYS stands for)."""
    up = Camera(position=cam.position, direction=(0.0, 0.0, 1.0), fov=20.0, aperture=0.0, focus=7.0)   # Z is up
    rows = []
    for view in (up, cam):
        best = math.inf
        for rep in range(3):
            r = render_progressive(dev, view, spp=64, seed=rep, **dict(kw, threads=1))
            best = min(best, r.stats.render_seconds / r.stats.pixel_samples)
        rows.append((r.stats.rays / r.stats.pixel_samples, best))
    (r1, t1), (r2, t2) = rows
    if r1 > 1.05 or r2 <= r1:          # a closed room: looking up hits the ceiling, no fit
        return r2, t1 * 1e6, t2 * 1e6, math.nan
    a = (t2 - t1) / (r2 - r1)
    return r2, t1 * 1e6, t2 * 1e6, (t1 - a * r1) / a


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--parts", default="time,error,adaptive", help="comma-separated: time, error, adaptive, cost")
    ap.add_argument("--scenes", default="demo,cornell,open")
    ap.add_argument("--seeds", type=int, default=2, help="seeds per adaptive comparison")
    ap.add_argument("--budgets", help="comma-separated time budgets in seconds (default 4,8,16; --quick 3,6)")
    ap.add_argument("--adaptive-budget", type=float, help="seconds per adaptive comparison (default the largest budget)")
    ap.add_argument("--metrics", default="relative,rmse", help="adaptive metrics to compare (relative, rmse)")
    ap.add_argument("--ref-factor", type=float, default=20.0, help="reference samples over the largest budget's")
    args = ap.parse_args()
    parts = set(args.parts.split(","))
    size = 32 if args.quick else 64
    budgets = (3.0, 6.0) if args.quick else (4.0, 8.0, 16.0)
    if args.budgets:
        budgets = tuple(float(b) for b in args.budgets.split(","))
    adaptive_budget = args.adaptive_budget or max(budgets)
    metrics = args.metrics.split(",")
    tmp = Path(tempfile.mkdtemp())
    print(f"{size}x{size} pixels; {os.cpu_count()} cores; load average {os.getloadavg()[0]:.1f} at the start\n")
    rows_t, rows_e, rows_a, rows_c = [], [], [], []
    for name, (files, cam, kw, cli_cam) in scenes(tmp).items():
        if name not in args.scenes.split(","):
            continue
        dev = DeviceScene(load_scene(*files, warn=lambda m: None))
        kw = dict(kw, width=size, height=size)
        render_progressive(dev, cam, spp=2, **kw)                                  # compile once
        probe = render_progressive(dev, cam, spp=64, seed=11, **kw)
        rate = probe.stats.pixel_samples / probe.stats.render_seconds
        print(f"[{name}] {rate / 1e6:.2f} M samples/s", flush=True)
        if parts & {"error", "adaptive"}:
            # reference: about 20x the samples of the largest budget
            ref_spp = int(min(1 << 14, args.ref_factor * rate * max(budgets) / (size * size)))
            t = time.perf_counter()
            ref = render_progressive(dev, cam, spp=ref_spp, seed=7919, **kw)
            ref_img = ref.image.astype(np.float64)
            ref_mse = float(np.nanmean(ref.std_error.astype(np.float64) ** 2))
            print(f"  reference {ref_spp} spp in {time.perf_counter() - t:.0f} s, estimated relative error "
                  f"{ref.relative_error:.2%}", flush=True)

        def measured(res):
            rel = relative_error(res.image - ref_img, ref_img)
            rel_c = math.sqrt(max(rel**2 - ref.relative_error**2, 0.0))
            mse = max(float(np.mean((res.image - ref_img) ** 2)) - ref_mse, 0.0)
            return rel_c, math.sqrt(mse)

        for budget in budgets if "time" in parts else ():
            wall, cli_spp, too_short = cli_wall_time(files, cli_cam, size, budget, tmp / f"{name}.png")
            res = render_progressive(dev, cam, time_budget=budget, seed=3, **kw)
            rows_t.append((name, budget, wall / budget, cli_spp, too_short, res.stats.seconds / budget, res.spp_total))
            print(f"  time budget {budget:>4.0f} s: CLI wall {wall:6.2f} s ({wall / budget:.3f}x, {cli_spp} spp"
                  f"{', said: shorter than start-up + one pass' if too_short else ''}), "
                  f"API {res.stats.seconds:6.2f} s ({res.stats.seconds / budget:.3f}x), {res.spp_total} spp",
                  flush=True)
        e_now = probe.relative_error
        for target in (e_now / 2, e_now / 4) if "error" in parts else ():
            res = render_progressive(dev, cam, target_error=target, seed=5, **kw)
            rel_c, _ = measured(res)
            rows_e.append((name, target, rel_c / target, res.relative_error / target, res.spp_total))
            print(f"  target error {target:.2%}: estimated {res.relative_error:.2%}, measured {rel_c:.2%} "
                  f"({rel_c / target:.3f}x target), {res.spp_total} spp, {res.stats.seconds:.1f} s", flush=True)
        if "cost" in parts:
            rps, t_up, t_scene, per_sample = sample_cost(dev, cam or Camera(), kw)
            rows_c.append((name, rps, t_up, t_scene, per_sample))
            print(f"  a sample looking up {t_up:.2f} us (1 ray), of the view {t_scene:.2f} us ({rps:.2f} rays): "
                  f"{per_sample:+.2f} rays per sample beyond its rays", flush=True)
        if "adaptive" not in parts:
            continue
        budget = adaptive_budget
        gains = {m: [] for m in metrics}
        for seed in range(21, 21 + args.seeds):
            u = render_progressive(dev, cam, time_budget=budget, seed=seed, **kw)
            ru, mu = measured(u)
            print(f"  equal time {budget:.0f} s, seed {seed}: uniform RMSE {mu:.4g} (rel {ru:.2%}, {u.spp_total} spp, "
                  f"{u.stats.rays / u.stats.render_seconds / 1e6:.2f} Mrays/s)", flush=True)
            for m in metrics:
                a = render_progressive(dev, cam, time_budget=budget, adaptive=True, adaptive_metric=m, seed=seed, **kw)
                w = render_progressive(dev, cam, sample_budget=u.stats.pixel_samples, adaptive=True,
                                       adaptive_metric=m, seed=seed, **kw)
                (ra, ma), (rw, mw) = measured(a), measured(w)
                speed = (a.stats.rays / a.stats.render_seconds) / (u.stats.rays / u.stats.render_seconds)
                gains[m].append((mu / ma, ru / ra, mu / mw, ru / rw, speed))
                print(f"    adaptive {m:>8}: RMSE {ma:.4g} (rel {ra:.2%}, {a.spp.min()}..{a.spp.max()} spp, mean "
                      f"{a.spp.mean():.0f}, {a.stats.rays / a.stats.render_seconds / 1e6:.2f} Mrays/s); equal work "
                      f"RMSE {mw:.4g} (rel {rw:.2%})", flush=True)
        c = ceiling(ref)
        for m in metrics:
            g = np.mean(gains[m], axis=0)
            rows_a.append((name, m, *g, *c))
            print(f"  adaptive ({m}) gain at equal time: RMSE x{g[0]:.2f}, relative error x{g[1]:.2f}; at equal "
                  f"work: RMSE x{g[2]:.2f}, relative error x{g[3]:.2f}; rays per second x{g[4]:.2f}", flush=True)
        print(f"  per-pixel oracle at equal work: RMSE x{c[0]:.2f}, relative error x{c[1]:.2f}\n", flush=True)

    print(f"summary (load average {os.getloadavg()[0]:.1f} at the end)")
    if rows_t:
        print("| scene | budget s | CLI wall / budget | CLI spp | CLI said too short | API / budget | API spp |")
        print("|---|---|---|---|---|---|---|")
        for r in rows_t:
            print(f"| {r[0]} | {r[1]:g} | {r[2]:.3f} | {r[3]} | {'yes' if r[4] else 'no'} | {r[5]:.3f} | {r[6]} |")
    if rows_e:
        print("\n| scene | target | measured / target | estimated / target | spp |")
        print("|---|---|---|---|---|")
        for r in rows_e:
            print(f"| {r[0]} | {r[1]:.2%} | {r[2]:.3f} | {r[3]:.3f} | {r[4]} |")
    if rows_c:
        print("\n| scene | rays per sample | us per sample, looking up (1 ray) | us per sample, the view | fitted cost "
              "per sample beyond its rays, in rays |")
        print("|---|---|---|---|---|")
        for r in rows_c:
            print(f"| {r[0]} | {r[1]:.2f} | {r[2]:.2f} | {r[3]:.2f} | {r[4]:+.2f} |")
    if rows_a:
        print("\n| scene | metric | equal time: RMSE gain (uniform / adaptive) | relative-error gain | equal work: "
              "RMSE gain | relative-error gain | rays/s adaptive / uniform | oracle per pixel, equal work: RMSE "
              "| relative error |")
        print("|---|---|---|---|---|---|---|---|---|")
        for r in rows_a:
            print(f"| {r[0]} | {r[1]} | {r[2]:.2f} | {r[3]:.2f} | {r[4]:.2f} | {r[5]:.2f} | {r[6]:.2f} | {r[7]:.2f} "
                  f"| {r[8]:.2f} |")


if __name__ == "__main__":
    main()
