"""Closest-hit rays/s of our intersector against a bare ``wp.mesh_query_ray`` kernel (issue 8, "Raw speed").

The same rays (the camera's sample-0 primary rays, exactly those the path kernel traces, or random
rays from inside the scene's box) go through a ladder of kernels, each adding one piece of what a
render does, so the gaps between rungs say where the time goes:

    bare            wp.mesh_query_ray on the mesh id (a kernel argument); the reference
    bare+struct     the same query, the id read from the Geometry struct argument
    tlas loop       the TLAS traversal of geometry.py, forced even for small scenes (small_scene=0)
    closest_hit     geometry.make_closest_hit as the renderer uses it
    + surface_at    closest_hit, then the shading-point description (shading.make_shading)
    + film f32/f64  ... and the result added to a float32 / float64 film
    camera samples  the path kernel's start_path alone (sampler, camera ray), stored: no ray traced
    path d=1        the integrator's own kernel at depth 1, 1 spp: one closest-hit ray per pixel
                    (the same rays as the rows above), emission, sky, film
    render d=1      renderer.render() at depth 1, 1 spp: tiles, launches, threads, film read-back
    render d=6      a real render: 8 spp, depth 6, closest-hit rays/s from its own ray count

Rates are rays per second (pixel-samples for the path rows: one closest-hit ray each at depth 1),
best of --repeat, and each row's ratio to the bare kernel of the same run. One-thread times are the
launching thread's CPU time (the launch is synchronous on the CPU), so another process sharing the
core does not inflate them; two-thread times are wall time, and need an idle machine. Scenes with several
objects have no single mesh to query bare: their reference is one wp.Mesh of all their triangles
(spheres left out), so there the ratio is only indicative. Threads 2 splits the rays into chunks
launched from a pool of 2 Python threads (Warp releases the GIL in a launch), as the renderer does.

    python benchmarks/bench_rays.py              # 512x512 rays, 1 and 2 threads, 4 scenes
    python benchmarks/bench_rays.py --quick      # 128x128, a smoke run
    python benchmarks/bench_rays.py --small-scene --size 256   # where the item loop beats the TLAS
    python benchmarks/bench_rays.py --integrator nee --sampler sobol   # path rows with the default estimator
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import warp as wp  # noqa: E402

wp.config.quiet = True

import warp_spt.rendering.tiles as R
from warp_spt.core.device_scene import DeviceScene, Features, Geometry  # noqa: E402
from warp_spt.core.geometry import KIND_MISS, NO_HIT, make_closest_hit  # noqa: E402
from warp_spt.core.lights import light_table, sky_emits  # noqa: E402
from warp_spt.core.surface import make_surface  # noqa: E402
from warp_spt.demo import demo_files  # noqa: E402
from warp_spt.integrators import (  # noqa: E402
    CameraParams,
    RenderParams,
    camera_params,
    get_kernel,
    get_step,
)
from warp_spt.io.loader import load_scene  # noqa: E402
from warp_spt.scene.camera import Camera  # noqa: E402
from warp_spt.scene.sky import Sky  # noqa: E402

CHUNK = 4096          # rays per launch in the threaded runs (the renderer's TILE_PIXELS)
SPP = 8               # "... 8 spp *" rows: samples 0..7 of each pixel, 8 per launch as render() does; the
DEPTH = 6             # rate counts every closest-hit ray (other rays than the bare kernel's: the ratio
                      # compares kernels, not rays; at depth 6 most rays are secondary, incoherent ones)


# --------------------------------------------------------------------------------------------
# Rays


INTEGRATOR, SAMPLER = "seed", "independent"    # the path rows' estimator (--integrator, --sampler): the
                                               # seed's traces only closest-hit rays, like the bare kernel
SKY = Sky.gradient()


def path_features(dev: DeviceScene) -> Features:
    """The feature set render() compiles for this scene and SKY."""
    return replace(dev.features, sky=sky_emits(SKY))


def camera_ray_kernel(dev: DeviceScene) -> wp.Kernel:
    """Sample 0 of every pixel, drawn by the path kernel's own start_path (so: the same rays)."""
    _step, start_path = get_step(INTEGRATOR, SAMPLER, path_features(dev))

    @wp.kernel(enable_backward=False, module="unique")
    def rays(cam: CameraParams, width: int, start: int, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3)):
        pix = start + wp.tid()
        p = start_path(cam, pix, width, wp.uint32(0), 0)
        o[pix] = p.o
        d[pix] = p.d

    return rays


