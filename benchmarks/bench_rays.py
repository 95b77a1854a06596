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
    python benchmarks/bench_rays.py --path       # issue 24: the path kernel's closest-hit and shadow rays
                                                 # against bare kernels on the same rays, and ablations
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING   # no banner or module-load lines (Warp 1.19 dropped config.quiet)

import warp_spt.rendering.tiles as R
from warp_spt.upload.device_scene import MESH_LEAF_SIZE, DeviceScene, Features, Geometry, Materials, Textures  # noqa: E402
from warp_spt.accel.ray_queries import KIND_MISS, NO_HIT, Hit, make_closest_hit, make_occluded  # noqa: E402
from warp_spt.emitters import Lights, declare_sky, light_table  # noqa: E402
from warp_spt.accel.surface import make_surface  # noqa: E402
from warp_spt.demo import demo_files  # noqa: E402
from warp_spt.integrators import (  # noqa: E402
    CameraParams,
    PathState,
    RenderParams,
    camera_params,
    get_kernel,
    get_step,
)
from warp_spt.integrators.common import FAST_KERNEL_OPTIONS, make_kernel, make_start_path  # noqa: E402
from warp_spt.io.loader import load_scene  # noqa: E402
from warp_spt.rendering.settings import TILE_PIXELS  # noqa: E402
from warp_spt.samplers import Sampler, SamplerState, batch_lanes, get_sampler  # noqa: E402
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
    return dev.features.with_lights(declare_sky(SKY))


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


def hit_kernel(hit_fn) -> wp.Kernel:
    """A kernel running ``hit_fn`` (a closest-hit function of geometry.py's kind) over stored rays from
    ``start``, writing each hit's t and face (-1 for a miss)."""
    @wp.kernel(enable_backward=False, module="unique")
    def hit(s: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), start: int,
            t_out: wp.array(dtype=float), face_out: wp.array(dtype=int)):
        i = start + wp.tid()
        h = hit_fn(s, o[i], d[i], NO_HIT)
        t_out[i] = h.t
        face_out[i] = wp.where(h.kind == KIND_MISS, -1, h.face)
    return hit


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


def interleaved(runs: dict[str, callable], repeat: int, clock=time.perf_counter, summary=min) -> dict[str, float]:
    """``summary`` (best by default, or np.median) of each run's times, the runs taken in turn
    ``repeat`` times after a warm-up: the machine is shared, and taking turns spreads its slow spells
    over every row instead of one."""
    for fn in runs.values():
        fn()                                   # warm-up (and load)
    times: dict[str, list[float]] = {k: [] for k in runs}
    for _ in range(repeat):
        for label, fn in runs.items():
            t = clock()
            fn()
            times[label].append(clock() - t)
    return {k: float(summary(v)) for k, v in times.items()}


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
            f"render d=1, tiles of {TILE_PIXELS}": render(TILE_PIXELS),
            "render d=1, one tile": render(n),
            f"render d=1, {SPP} spp *": render(TILE_PIXELS, SPP),
            f"render d={DEPTH}, {SPP} spp *": render(TILE_PIXELS, SPP, DEPTH, f"render d={DEPTH}, {SPP} spp *")}, rays


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
# The whole path kernel against bare closest-hit and any-hit kernels on the same rays (issue 24)
#
# Instrumented builds of the path kernel live here, never in the product: the integrator's step is
# rebuilt (nee.make_path_step) with its closest-hit, shadow-ray and sampler functions wrapped, and
# the wrappers write to device arrays whose addresses are compiled in as constants (a Warp function
# cannot take an array from a closure). One single-threaded launch calls them in a fixed order, so
# a *record* build stores what each call returned, in call order, and a *replay* build of the same
# kernel returns the stored results instead of computing them: the image is bit-identical and the
# time saved is what that piece costs inside the path kernel. A *count* build only counts.

PATH_SIZE, PATH_SPP = 128, 8     # --path-size, --path-spp: one launch of size^2 pixels x spp samples


def _device_view(arr: wp.array):
    """(address constant, length) of ``arr``: how an instrumented Warp function reaches it."""
    return wp.constant(wp.uint64(arr.ptr)), int(arr.shape[0])


