"""render(): split the image into tiles, launch the specialised kernel from a thread pool, return linear HDR.

Warp runs a CPU kernel on one thread and releases the GIL while it runs, so tiles launched from a
pool of Python threads use every core. Each pixel's samples are summed in a fixed order (passes of
PASS_SAMPLES in sample order), so the image depends only on the seed, never on threads or tiles.
"""

from __future__ import annotations

import os
import time
import warnings as _warnings
from dataclasses import replace

import numpy as np
import warp as wp

from warp_spt.core.device_scene import DeviceScene
from warp_spt.core.lights import light_table, sky_emits
from warp_spt.core.proctex import nonfinite_textures
from warp_spt.integrators import RenderParams, camera_params, get_kernel
from warp_spt.rendering.film import Film
from warp_spt.rendering.result import RenderResult, RenderStats
from warp_spt.rendering.schedule import samples_per_pass
from warp_spt.rendering.settings import (
    RenderSettings,
    _check_rows,
    check_args,
    settings_from,
)
from warp_spt.runtime.progress import ProgressFn, progress_reporter
from warp_spt.runtime.threads import run_jobs
from warp_spt.scene.camera import Camera
from warp_spt.scene.model import Scene
from warp_spt.scene.recentre import recentre
from warp_spt.scene.sky import Sky


def render(scene: Scene | DeviceScene, camera: Camera | None = None, *,
           progress: bool | ProgressFn = False, **settings) -> np.ndarray:
    """Render ``scene`` and return a float32 (height, width, 3) array of linear radiance.

    Keyword arguments are the fields of :class:`RenderSettings`. ``progress`` is True for a tqdm bar
    or a callable ``(done, total)`` in samples x pixels, called on the calling thread. Ctrl-C stops the
    workers and re-raises KeyboardInterrupt. :func:`render_scene` returns the film and stats too.
    """
    return render_scene(scene, camera, settings_from(settings), progress=progress).image


def render_film(scene: Scene | DeviceScene, camera: Camera | None = None, *,
                progress: bool | ProgressFn = False, rows: tuple[int, int] | None = None, **settings) -> Film:
    """Like :func:`render`, but returns the :class:`Film` (float64 sums and sample count); ``rows``
    as in :func:`render_scene`."""
    return render_scene(scene, camera, settings_from(settings), progress=progress, rows=rows).film


def render_scene(scene: Scene | DeviceScene, camera: Camera | None = None,
                 settings: RenderSettings | None = None, *, progress: bool | ProgressFn = False,
                 rows: tuple[int, int] | None = None) -> RenderResult:
    """Render with a :class:`RenderSettings`; returns a :class:`RenderResult` (film, image, stats).

    ``rows`` = (first, stop) renders only those rows of the width x height image: the film holds
    just them, equal bit for bit to the same rows of the full render (random streams key on the
    global pixel, passes on the whole image's size), which is what tile tasks stand on.
    """
    rs = settings or RenderSettings()
    check_args(rs)
    (camera or Camera()).validate(rs.width, rs.height)     # ValueError before anything is uploaded
    _check_rows(rows, rs.height)
    width, height, spp = rs.width, rs.height, rs.spp
    if not isinstance(scene, DeviceScene):      # far from the origin: shift to it in float64 first
        scene, camera, _ = recentre(scene, camera)
    dev = scene if isinstance(scene, DeviceScene) else DeviceScene(scene, device=rs.device)
    sky = rs.sky or Sky.black()
    feats = rs.features or replace(dev.features, sky=sky_emits(sky))
    kernel = get_kernel(feats, dev.device, rs.integrator, rs.sampler)
    camera = camera or Camera()
    cam = camera_params(camera, width, height)
    lights = light_table(dev, sky, camera.up)
    tex = dev.textures(rs.texture_filter)
    n = width * height
    first, stop = rows or (0, height)
    film, counters, keep = _window_arrays(first * width, stop * width, dev.device)
    tiles = [(p, min(stop * width, p + rs.tile_pixels)) for p in range(first * width, stop * width, rs.tile_pixels)]
    nthreads = max(1, min(rs.threads or os.cpu_count() or 1, len(tiles)))
    per_pass = samples_per_pass(width, height)

    def params(lo: int, s0: int, count: int) -> RenderParams:
        p = RenderParams()
        p.width, p.pixel_start, p.sample_start, p.sample_count = width, lo, rs.sample_offset + s0, count
        p.max_depth, p.roulette_depth, p.seed = rs.max_depth, rs.roulette_depth, wp.uint32(rs.seed & 0xFFFFFFFF)
        return p

    def work(tile: tuple[int, int], stop, done) -> None:
        lo, hi = tile
        for s0 in range(0, spp, per_pass):
            if stop.is_set():
                return
            count = min(per_pass, spp - s0)
            wp.launch(kernel, dim=hi - lo, device=dev.device, inputs=[
                dev.geometry, dev.materials, tex, lights, cam, params(lo, s0, count), film, counters, None])
            done(count * (hi - lo))

    report = progress_reporter(progress, (stop - first) * width * spp)
    start = time.perf_counter()
    try:
        run_jobs(tiles, work, nthreads, report)   # Ctrl-C: workers stop, then KeyboardInterrupt
    finally:
        report(None)
    seconds = time.perf_counter() - start
    c = keep[1].numpy().sum(axis=0)
    stats = RenderStats(feats, rs.integrator, rs.sampler, seconds, int(c[0]), int(c[1]), len(tiles), nthreads,
                        pixel_samples=(stop - first) * width * spp, render_seconds=seconds,
                        launches=len(tiles) * -(-spp // per_pass))
    if stats.dropped_samples and feats.procedural:
        stats.nonfinite_textures = tuple(nonfinite_textures(dev.scene, dev.device))
        _warnings.warn(f"{stats.dropped_samples} non-finite samples dropped; procedural texture(s) returning "
                       f"NaN or infinity: {', '.join(stats.nonfinite_textures) or 'none found by probing'}",
                       RuntimeWarning, stacklevel=2)
    sums = keep[0].numpy().reshape(stop - first, width, 3)
    return RenderResult(Film(sums, spp), stats, rs)


def _window_arrays(lo: int, hi: int, device) -> tuple[wp.array, wp.array, tuple[wp.array, wp.array]]:
    """Film and counters for global pixels [lo, hi): device memory for those pixels only, viewed
    through arrays indexed by the global pixel (the kernel writes ``film[pixel]``). The views start
    ``lo`` elements before the allocation, an address that is computed but never read or written.
    Returns (film view, counters view, (film, counters) allocations: keep them alive, read them)."""
    film = wp.zeros(hi - lo, dtype=wp.vec3d, device=device)
    counters = wp.zeros((hi - lo, 2), dtype=wp.int64, device=device)    # rays traced, samples dropped
    if lo == 0:
        return film, counters, (film, counters)
    film_view = wp.array(ptr=film.ptr - lo * film.strides[0], dtype=wp.vec3d, shape=(hi,), device=device)
    counters_view = wp.array(ptr=counters.ptr - lo * counters.strides[0], dtype=wp.int64, shape=(hi, 2),
                             device=device)
    return film_view, counters_view, (film, counters)


