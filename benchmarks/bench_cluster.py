"""Distributed rendering: scaling on 1, 2 and 4 local worker processes, per-task overheads, and a model.

Prints three tables:

1. wall time and speed-up of one render of the built-in demo on a LocalCluster of 1, 2 and 4
   worker processes (one thread each), against the same render in this process on one thread;
2. the per-task overheads, measured on the cluster: scheduling a task (a round trip of a no-op),
   shipping and uploading the scene to a worker, returning one pass's float64 film and merging it;
3. the model fitted to them (see docs/cluster.md): expected speed-up for 8..256 workers and the
   smallest task that keeps overhead under 5%.

    python benchmarks/bench_cluster.py                 # 64x64, 128 spp, depth 6 (a few minutes)
    python benchmarks/bench_cluster.py --size 128 --spp 512

Compare ratios within one run: the machine is shared and absolute times drift.
"""

from __future__ import annotations

import argparse
import os
import pickle
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import warp_spt  # noqa: E402
from warp_spt import cluster  # noqa: E402
from warp_spt.demo import demo_files  # noqa: E402
from warp_spt.film import Film  # noqa: E402


def _noop(x):
    return x


def _zeros(n_pixels: int) -> np.ndarray:
    return np.zeros((n_pixels, 1, 3))


def _upload(key, scene) -> float:
    """Worker side: time to upload ``scene`` (the transfer happened before the task started)."""
    t = time.perf_counter()
    distributed_worker().plugins[cluster.PLUGIN_NAME].device_scene(key, scene)
    return time.perf_counter() - t


def distributed_worker():
    import distributed
    return distributed.get_worker()


def timed(fn, repeat: int = 1) -> float:
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


def scaling(scene, camera, kw: dict, workers: list[int], repeat: int) -> dict[int, float]:
    """Best wall seconds of ``repeat`` runs per worker count (0: this process, one thread).

    One cluster at a time, warmed first (scene uploaded, kernels loaded); every image is checked
    bit for bit against the in-process one.
    """
    ref = warp_spt.render_film(scene, camera, threads=1, **kw)      # also warms the kernel
    times = {0: min(timed(lambda: warp_spt.render_film(scene, camera, threads=1, **kw)) for _ in range(repeat))}
    for n in workers:
        with cluster.local_client(n) as client:
            cluster.render_film(client, scene, camera, **kw)
            film = [None]

            def run():
                film[0] = cluster.render_film(client, scene, camera, **kw)
            times[n] = min(timed(run) for _ in range(repeat))
            assert np.array_equal(film[0].sum, ref.sum), "cluster image differs from the single-process one"
    return times


def overheads(scene, kw: dict) -> dict[str, float]:
    """Per-task costs on a 1-worker LocalCluster, in seconds (and bytes)."""
    n = kw["width"] * kw["height"]
    out = {}
    with cluster.local_client(1) as client:
        cluster.register(client)
        client.submit(_noop, 0, pure=False).result()
        m = 200
        out["schedule"] = timed(lambda: client.gather([client.submit(_noop, i, pure=False) for i in range(m)]), 3) / m
        payload = len(pickle.dumps(scene, protocol=5))
        key, fut = cluster.share_scene(client, scene)
        t = time.perf_counter()
        upload = client.submit(_upload, key, fut, pure=False).result()
        out["scene_total"] = time.perf_counter() - t
        out["scene_upload"] = upload
        out["scene_bytes"] = payload
        big = 1 << 20                                  # a 1 Mpixel pass film: 24 MB of float64
        client.submit(_zeros, big, pure=False).result()
        out["film_per_pixel"] = max(0.0, timed(lambda: client.submit(_zeros, big, pure=False).result(), 3)
                                    - out["schedule"]) / big
        # one pass of this benchmark's render, on a worker: the rate of useful work
        settings = cluster.Settings(**kw)
        passes = cluster.pass_ranges(settings)
        cam = warp_spt.Camera()
        client.submit(cluster._render_task, key, fut, cam, settings, passes[:1], 1, pure=False).result()
        t_pass = timed(lambda: client.submit(cluster._render_task, key, fut, cam, settings, passes[:1], 1,
                                             pure=False).result(), 3)
        out["pass_seconds"] = t_pass - out["schedule"] - out["film_per_pixel"] * n
        out["pass_samples"] = passes[0][1]
    film = Film.empty(1024, 1024)
    part = np.ones((1024, 1024, 3))
    out["merge_per_pixel"] = timed(lambda: film.accumulate(part, 8), 5) / (1024 * 1024)
    return out