class Taps:
    """The buffers of one instrumented build: counters (slot 0 closest-hit rays, 1 shadow rays, 2 sampler
    requests, 3 camera samples) and, once sized by a count run, the recorded calls."""

    def __init__(self, sizes: tuple[int, int, int, int] | None = None):
        self.counters = wp.zeros(4, dtype=wp.int32)
        n = sizes or (0, 0, 0, 0)
        # (origins, directions, t_max, results) of the closest-hit and the shadow rays
        self.closest = (wp.zeros(max(1, n[0]), dtype=wp.vec3), wp.zeros(max(1, n[0]), dtype=wp.vec3),
                        wp.zeros(max(1, n[0]), dtype=float), wp.zeros(max(1, n[0]), dtype=Hit))
        self.shadow = (wp.zeros(max(1, n[1]), dtype=wp.vec3), wp.zeros(max(1, n[1]), dtype=wp.vec3),
                       wp.zeros(max(1, n[1]), dtype=float), wp.zeros(max(1, n[1]), dtype=wp.int32))
        self.values = wp.zeros(max(1, n[2]), dtype=wp.vec2), wp.zeros(max(1, n[2]), dtype=SamplerState)
        self.starts = wp.zeros(max(1, n[3]), dtype=PathState)

    def reset(self) -> None:
        self.counters.zero_()


def tapped_rays(make_real, taps: Taps, slot: int, mode: str):
    """A replacement for ``make_real`` (``geometry.make_closest_hit``, slot 0, or ``make_occluded``,
    slot 1): its rays counted / recorded / replayed (mode); what each call returned is recorded in
    ``taps.closest[3]`` (Hit) or ``taps.shadow[3]`` (1 occluded, 0 not)."""
    arrays = taps.closest if slot == 0 else taps.shadow
    C, _ = _device_view(taps.counters)
    (O, N), (D, _), (T, _), (R, _) = (_device_view(a) for a in arrays)
    hit = slot == 0
    rtype = Hit if hit else wp.int32
    record, replay = mode == "record", mode == "replay"

    def make(features, **kw):
        real = make_real(features, **kw)

        @wp.func
        def traced(s: Geometry, o: wp.vec3, d: wp.vec3, t_max: float):
            k = wp.atomic_add(wp.array(ptr=C, shape=(4,), dtype=wp.int32), slot, 1)
            if wp.static(replay and hit):
                return wp.array(ptr=R, shape=(N,), dtype=rtype)[k]
            if wp.static(replay and not hit):
                return wp.array(ptr=R, shape=(N,), dtype=rtype)[k] != 0
            r = real(s, o, d, t_max)
            if wp.static(record):
                wp.array(ptr=O, shape=(N,), dtype=wp.vec3)[k] = o
                wp.array(ptr=D, shape=(N,), dtype=wp.vec3)[k] = d
                wp.array(ptr=T, shape=(N,), dtype=float)[k] = t_max
                if wp.static(hit):
                    wp.array(ptr=R, shape=(N,), dtype=rtype)[k] = r
                else:
                    wp.array(ptr=R, shape=(N,), dtype=rtype)[k] = wp.where(r, 1, 0)
            return r
        return traced
    return make


def tapped_sampler(sampler: Sampler, taps: Taps, mode: str) -> Sampler:
    """``sampler`` with its requests counted / recorded / replayed (mode)."""
    C, _ = _device_view(taps.counters)
    V, NV = _device_view(taps.values[0])
    S, _ = _device_view(taps.values[1])
    record, replay = mode == "record", mode == "replay"

    @wp.func
    def next_2d(state: SamplerState, dim: int):
        k = wp.atomic_add(wp.array(ptr=C, shape=(4,), dtype=wp.int32), 2, 1)
        if wp.static(replay):
            return wp.array(ptr=V, shape=(NV,), dtype=wp.vec2)[k], wp.array(ptr=S, shape=(NV,), dtype=SamplerState)[k]
        v, st = sampler.next_2d(state, dim)
        if wp.static(record):
            wp.array(ptr=V, shape=(NV,), dtype=wp.vec2)[k] = v
            wp.array(ptr=S, shape=(NV,), dtype=SamplerState)[k] = st
        return v, st

    @wp.func
    def next_1d(state: SamplerState, dim: int):
        k = wp.atomic_add(wp.array(ptr=C, shape=(4,), dtype=wp.int32), 2, 1)
        if wp.static(replay):
            return wp.array(ptr=V, shape=(NV,), dtype=wp.vec2)[k][0], wp.array(ptr=S, shape=(NV,), dtype=SamplerState)[k]
        v, st = sampler.next_1d(state, dim)
        if wp.static(record):
            wp.array(ptr=V, shape=(NV,), dtype=wp.vec2)[k] = wp.vec2(v, 0.0)
            wp.array(ptr=S, shape=(NV,), dtype=SamplerState)[k] = st
        return v, st

    def make_batch(offsets):
        """The batch of ``sampler.make_batch(offsets)`` tapped too: its ``lanes`` (x, y) pairs are
        counted, recorded and replayed as that many requests, in lane order."""
        real = sampler.make_batch(offsets)
        lanes = batch_lanes(len(offsets))
        vf = wp.types.vector(length=2 * lanes, dtype=wp.float32)

        @wp.func
        def batch(state: SamplerState, base: int):
            k = wp.atomic_add(wp.array(ptr=C, shape=(4,), dtype=wp.int32), 2, wp.static(lanes))
            values = wp.array(ptr=V, shape=(NV,), dtype=wp.vec2)
            if wp.static(replay):
                out = vf()
                for j in range(wp.static(lanes)):
                    out[j] = values[k + j][0]
                    out[j + wp.static(lanes)] = values[k + j][1]
                return out
            u = real(state, base)
            if wp.static(record):
                for j in range(wp.static(lanes)):
                    values[k + j] = wp.vec2(u[j], u[j + wp.static(lanes)])
            return u
        return batch

    return Sampler(sampler.name, sampler.start, next_1d, next_2d, sampler.random_access,
                   make_batch=make_batch if sampler.make_batch is not None else None)


