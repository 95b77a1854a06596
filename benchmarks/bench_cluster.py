"""Distributed rendering: scaling on 1, 2 and 4 local worker processes, per-task overheads, a model,
and what an animation frame saves by uploading only its changed meshes.

Prints:

1. wall time and speed-up of one render of the built-in demo on a LocalCluster of 1, 2 and 4
   worker processes (one thread each), against the same render in this process on one thread:
   once split by sample ranges (many passes), once a single pass split by row tiles only;
2. the per-task overheads, measured on the cluster: scheduling a task (a round trip of a no-op),
   shipping and uploading the scene to a worker, returning one pass's float64 film and merging it;
3. the model fitted to them (see docs/cluster.md): expected speed-up for 8..256 workers, with and
   without row tiles, and the smallest task that keeps overhead under 5%;
4. per animation frame (the demo animation of scripts/make_animation.py): upload time and bytes
   shipped with and without the static meshes cached.

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
from warp_spt.rendering.schedule import pass_ranges  # noqa: E402
from warp_spt.demo import demo_files  # noqa: E402
from warp_spt.rendering.film import Film  # noqa: E402
from warp_spt.rendering.settings import RenderSettings  # noqa: E402


def _noop(x):
    return x


def _zeros(n_pixels: int) -> np.ndarray:
    return np.zeros((n_pixels, 1, 3))


def _upload(key, scene, rs) -> float:
    """Worker side: time to upload ``scene`` (the transfer happened before the task started)."""
    t = time.perf_counter()
    distributed_worker().plugins[cluster.PLUGIN_NAME].device_scene(key, scene, rs)
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


def scaling(scene, camera, renders: dict[str, dict], workers: list[int], repeat: int) -> dict[str, dict[int, float]]:
    """Best wall seconds of ``repeat`` runs of each render per worker count (0: this process, one thread).

    One cluster at a time, warmed first (scene uploaded, kernels loaded); every image is checked
    bit for bit against the in-process one.
    """
    refs, times = {}, {name: {} for name in renders}
    for name, kw in renders.items():
        refs[name] = warp_spt.render_film(scene, camera, threads=1, **kw)      # also warms the kernel
        times[name][0] = min(timed(lambda: warp_spt.render_film(scene, camera, threads=1, **kw)) for _ in range(repeat))
    for n in workers:
        with cluster.local_client(n) as client:
            for name, kw in renders.items():
                cluster.render_film(client, scene, camera, **kw)
                film = [None]

                def run():
                    film[0] = cluster.render_film(client, scene, camera, **kw)
                times[name][n] = min(timed(run) for _ in range(repeat))
                assert np.array_equal(film[0].sum, refs[name].sum), "cluster image differs from the in-process one"
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
        rs = cluster.cluster_settings(RenderSettings(**kw))
        fut = client.scatter(scene, hash=False)
        key = cluster.scene_key(scene)
        t = time.perf_counter()
        upload = client.submit(_upload, key, fut, rs, pure=False).result()
        out["scene_total"] = time.perf_counter() - t
        out["scene_upload"] = upload
        out["scene_bytes"] = payload
        big = 1 << 20                                  # a 1 Mpixel pass film: 24 MB of float64
        client.submit(_zeros, big, pure=False).result()
        out["film_per_pixel"] = max(0.0, timed(lambda: client.submit(_zeros, big, pure=False).result(), 3)
                                    - out["schedule"]) / big
        # one pass of this benchmark's render, on a worker: the rate of useful work
        shared = cluster.share_scene(client, scene)
        passes = tuple(pass_ranges(rs.spp, rs.width, rs.height)[:1])
        cam = warp_spt.Camera()

        def one_pass():
            client.submit(cluster._render_task, shared.key, shared.parts, cam, rs, (0, rs.height), passes,
                          pure=False).result()
        one_pass()
        t_pass = timed(one_pass, 3)
        out["pass_seconds"] = t_pass - out["schedule"] - out["film_per_pixel"] * n
        out["pass_samples"] = passes[0][1]
    film = Film.empty(1024, 1024)
    part = np.ones((1024, 1024, 3))
    out["merge_per_pixel"] = timed(lambda: film.accumulate(part, 8), 5) / (1024 * 1024)
    return out


def model(o: dict, n_pixels: int, pass_seconds_per_pixel: float, workers: int, passes: int,
          passes_per_task: int, tiles: int = 1) -> float:
    """Expected speed-up on ``workers`` (see docs/cluster.md for the derivation).

    Worker side: each task (``passes_per_task`` passes of one of ``tiles`` row tiles) costs its
    work plus one scheduling round trip, tasks spread evenly; the scene costs one shipment and
    upload per worker, in parallel. Client side (serial): every pass's film is received and merged
    on the client (tiles split it, they do not shrink it), plus a round trip per task.
    """
    w = pass_seconds_per_pixel * n_pixels                          # one pass's work, seconds
    tasks = -(-passes // passes_per_task) * tiles
    per_task = passes_per_task * w / tiles + o["schedule"]
    worker_time = o["scene_total"] + -(-tasks // workers) * per_task
    client_time = passes * n_pixels * (o["film_per_pixel"] + o["merge_per_pixel"]) + tasks * o["schedule"]
    return passes * w / max(worker_time, client_time)


def animation_uploads(objs: list[str], mtls: list[str]) -> dict[str, float]:
    """Per frame of an OBJ sequence: upload seconds (best of frames 1..3) and bytes shipped, everything
    vs only what changed since the previous frame."""
    from dataclasses import replace

    from warp_spt.animation import ObjSequence
    from warp_spt.cluster import _array_key
    from warp_spt.upload.device_scene import DeviceScene, mesh_key

    seq = ObjSequence(objs, mtls)
    scenes = [seq.scene(k) for k in range(4)]
    DeviceScene(scenes[0])                                         # warm-up (first Warp allocations)
    full = min(timed(lambda: DeviceScene(sc)) for sc in scenes[1:])
    cache: dict = {}
    DeviceScene(scenes[0], meshes=cache)
    cached = min(timed(lambda: DeviceScene(sc, meshes=cache)) for sc in scenes[1:])
    sent = {mesh_key(m) for m in scenes[0].meshes} | {_array_key(t) for t in scenes[0].textures}
    changed = [m for m in scenes[1].meshes if mesh_key(m) not in sent]
    new_textures = [t for t in scenes[1].textures if _array_key(t) not in sent]
    return {"full_s": full, "cached_s": cached, "meshes": len(scenes[1].meshes), "changed": len(changed),
            "triangles": scenes[1].num_triangles, "changed_triangles": sum(len(m.indices) for m in changed),
            "full_bytes": len(pickle.dumps(scenes[1], protocol=5)),
            "changed_bytes": len(pickle.dumps((replace(scenes[1], meshes=[], textures=[]), changed, new_textures),
                                              protocol=5))}


def animations(folder: Path) -> dict[str, tuple[list[str], list[str]]]:
    """Two OBJ sequences: the demo animation (its vase, nearly all the triangles, twists every frame)
    and the built-in demo standing still while a 12-triangle box moves through it."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
    import make_animation

    out = {"demo animation (scripts/make_animation.py)": make_animation.write_scene(folder / "vase")}
    objs, mtls = demo_files()
    box = folder / "box"
    box.mkdir()
    for k in range(4):
        x0 = -5.0 + k
        corners = [(x0 + dx, 10.0 + dy, dz) for dx in (0, 2) for dy in (0, 2) for dz in (0, 2)]
        faces = ((1, 3, 4, 2), (5, 6, 8, 7), (1, 2, 6, 5), (3, 7, 8, 4), (1, 5, 7, 3), (2, 4, 8, 6))
        (box / f"box_{k}.obj").write_text("usemtl Box1\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in corners)
                                          + "".join("f " + " ".join(map(str, f)) + "\n" for f in faces))
    out["built-in demo + a moving 12-triangle box"] = (list(objs) + [str(box / "box_{frame}.obj")], list(mtls))
    return out