def camera_rays(dev: DeviceScene, cam: Camera, size: int) -> tuple[wp.array, wp.array]:
    o = wp.zeros(size * size, dtype=wp.vec3)
    d = wp.zeros(size * size, dtype=wp.vec3)
    wp.launch(camera_ray_kernel(dev), dim=size * size, inputs=[camera_params(cam, size, size), size, 0, o, d])
    return o, d


def random_rays(bounds: np.ndarray, n: int, seed: int = 1) -> tuple[wp.array, wp.array]:
    """Origins uniform in the middle 80% of the scene's box, directions uniform on the sphere."""
    rng = np.random.default_rng(seed)
    lo, hi = bounds[0], bounds[1]
    o = lo + (hi - lo) * rng.uniform(0.1, 0.9, size=(n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return wp.array(o.astype(np.float32), dtype=wp.vec3), wp.array(d.astype(np.float32), dtype=wp.vec3)


# --------------------------------------------------------------------------------------------
# The ladder of kernels


@wp.kernel(enable_backward=False)
def _bare(mesh: wp.uint64, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), start: int,
          t_out: wp.array(dtype=float), face_out: wp.array(dtype=int)):
    i = start + wp.tid()
    q = wp.mesh_query_ray(mesh, o[i], d[i], NO_HIT)
    t_out[i] = wp.where(q.result, q.t, NO_HIT)
    face_out[i] = wp.where(q.result, q.face, -1)


def make_ladder(features: Features) -> dict[str, wp.Kernel]:
    """The kernels between the bare query and the renderer, for one feature set."""
    closest_hit = make_closest_hit(features)
    surface_at = make_surface(features)
    tlas_hit = make_closest_hit(features, small_scene=0) if _has_tlas_switch() else closest_hit

    @wp.kernel(enable_backward=False, module="unique")
    def bare_struct(s: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), start: int,
                    t_out: wp.array(dtype=float), face_out: wp.array(dtype=int)):
        i = start + wp.tid()
        q = wp.mesh_query_ray(s.mesh_ids[0], o[i], d[i], NO_HIT)
        t_out[i] = wp.where(q.result, q.t, NO_HIT)
        face_out[i] = wp.where(q.result, q.face, -1)

    def hit_kernel(hit_fn):
        @wp.kernel(enable_backward=False, module="unique")
        def hit(s: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), start: int,
                t_out: wp.array(dtype=float), face_out: wp.array(dtype=int)):
            i = start + wp.tid()
            h = hit_fn(s, o[i], d[i], NO_HIT)
            t_out[i] = h.t
            face_out[i] = wp.where(h.kind == KIND_MISS, -1, h.face)
        return hit

    def shade_kernel(vec, add: bool):
        """closest_hit, surface_at, then the shading normal stored (add False) or added to a film."""
        @wp.kernel(enable_backward=False, module="unique")
        def shade(s: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), start: int,
                  t_out: wp.array(dtype=float), face_out: wp.array(dtype=int), film: wp.array(dtype=vec)):
            i = start + wp.tid()
            h = closest_hit(s, o[i], d[i], NO_HIT)
            t_out[i] = h.t
            face_out[i] = wp.where(h.kind == KIND_MISS, -1, h.face)
            L = wp.vec3(0.0)
            if h.kind != KIND_MISS:
                L = surface_at(s, h, o[i], d[i]).ns
            if wp.static(add):
                film[i] = film[i] + vec(L)
            else:
                film[i] = vec(L)
        return shade

    return {"bare+struct": bare_struct, "tlas loop": hit_kernel(tlas_hit), "closest_hit": hit_kernel(closest_hit),
            "+ surface_at": shade_kernel(wp.vec3, False), "+ film f32": shade_kernel(wp.vec3, True),
            "+ film f64": shade_kernel(wp.vec3d, True)}


def _has_tlas_switch() -> bool:
    """Whether geometry.make_closest_hit can be told to traverse the TLAS always (small_scene=0)."""
    import inspect
    return "small_scene" in inspect.signature(make_closest_hit).parameters


# --------------------------------------------------------------------------------------------
# Timing


def interleaved(runs: dict[str, callable], repeat: int, clock=time.perf_counter) -> dict[str, float]:
    """Best time of each run, the runs taken in turn ``repeat`` times: the machine is shared, and
    taking turns spreads its slow spells over every row instead of one."""
    for fn in runs.values():
        fn()                                   # warm-up (and load)
    best = dict.fromkeys(runs, float("inf"))
    for _ in range(repeat):
        for label, fn in runs.items():
            t = clock()
            fn()
            best[label] = min(best[label], clock() - t)
    return best