def tapped_start(sampler: Sampler, taps: Taps, mode: str):
    """``make_start_path(sampler)`` with the camera samples counted / recorded / replayed (mode)."""
    C, _ = _device_view(taps.counters)
    P, NP = _device_view(taps.starts)
    real = make_start_path(sampler)
    record, replay = mode == "record", mode == "replay"

    @wp.func
    def start_path(cam: CameraParams, pix: int, width: int, seed: wp.uint32, index: int) -> PathState:
        k = wp.atomic_add(wp.array(ptr=C, shape=(4,), dtype=wp.int32), 3, 1)
        if wp.static(replay):
            return wp.array(ptr=P, shape=(NP,), dtype=PathState)[k]
        p = real(cam, pix, width, seed, index)
        if wp.static(record):
            wp.array(ptr=P, shape=(NP,), dtype=PathState)[k] = p
        return p
    return start_path


def path_build(features: Features, taps: Taps | None = None, **modes) -> wp.Kernel:
    """The fast kernel of INTEGRATOR + SAMPLER rebuilt, with the pieces named in ``modes`` (hits,
    shadow, sampler, camera: "count", "record" or "replay") instrumented; no modes: the product's."""
    from warp_spt.bsdfs import cutout
    from warp_spt.integrators import nee
    sampler = get_sampler(SAMPLER)
    if not modes:
        return get_kernel(features, integrator=INTEGRATOR, sampler=SAMPLER)
    if "sampler" in modes:
        sampler = tapped_sampler(sampler, taps, modes["sampler"])
    # the vertex reaches the queries through bsdfs.cutout (make_hit, make_blocked)
    saved = cutout.make_closest_hit, cutout.make_occluded
    try:
        if "hits" in modes:
            cutout.make_closest_hit = tapped_rays(make_closest_hit, taps, 0, modes["hits"])
        if "shadow" in modes:
            cutout.make_occluded = tapped_rays(make_occluded, taps, 1, modes["shadow"])
        step = nee.make_path_step(features, sampler, light_sampling=INTEGRATOR == "nee")
    finally:
        cutout.make_closest_hit, cutout.make_occluded = saved
    start = tapped_start(sampler, taps, modes["camera"]) if "camera" in modes else make_start_path(sampler)
    k = make_kernel(step, start)
    wp.load_module(k.module)
    return k