def model(o: dict, n_pixels: int, pass_seconds_per_pixel: float, workers: int, passes: int,
          passes_per_task: int) -> float:
    """Expected speed-up on ``workers`` (see docs/cluster.md for the derivation).

    Worker side: each task costs its passes' work plus one scheduling round trip, tasks spread
    evenly; the scene costs one shipment and upload per worker, in parallel. Client side (serial):
    every pass's film is received and merged on the client, one at a time.
    """
    w = pass_seconds_per_pixel * n_pixels                          # one pass's work, seconds
    tasks = -(-passes // passes_per_task)
    per_task = passes_per_task * w + o["schedule"]
    worker_time = o["scene_total"] + -(-tasks // workers) * per_task
    client_time = passes * n_pixels * (o["film_per_pixel"] + o["merge_per_pixel"]) + tasks * o["schedule"]
    return passes * w / max(worker_time, client_time)


def main() -> None:
    """Scaling, overheads, model."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--spp", type=int, default=128)
    parser.add_argument("--depth", type=int, default=6)
    parser.add_argument("--workers", type=int, nargs="*", default=[1, 2, 4])
    parser.add_argument("--repeat", type=int, default=2)
    args = parser.parse_args()
    scene = warp_spt.load_scene(*demo_files(), warn=lambda m: None)
    camera = warp_spt.Camera()
    kw = dict(width=args.size, height=args.size, spp=args.spp, max_depth=args.depth, seed=1)
    print(f"# built-in demo, {args.size}x{args.size}, {args.spp} spp, depth {args.depth}; "
          f"{os.cpu_count()} cores; passes of {cluster.pass_ranges(cluster.Settings(**kw))[0][1]} spp; "
          f"default tasks (4 per worker)")
    times = scaling(scene, camera, kw, args.workers, args.repeat)
    o = overheads(scene, kw)
    px = args.size * args.size
    per_px = o["pass_seconds"] / px
    settings = cluster.Settings(**kw)
    passes = len(cluster.pass_ranges(settings))
    cores = os.cpu_count() or 1
    print("\n| worker processes | seconds | speed-up vs 1 worker | vs 1 thread in-process | model (capped at "
          f"{cores} cores) |\n|---|---|---|---|---|")
    print(f"| (in-process, 1 thread) | {times[0]:.2f} | | 1.00 | |")
    for n in args.workers:
        per_task = len(cluster.tasks_for(settings, n)[0])
        predicted = model(o, px, per_px, min(n, cores), passes, per_task)
        print(f"| {n} | {times[n]:.2f} | {times[args.workers[0]] / times[n]:.2f} | {times[0] / times[n]:.2f} | "
              f"{predicted:.2f} |")

    print("\n| overhead (1-worker LocalCluster) | measured |\n|---|---|")
    print(f"| scheduling, per task (no-op round trip) | {o['schedule'] * 1e3:.2f} ms |")
    print(f"| scene: pickled size | {o['scene_bytes'] / 1e6:.1f} MB |")
    print(f"| scene: ship + upload to a fresh worker (first task) | {o['scene_total']:.2f} s "
          f"(upload {o['scene_upload']:.2f} s) |")
    print(f"| film: return one pass, per pixel (float64 RGB, 24 B) | {o['film_per_pixel'] * 1e9:.1f} ns "
          f"({24 / max(o['film_per_pixel'], 1e-12) / 1e9:.2f} GB/s) |")
    print(f"| film: merge one pass on the client, per pixel | {o['merge_per_pixel'] * 1e9:.1f} ns |")
    print(f"| work: one pass of {o['pass_samples']} spp, per pixel | {per_px * 1e6:.2f} us |")

    # The model on a production-sized job: 1920x1080, 1024 spp, passes of 8 spp (128 passes).
    n_big, passes = 1920 * 1080, 1024 // 8
    work_px = per_px * 8 / o["pass_samples"]
    print(f"\nModel, 1920x1080 at 1024 spp (128 passes of 8 spp; work {work_px * 1e6:.2f} us per pixel "
          "per pass as measured above):\n")
    print("| workers | 1024 spp, 1 pass/task | 1024 spp, default tasks | 4096 spp, default tasks |\n|---|---|---|---|")
    for n in (1, 2, 4, 8, 16, 32, 64, 128, 256):
        row = [model(o, n_big, work_px, n, passes, 1)]
        for p in (passes, 4 * passes):
            row.append(model(o, n_big, work_px, n, p, max(1, -(-p // (4 * n)))))
        print(f"| {n} | " + " | ".join(f"{s:.1f}" for s in row) + " |")
    limit = work_px / (o["film_per_pixel"] + o["merge_per_pixel"])
    print(f"\nclient ceiling (pass work / per-pass film cost per pixel): {limit:.0f} workers")
    print(f"task size for scheduling overhead < 5%: work per task > 20 x {o['schedule'] * 1e3:.2f} ms = "
          f"{20 * o['schedule']:.3f} s, i.e. > {20 * o['schedule'] / work_px:,.0f} pixel-passes "
          f"(> {20 * o['schedule'] / (work_px / 8):,.0f} pixel-samples)")
    for net, bw in (("1 GbE", 0.117e9), ("10 GbE", 1.17e9)):
        film = 24 / bw + o["merge_per_pixel"]
        print(f"on {net} (film {film * 1e9:.0f} ns per pixel-pass): client ceiling {work_px / film:.0f} workers")


if __name__ == "__main__":
    main()