_pools: dict[int, ThreadPoolExecutor] = {}


def launcher(kernel, n: int, inputs, threads: int):
    """A function launching ``kernel`` over n items, ``inputs(start)`` its arguments for the items
    from ``start`` on: one launch on one thread, or CHUNK-sized launches from a pool of ``threads``."""
    if threads == 1:
        return lambda: wp.launch(kernel, dim=n, inputs=inputs(0))
    chunks = [(lo, min(n, lo + CHUNK)) for lo in range(0, n, CHUNK)]
    pool = _pools.setdefault(threads, ThreadPoolExecutor(max_workers=threads))
    return lambda: list(pool.map(lambda c: wp.launch(kernel, dim=c[1] - c[0], inputs=inputs(c[0])), chunks))


def ladder_runs(dev: DeviceScene, bare_mesh: wp.Mesh, o: wp.array, d: wp.array, ladder: dict[str, wp.Kernel],
                threads: int) -> tuple[dict, dict]:
    """The ray kernels as runs, and the (t, face) arrays each writes."""
    n = o.shape[0]
    outs = {label: (wp.zeros(n, dtype=float), wp.zeros(n, dtype=int)) for label in ["bare", *ladder]}
    extra = {"+ surface_at": wp.vec3, "+ film f32": wp.vec3, "+ film f64": wp.vec3d}
    runs = {"bare": launcher(_bare, n, lambda lo: [bare_mesh.id, o, d, lo, *outs["bare"]], threads)}
    for label, k in ladder.items():
        if label == "bare+struct" and len(dev.scene.meshes) != 1:
            continue                           # mesh 0 alone is not the scene
        after = list(outs[label]) + ([wp.zeros(n, dtype=extra[label])] if label in extra else [])
        runs[label] = launcher(k, n, lambda lo, after=after: [dev.geometry, o, d, lo, *after], threads)
    return runs, outs


def path_runs(dev: DeviceScene, cam: Camera, size: int, threads: int) -> dict:
    """Camera samples alone, the integrator's kernel at depth 1 (one closest-hit ray per pixel), 1 spp;
    render() at depth 1 (default tiles, one tile, 8 spp) and at depth 6, 8 spp. Also returns the
    rays each row traces where that is not one per pixel."""
    n = size * size
    feats = path_features(dev)
    kernel = get_kernel(feats, integrator=INTEGRATOR, sampler=SAMPLER)
    film = wp.zeros(n, dtype=wp.vec3d)
    counters = wp.zeros((n, 2), dtype=wp.int64)
    fixed = [dev.geometry, dev.materials, dev.textures(), light_table(dev, SKY), camera_params(cam, size, size)]

    def inputs(depth):
        def at(lo):
            p = RenderParams()
            p.width, p.pixel_start, p.sample_start, p.sample_count = size, lo, 0, 1
            p.max_depth, p.roulette_depth, p.seed = depth, 0, wp.uint32(0)
            return [*fixed, p, film, counters, None]
        return at

    rays = {f"render d=1, {SPP} spp *": n * SPP}

    def render(tile, spp=1, depth=1, label=None):
        def go():
            result = R.render_scene(dev, cam, R.RenderSettings(
                width=size, height=size, spp=spp, max_depth=depth, sky=SKY, threads=threads, tile_pixels=tile,
                integrator=INTEGRATOR, sampler=SAMPLER))
            if label:
                rays[label] = result.stats.rays
        return go
    o, d = wp.zeros(n, dtype=wp.vec3), wp.zeros(n, dtype=wp.vec3)
    cam_args = camera_params(cam, size, size)
    return {"camera samples only": launcher(camera_ray_kernel(dev), n, lambda lo: [cam_args, size, lo, o, d], threads),
            "path d=1": launcher(kernel, n, inputs(1), threads),
            f"render d=1, tiles of {R.TILE_PIXELS}": render(R.TILE_PIXELS),
            "render d=1, one tile": render(n),
            f"render d=1, {SPP} spp *": render(R.TILE_PIXELS, SPP),
            f"render d={DEPTH}, {SPP} spp *": render(R.TILE_PIXELS, SPP, DEPTH, f"render d={DEPTH}, {SPP} spp *")}, rays