def variant_kernel(features: Features, film32: bool = False) -> wp.Kernel:
    """The product's kernel body with a last argument ``per_thread``: pixels per thread (the struct
    arguments are copied once per thread, so once per ``per_thread`` pixels); ``film32``: the samples
    summed in float32 (not the product's bits)."""
    step, start_path = get_step(INTEGRATOR, SAMPLER, features)
    acc_t = wp.vec3 if film32 else wp.vec3d

    @wp.kernel(enable_backward=False, module="unique", module_options=FAST_KERNEL_OPTIONS)
    def trace(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, cam: CameraParams,
              rp: RenderParams, film: wp.array(dtype=wp.vec3d), counters: wp.array2d(dtype=wp.int64),
              work: wp.array(dtype=wp.vec3i), per_thread: int):
        for q in range(per_thread):        # a dynamic loop: unrolled, 16 copies of the path overflow the caches
            pix = rp.pixel_start + wp.tid() * per_thread + q
            acc = acc_t()
            rays = int(0)
            for j in range(rp.sample_count):
                path = start_path(cam, pix, rp.width, rp.seed, rp.sample_start + j)
                while path.alive != 0:
                    path = step(geo, mats, tex, lights, rp, path)
                rays += path.rays
                if wp.isfinite(path.radiance):
                    acc += acc_t(path.radiance)
            film[pix] = film[pix] + wp.vec3d(acc)
            counters[pix, 0] = counters[pix, 0] + wp.int64(rays)

    wp.load_module(trace.module)
    return trace


@wp.kernel(enable_backward=False)
def _bare_anyhit(mesh: wp.uint64, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), t_max: wp.array(dtype=float),
                 out: wp.array(dtype=wp.int32)):
    i = wp.tid()
    out[i] = wp.where(wp.mesh_query_ray_anyhit(mesh, o[i], d[i], t_max[i]), 1, 0)


def _ours_kernels(features: Features):
    """Our closest_hit and occluded (geometry.py, as the renderer builds them) over stored rays."""
    occluded = make_occluded(features)

    @wp.kernel(enable_backward=False, module="unique")
    def ours_any(s: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), t_max: wp.array(dtype=float),
                 out: wp.array(dtype=wp.int32)):
        i = wp.tid()
        out[i] = wp.where(occluded(s, o[i], d[i], t_max[i]), 1, 0)

    return hit_kernel(make_closest_hit(features)), ours_any