def main() -> None:
    """Scaling, overheads, model, animation uploads."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=64)
    parser.add_argument("--spp", type=int, default=128)
    parser.add_argument("--tile-size", type=int, default=192, help="image side of the single-pass (tiles only) render")
    parser.add_argument("--depth", type=int, default=6)
    parser.add_argument("--workers", type=int, nargs="*", default=[1, 2, 4])
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--animation-only", action="store_true", help="only the per-frame upload table")
    args = parser.parse_args()
    if args.animation_only:
        return animation_table()
    scene = warp_spt.load_scene(*demo_files(), warn=lambda m: None)
    camera = warp_spt.Camera()
    kw = dict(width=args.size, height=args.size, spp=args.spp, max_depth=args.depth, seed=1)
    t = args.tile_size
    tile_kw = dict(kw, width=t, height=t, spp=cluster.samples_per_pass(t, t))
    rs = RenderSettings(**kw)
    load = os.getloadavg()
    print(f"# built-in demo, depth {args.depth}; {os.cpu_count()} cores; load average at start "
          f"{load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (1 / 5 / 15 min)")
    print(f"# passes: {args.size}x{args.size} at {args.spp} spp = {len(pass_ranges(rs.spp, rs.width, rs.height))} passes of "
          f"{pass_ranges(rs.spp, rs.width, rs.height)[0][1]} spp, default tasks; {t}x{t} at {tile_kw['spp']} spp = one pass, "
          "split into row tiles only (default tiles: 4 tasks per worker)")
    times = scaling(scene, camera, {"passes": kw, "tiles": tile_kw}, args.workers, args.repeat)
    o = overheads(scene, kw)
    px = args.size * args.size
    per_px = o["pass_seconds"] / px
    passes = len(pass_ranges(rs.spp, rs.width, rs.height))
    cores = os.cpu_count() or 1
    print(f"\nload average after the scaling runs: {os.getloadavg()[0]:.1f}")
    print("\n| worker processes | sample ranges: seconds | speed-up vs 1 thread in-process | model (capped at "
          f"{cores} cores) | row tiles: seconds | speed-up vs 1 thread in-process | model |\n|---|---|---|---|---|---|---|")
    print(f"| (in-process, 1 thread) | {times['passes'][0]:.2f} | 1.00 | | {times['tiles'][0]:.2f} | 1.00 | |")
    tile_rs = RenderSettings(**tile_kw)
    for n in args.workers:
        per_task = len(cluster.plan(rs, n)[0].passes)
        predicted = model(o, px, per_px, min(n, cores), passes, per_task)
        n_tiles = len({task.rows for task in cluster.plan(tile_rs, n)})
        tile_pred = model(o, t * t, per_px * tile_kw["spp"] / o["pass_samples"], min(n, cores), 1, 1, n_tiles)
        print(f"| {n} | {times['passes'][n]:.2f} | {times['passes'][0] / times['passes'][n]:.2f} | {predicted:.2f} | "
              f"{times['tiles'][n]:.2f} | {times['tiles'][0] / times['tiles'][n]:.2f} | {tile_pred:.2f} |")

    print("\n| overhead (1-worker LocalCluster) | measured |\n|---|---|")
    print(f"| scheduling, per task (no-op round trip) | {o['schedule'] * 1e3:.2f} ms |")
    print(f"| scene: pickled size | {o['scene_bytes'] / 1e6:.1f} MB |")
    print(f"| scene: ship + upload to a fresh worker (first task) | {o['scene_total']:.2f} s "
          f"(upload {o['scene_upload']:.2f} s) |")
    print(f"| film: return one pass, per pixel (float64 RGB, 24 B) | {o['film_per_pixel'] * 1e9:.1f} ns "
          f"({24 / max(o['film_per_pixel'], 1e-12) / 1e9:.2f} GB/s) |")
    print(f"| film: merge one pass on the client, per pixel | {o['merge_per_pixel'] * 1e9:.1f} ns |")
    print(f"| work: one pass of {o['pass_samples']} spp, per pixel | {per_px * 1e6:.2f} us |")

    # The model on production-sized jobs: 1920x1080, passes of 8 spp.
    n_big = 1920 * 1080
    work_px = per_px * 8 / o["pass_samples"]
    print(f"\nModel, 1920x1080, passes of 8 spp (work {work_px * 1e6:.2f} us per pixel per pass as measured "
          "above); default tasks = about 4 per worker; tiles = row tiles added until there are 4 tasks per worker:\n")
    print("| workers | 1024 spp, 1 pass/task | 1024 spp, default tasks | 1024 spp, default tasks + tiles | "
          "4096 spp, default tasks | 64 spp, default tasks | 64 spp, default tasks + tiles |\n|---|---|---|---|---|---|---|")
    for n in (1, 2, 4, 8, 16, 32, 64, 128, 256):
        row = [model(o, n_big, work_px, n, 128, 1)]
        for p, tiled in ((128, False), (128, True), (512, False), (8, False), (8, True)):
            per_task = max(1, -(-p // (4 * n)))
            tiles = max(1, -(-(4 * n) // -(-p // per_task))) if tiled else 1
            row.append(model(o, n_big, work_px, n, p, per_task, min(tiles, 1080)))
        print(f"| {n} | " + " | ".join(f"{x:.1f}" for x in row) + " |")
    limit = work_px / (o["film_per_pixel"] + o["merge_per_pixel"])
    print(f"\nclient ceiling (pass work / per-pass film cost per pixel): {limit:.0f} workers")
    print(f"task size for scheduling overhead < 5%: work per task > 20 x {o['schedule'] * 1e3:.2f} ms = "
          f"{20 * o['schedule']:.3f} s, i.e. > {20 * o['schedule'] / work_px:,.0f} pixel-passes "
          f"(> {20 * o['schedule'] / (work_px / 8):,.0f} pixel-samples); a row tile of 1920 pixels holds "
          f"{20 * o['schedule'] / work_px / 1920:,.1f} rows x passes of it")
    for net, bw in (("1 GbE", 0.117e9), ("10 GbE", 1.17e9)):
        film = 24 / bw + o["merge_per_pixel"]
        print(f"on {net} (film {film * 1e9:.0f} ns per pixel-pass): client ceiling {work_px / film:.0f} workers")

    animation_table()


def animation_table() -> None:
    """Print the per-frame upload and shipping table."""
    import tempfile

    print("\nPer animation frame: upload (DeviceScene, in-process or on a worker; best of 3 frames) and bytes "
          "shipped to the cluster, everything vs only what changed:\n")
    print("| sequence | triangles (changing) | upload: everything | only changed | saving | shipped: everything "
          "| only changed | saving |\n|---|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as folder:
        for name, (objs, mtls) in animations(Path(folder)).items():
            a = animation_uploads(objs, mtls)
            print(f"| {name} | {a['triangles']:,} ({a['changed_triangles']:,}) | {a['full_s'] * 1e3:.0f} ms | "
                  f"{a['cached_s'] * 1e3:.0f} ms | {(1 - a['cached_s'] / a['full_s']) * 100:.0f}% | "
                  f"{a['full_bytes'] / 1e6:.2f} MB | {a['changed_bytes'] / 1e3:,.1f} kB | "
                  f"{(1 - a['changed_bytes'] / a['full_bytes']) * 100:.0f}% |")


if __name__ == "__main__":
    main()