def print_table(title: str, n: int, times: dict[tuple[str, int], float], agree: dict[str, str],
                rays: dict[str, int]) -> None:
    print(f"\n## {title}: {n} rays")
    print("| kernel | threads | Mrays/s | ratio to bare | 2-thread scaling | same hits as bare |")
    print("|---|---|---|---|---|---|")
    for (label, threads), secs in times.items():
        bare = n / times[("bare", threads)]
        one = times.get((label, 1))
        scaling = f"{one / secs:.2f}x" if threads > 1 and one else ""
        rate = rays.get(label, n) / secs
        print(f"| {label} | {threads} | {rate / 1e6:.2f} | {rate / bare:.2f} | {scaling} | "
              f"{agree.get(label, '')} |", flush=True)


def _agreement(outs: dict, dev: DeviceScene) -> dict[str, str]:
    if len(dev.scene.meshes) != 1 or len(dev.scene.spheres):
        return {}                              # the bare kernel sees other geometry than ours
    t_ref, f_ref = (a.numpy() for a in outs["bare"])
    out = {}
    for label, (t, f) in outs.items():
        if label != "bare":
            diff = np.mean((t.numpy() != t_ref) | (f.numpy() != f_ref))
            out[label] = "bit-identical" if diff == 0 else f"{diff:.2%} differ"
    return out


def measure(title: str, dev: DeviceScene, bare_mesh: wp.Mesh, o: wp.array, d: wp.array, ladder: dict,
            repeat: int, thread_counts: list[int], cam: Camera | None = None, size: int = 0) -> None:
    times: dict[tuple[str, int], float] = {}
    agree: dict[str, str] = {}
    rays: dict[str, int] = {}
    for threads in thread_counts:
        runs, outs = ladder_runs(dev, bare_mesh, o, d, ladder, threads)
        if cam is not None:
            more, rays = path_runs(dev, cam, size, threads)
            runs.update(more)
        # One thread: the launch runs on this thread, so its CPU time is the kernel's time, and
        # another process on the same core does not inflate it. More threads: wall time.
        clock = time.thread_time if threads == 1 else time.perf_counter
        for label, secs in interleaved(runs, repeat, clock).items():
            times[(label, threads)] = secs
        agree = _agreement(outs, dev)
    print_table(title, o.shape[0], times, agree, rays)


# --------------------------------------------------------------------------------------------
# Scenes


def grid_obj(folder: Path, quads: int) -> str:
    """A wavy height field of 2*quads^2 triangles over [-50, 50]^2, as an OBJ file."""
    x, y = np.meshgrid(np.linspace(-50, 50, quads + 1), np.linspace(-50, 50, quads + 1))
    z = 4.0 * np.sin(x / 5.0) * np.cos(y / 7.0)
    v = np.stack([x, y, z], -1).reshape(-1, 3)
    i, j = np.meshgrid(np.arange(quads), np.arange(quads))
    a = (i * (quads + 1) + j).reshape(-1) + 1
    b, c, e = a + 1, a + quads + 2, a + quads + 1
    f = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, e], 1)])
    path = folder / "grid.obj"
    with open(path, "w") as fh:
        np.savetxt(fh, v, fmt="v %.6f %.6f %.6f")
        np.savetxt(fh, f, fmt="f %d %d %d")
    return str(path)


def scenes(folder: Path) -> list[tuple[str, DeviceScene, Camera]]:
    objs, mtls = demo_files()
    quiet = dict(warn=lambda message: None)
    out = [
        ("grid, 1 mesh, 100k tris", DeviceScene(load_scene([grid_obj(folder, 224)], [], **quiet)),
         Camera(position=(0.0, -45.0, 40.0), direction=(0.0, 1.0, -0.8), fov=80.0, aperture=0.0, focus=1.0)),
        ("demo sculpture alone, 1 mesh, 25.6k tris", DeviceScene(load_scene([objs[1]], mtls, **quiet)),
         Camera()),
        ("built-in demo, 3 meshes + 3 spheres", DeviceScene(load_scene(objs, mtls, **quiet)), Camera()),
    ]
    try:
        sys.path.insert(0, str(REPO))
        from tests.stability_scenes import cornell_camera, cornell_files
        out.append(("Cornell box (tests), 1 mesh + 2 spheres",
                    DeviceScene(load_scene(*cornell_files(folder), **quiet)), cornell_camera()))
    except ImportError:                      # an installed package without the tests
        pass
    return out