def path_table(name: str, dev: DeviceScene, cam: Camera, sky: Sky, size: int, spp: int, depth: int,
               repeat: int) -> None:
    """Rays/s of the whole path kernel (closest-hit and shadow rays together) against the bare
    wp.mesh_query_ray and wp.mesh_query_ray_anyhit kernels on the very rays it traced, and the
    ablations (what each piece costs inside the path kernel). One thread, CPU time of the launch."""
    n = size * size
    feats = dev.features.with_lights(declare_sky(sky))
    fixed = [dev.geometry, dev.materials, dev.textures(), light_table(dev, sky), camera_params(cam, size, size)]
    rp = RenderParams()
    rp.width, rp.pixel_start, rp.sample_start, rp.sample_count = size, 0, 0, spp
    rp.max_depth, rp.roulette_depth, rp.seed = depth, 0, wp.uint32(1)

    def launch(kernel, taps=None, per_thread=0):
        """One single-threaded launch over every pixel (``per_thread`` > 0: a variant_kernel with that
        many pixels per thread); returns the film (float64 sums)."""
        film = wp.zeros(n, dtype=wp.vec3d)
        if taps is not None:
            taps.reset()
        more = [per_thread] if per_thread else []
        wp.launch(kernel, dim=n // max(1, per_thread), inputs=[*fixed, rp, film, wp.zeros((n, 2), dtype=wp.int64),
                                                                 None, *more])
        return film

    # count, then record every call of the product's kernel, in call order
    counting = Taps()
    launch(path_build(feats, counting, hits="count", shadow="count", sampler="count", camera="count"), counting)
    sizes = tuple(int(x) for x in counting.counters.numpy())
    taps = Taps(sizes)
    reference = launch(path_build(feats), None).numpy()
    recorded = launch(path_build(feats, taps, hits="record", shadow="record", sampler="record", camera="record"),
                      taps).numpy()
    assert np.array_equal(recorded, reference), "the recording build changed the image"
    n_hit, n_shadow, n_req, n_cam = sizes
    print(f"\n## {name}: path kernel against bare kernels on the same rays, {size}x{size}, {spp} spp, depth {depth}, "
          f"{INTEGRATOR} + {SAMPLER}, one thread, median CPU s of {repeat}")
    print(f"counted (a counting build): {n_hit:,} closest-hit rays, {n_shadow:,} shadow rays, {n_req:,} sampler "
          f"requests, {n_cam:,} camera samples; {(n_hit + n_shadow) / n_cam:.2f} rays and {n_req / n_cam:.1f} "
          "requests per camera sample")

    mesh = dev._meshes[0] if len(dev._meshes) == 1 else merged_mesh(dev)
    o, d = taps.closest[:2]
    so, sd, st, sres = taps.shadow
    t_out, f_out, any_out = wp.zeros(n_hit, dtype=float), wp.zeros(n_hit, dtype=int), wp.zeros(n_shadow, dtype=wp.int32)
    ours_hit, ours_any = _ours_kernels(feats)
    for k in (ours_hit, ours_any):
        wp.load_module(k.module)
    product = path_build(feats)
    runs = {
        "path kernel (product)": lambda: launch(product),
        "bare closest-hit": lambda: wp.launch(_bare, dim=n_hit, inputs=[mesh.id, o, d, 0, t_out, f_out]),
        "bare any-hit": lambda: wp.launch(_bare_anyhit, dim=n_shadow, inputs=[mesh.id, so, sd, st, any_out]),
        "our closest_hit": lambda: wp.launch(ours_hit, dim=n_hit, inputs=[dev.geometry, o, d, 0, t_out, f_out]),
        "our occluded": lambda: wp.launch(ours_any, dim=n_shadow, inputs=[dev.geometry, so, sd, st, any_out]),
    }
    same_shadow = None
    if len(dev._meshes) == 1 and not len(dev.scene.spheres):
        wp.launch(_bare_anyhit, dim=n_shadow, inputs=[mesh.id, so, sd, st, any_out])
        same_shadow = np.array_equal(any_out.numpy(), sres.numpy())
    # the ablations: one piece replaced by its recorded results (same image) or one overhead changed
    ablations = {
        "sampler requests replayed (no Sobol' hashing)": dict(sampler="replay"),
        "camera samples replayed (no start_path)": dict(camera="replay"),
        "closest hits replayed (no traversal)": dict(hits="replay"),
        "shadow rays replayed (no any-hit traversal)": dict(shadow="replay"),
        "closest hits and shadow rays replayed": dict(hits="replay", shadow="replay"),
    }
    ab_kernels = {label: path_build(feats, taps, **modes) for label, modes in ablations.items()}
    for label, k in ab_kernels.items():
        runs[label] = lambda k=k: launch(k, taps)
    k64, f32 = variant_kernel(feats), variant_kernel(feats, film32=True)
    runs["the same kernel body, 1 pixel per thread"] = lambda: launch(k64, per_thread=1)
    runs["16 pixels per thread (struct arguments copied 1/16 as often)"] = lambda: launch(k64, per_thread=16)
    runs["samples summed in float32 (not the product's bits)"] = lambda: launch(f32, per_thread=1)
    identical = {label: np.array_equal(launch(k, taps).numpy(), reference) for label, k in ab_kernels.items()}
    for label, k, per in (("the same kernel body, 1 pixel per thread", k64, 1),
                          ("16 pixels per thread (struct arguments copied 1/16 as often)", k64, 16),
                          ("samples summed in float32 (not the product's bits)", f32, 1)):
        identical[label] = np.array_equal(launch(k, per_thread=per).numpy(), reference)
    times = interleaved(runs, repeat, time.thread_time, np.median)
    # tiles, launches, worker threads, film read-back: render_scene on one thread, process CPU time
    # (its launches run on a worker thread), against the one launch above
    settings = R.RenderSettings(width=size, height=size, spp=spp, max_depth=depth, sky=sky, seed=1, threads=1,
                                integrator=INTEGRATOR, sampler=SAMPLER)
    render_label = f"render_scene, 1 thread, tiles of {settings.tile_pixels} pixels (process CPU)"
    times[render_label] = interleaved(
        {render_label: lambda: R.render_scene(dev, cam, settings)}, repeat, time.process_time, np.median)[render_label]
    identical[render_label] = np.array_equal(R.render_scene(dev, cam, settings).film.sum.reshape(-1, 3), reference)

    t_path = times["path kernel (product)"]
    t_bare = times["bare closest-hit"] + times["bare any-hit"]
    print("\n| kernel | rays | CPU s | Mrays/s | ratio to bare |")
    print("|---|---|---|---|---|")
    print(f"| path kernel (closest-hit + shadow rays) | {n_hit + n_shadow:,} | {t_path:.3f} | "
          f"{(n_hit + n_shadow) / t_path / 1e6:.2f} | **{t_bare / t_path:.2f}** |")
    print(f"| bare closest-hit + bare any-hit | {n_hit + n_shadow:,} | {t_bare:.3f} | "
          f"{(n_hit + n_shadow) / t_bare / 1e6:.2f} | 1.00 |")
    for label, rays in (("bare closest-hit", n_hit), ("bare any-hit", n_shadow), ("our closest_hit", n_hit),
                        ("our occluded", n_shadow)):
        print(f"| {label} | {rays:,} | {times[label]:.3f} | {rays / times[label] / 1e6:.2f} | |")
    if same_shadow is not None:
        print(f"\nbare any-hit agrees with the path kernel's shadow rays: {same_shadow}")
    print("\nAblations (each row one change to the product's kernel; 'saves': share of the product kernel's time)")
    print("| build | CPU s | saves | image |")
    print("|---|---|---|---|")
    print(f"| product kernel | {t_path:.3f} | | reference |")
    for label in list(ab_kernels) + ["the same kernel body, 1 pixel per thread",
                                     "16 pixels per thread (struct arguments copied 1/16 as often)",
                                     "samples summed in float32 (not the product's bits)", render_label]:
        print(f"| {label} | {times[label]:.3f} | {1 - times[label] / t_path:+.1%} | "
              f"{'bit-identical' if identical[label] else 'differs'} |", flush=True)


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
        from tests.support.stability_scenes import cornell_camera, cornell_files
        out.append(("Cornell box (tests), 1 mesh + 2 spheres",
                    DeviceScene(load_scene(*cornell_files(folder), **quiet)), cornell_camera()))
    except ImportError:                      # an installed package without the tests
        pass
    return out


def mitsuba_cornell(folder: Path) -> tuple[str, DeviceScene, Camera, Sky]:
    """The Cornell box of bench_vs_mitsuba.py (the issue's 512^2, 16 spp comparison): one mesh, black sky."""
    import bench_vs_mitsuba as mb
    desc = mb.SCENES["cornell"]
    sub = folder / "mitsuba_cornell"
    sub.mkdir(exist_ok=True)
    return ("cornell (bench_vs_mitsuba)", mb.warp_scene(desc, sub), mb.warp_camera(desc), Sky.constant(*desc["sky"]))


def merged_mesh(dev: DeviceScene) -> wp.Mesh:
    """One wp.Mesh of every triangle in the scene: the bare kernel's mesh."""
    pts, idx, base = [], [], 0
    for m in dev.scene.meshes:
        pts.append(m.positions.astype(np.float32))
        idx.append(m.indices.reshape(-1).astype(np.int32) + base)
        base += len(m.positions)
    return wp.Mesh(points=wp.array(np.concatenate(pts), dtype=wp.vec3),
                   indices=wp.array(np.concatenate(idx), dtype=wp.int32), bvh_constructor="sah",
                   bvh_leaf_size=MESH_LEAF_SIZE)


def small_scene_table(folder: Path, size: int, repeat: int) -> None:
    """Where visiting every item beats the TLAS (geometry.SMALL_SCENE): the tests' Cornell box with
    0..13 extra spheres, closest hits by the item loop against the TLAS traversal, same rays."""
    from tests.support.stability_scenes import cornell_camera, cornell_files
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
    ap.add_argument("--path", action="store_true",
                    help="only the path kernel against bare kernels on the same rays, and the ablations "
                         "(default scene: bench_vs_mitsuba's Cornell box; nee + sobol unless given)")
    ap.add_argument("--path-size", type=int, default=PATH_SIZE, help=f"--path: image size (default {PATH_SIZE})")
    ap.add_argument("--path-spp", type=int, default=PATH_SPP, help=f"--path: samples per pixel (default {PATH_SPP})")
    ap.add_argument("--depth", type=int, default=DEPTH, help=f"--path: max depth (default {DEPTH})")
    args = ap.parse_args()
    INTEGRATOR, SAMPLER = args.integrator, args.sampler
    if args.path:
        if "--integrator" not in sys.argv:
            INTEGRATOR = "nee"
        if "--sampler" not in sys.argv:
            SAMPLER = "sobol"
        wp.init()
        print(f"# bench_rays --path: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}")
        with tempfile.TemporaryDirectory() as tmp:
            chosen = [mitsuba_cornell(Path(tmp))] + [(*sc, SKY) for sc in scenes(Path(tmp))]
            for name, dev, cam, sky in chosen:
                if (args.scene or "bench_vs_mitsuba") in name:
                    path_table(name, dev, cam, sky, args.path_size, args.path_spp, args.depth,
                               2 if args.quick else args.repeat)
        return
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