def merged_mesh(dev: DeviceScene) -> wp.Mesh:
    """One wp.Mesh of every triangle in the scene: the bare kernel's mesh."""
    pts, idx, base = [], [], 0
    for m in dev.scene.meshes:
        pts.append(m.positions.astype(np.float32))
        idx.append(m.indices.reshape(-1).astype(np.int32) + base)
        base += len(m.positions)
    return wp.Mesh(points=wp.array(np.concatenate(pts), dtype=wp.vec3),
                   indices=wp.array(np.concatenate(idx), dtype=wp.int32), bvh_constructor="sah")


def small_scene_table(folder: Path, size: int, repeat: int) -> None:
    """Where visiting every item beats the TLAS (geometry.SMALL_SCENE): the tests' Cornell box with
    0..13 extra spheres, closest hits by the item loop against the TLAS traversal, same rays."""
    from tests.stability_scenes import cornell_camera, cornell_files
    objs, mtls = cornell_files(folder)
    rng = np.random.default_rng(3)
    loop, tlas = (make_closest_hit(Features.general(), small_scene=k) for k in (64, 0))

    def kernel(hit_fn):
        @wp.kernel(enable_backward=False, module="unique")
        def k(s: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), t_out: wp.array(dtype=float)):
            i = wp.tid()
            t_out[i] = hit_fn(s, o[i], d[i], NO_HIT).t
        return k

    k_loop, k_tlas = kernel(loop), kernel(tlas)
    print("\n## Item loop against the TLAS (Cornell box + extra spheres), one thread")
    print("| items | rays | loop speed / TLAS speed | same t |")
    print("|---|---|---|---|")
    for extra in (0, 3, 5, 9, 13):
        path = folder / f"cornell_plus_{extra}.obj"
        spheres = rng.uniform(4, 28, size=(extra, 3))
        path.write_text(Path(objs[0]).read_text() + "".join(f"b {x:.3f} {y:.3f} {z:.3f} 1.5\n" for x, y, z in spheres))
        dev = DeviceScene(load_scene([str(path)], mtls, warn=lambda message: None))
        for name, (o, d) in (("camera", camera_rays(dev, cornell_camera(), size)),
                             ("random", random_rays(dev.scene.bounds, size * size))):
            n = o.shape[0]
            a, b = wp.zeros(n, dtype=float), wp.zeros(n, dtype=float)
            best = interleaved({"loop": lambda: wp.launch(k_loop, dim=n, inputs=[dev.geometry, o, d, a]),
                                "tlas": lambda: wp.launch(k_tlas, dim=n, inputs=[dev.geometry, o, d, b])},
                               repeat, time.thread_time)
            same = np.array_equal(a.numpy(), b.numpy())
            print(f"| {dev.tlas.items.shape[0]} | {name} | {best['tlas'] / best['loop']:.2f} | {same} |", flush=True)


def main() -> None:
    global INTEGRATOR, SAMPLER
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="128x128 rays, 2 repeats")
    ap.add_argument("--size", type=int, default=512, help="camera rays: size x size (default 512)")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--scene", default="", help="only scenes whose name contains this")
    ap.add_argument("--small-scene", action="store_true",
                    help="only the table of item loop against TLAS by number of items (geometry.SMALL_SCENE)")
    ap.add_argument("--integrator", default=INTEGRATOR, help=f"the path rows' integrator (default {INTEGRATOR})")
    ap.add_argument("--sampler", default=SAMPLER, help=f"the path rows' sampler (default {SAMPLER})")
    args = ap.parse_args()
    INTEGRATOR, SAMPLER = args.integrator, args.sampler
    size, repeat = (128, 2) if args.quick else (args.size, args.repeat)
    wp.init()
    print(f"# bench_rays: {size}x{size} rays, best of {repeat}, threads {args.threads}, path rows {INTEGRATOR} + {SAMPLER}, "
          f"{os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
    with tempfile.TemporaryDirectory() as tmp:
        if args.small_scene:
            small_scene_table(Path(tmp), size, repeat)
            return
        for name, dev, cam in scenes(Path(tmp)):
            if args.scene not in name:
                continue
            bare_mesh = dev._meshes[0] if len(dev._meshes) == 1 else merged_mesh(dev)
            ladder = make_ladder(dev.features)
            for k in ladder.values():
                wp.load_module(k.module)
            o, d = camera_rays(dev, cam, size)
            measure(f"{name}, camera rays", dev, bare_mesh, o, d, ladder, repeat, args.threads, cam, size)
            o, d = random_rays(dev.scene.bounds, size * size)
            measure(f"{name}, random rays from inside the box", dev, bare_mesh, o, d, ladder, repeat,
                    args.threads)
    for pool in _pools.values():
        pool.shutdown()


if __name__ == "__main__":
    main()
