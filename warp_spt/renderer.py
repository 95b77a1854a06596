"""render(): split the image into tiles, launch the specialised kernel from a thread pool, return linear HDR.

Warp runs a CPU kernel on one thread and releases the GIL while it runs, so tiles launched from a
pool of Python threads use every core. Each pixel's samples are summed in a fixed order (passes of
PASS_SAMPLES in sample order), so the image depends only on the seed, never on threads or tiles.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Callable

import numpy as np
import warp as wp

from .camera import Camera
from .device_scene import DeviceScene, Features
from .film import Film
from .integrator import camera_params, get_kernel
from .parallel import run_jobs
from .scene import Scene
from .sky import Sky

ProgressFn = Callable[[int, int], None]

PASS_SAMPLES = 8          # samples per launch: bounds the time between progress reports / Ctrl-C checks
PASS_WORK = 1 << 16       # ...but at least this many pixel-samples per launch, so tiny images with huge
                          # spp (1x1 at 2**20 spp: 131072 launches, ~3 s of launch overhead) are not
                          # launch-bound. Depends on the image size only: the image stays independent
                          # of tiles and threads.
TILE_PIXELS = 4096        # pixels per launch
MAX_PIXELS = 1 << 28      # far beyond any sane image; guards the int32 pixel index in the kernel


@dataclass
class RenderStats:
    """What the last render did, for callers that want more than the image."""

    features: Features
    dropped_samples: int      # non-finite samples discarded (should always be 0)
    rays: int                 # rays traced (closest-hit queries)
    tiles: int
    threads: int


last_stats: RenderStats | None = None


def render(
    scene: Scene | DeviceScene,
    camera: Camera | None = None,
    *,
    width: int = 500,
    height: int = 500,
    spp: int = 16,
    max_depth: int = 6,
    sky: Sky | None = None,
    seed: int = 0,
    threads: int | None = None,
    device: str = "cpu",
    texture_filter: str = "nearest",
    progress: bool | ProgressFn = False,
    sample_offset: int = 0,
    features: Features | None = None,
    tile_pixels: int = TILE_PIXELS,
) -> np.ndarray:
    """Render ``scene`` and return a float32 (height, width, 3) array of linear radiance.

    ``spp`` samples per pixel starting at global sample index ``sample_offset`` (renders of disjoint
    sample ranges can be merged, see :class:`warp_spt.film.Film`); ``max_depth`` counts surface hits as in
    the seed; ``sky`` defaults to the seed's (blue) BlackSky; ``threads`` defaults to every core;
    ``features`` overrides the scene's own feature set (a superset gives the same image, slower).
    ``progress`` is True for a tqdm bar or a callable ``(done, total)`` in samples x pixels, called on
    the calling thread. Ctrl-C stops the workers and re-raises KeyboardInterrupt.
    """
    film = render_film(scene, camera, width=width, height=height, spp=spp, max_depth=max_depth, sky=sky,
                       seed=seed, threads=threads, device=device, texture_filter=texture_filter,
                       progress=progress, sample_offset=sample_offset, features=features,
                       tile_pixels=tile_pixels)
    return film.image()


def render_film(scene: Scene | DeviceScene, camera: Camera | None = None, *, width: int = 500,
                height: int = 500, spp: int = 16, max_depth: int = 6, sky: Sky | None = None, seed: int = 0,
                threads: int | None = None, device: str = "cpu", texture_filter: str = "nearest",
                progress: bool | ProgressFn = False, sample_offset: int = 0,
                features: Features | None = None, tile_pixels: int = TILE_PIXELS) -> Film:
    """Like :func:`render`, but returns the :class:`Film` (float64 sums and sample count)."""
    global last_stats
    _check_args(width, height, spp, max_depth, seed, sample_offset, texture_filter, tile_pixels)
    dev = scene if isinstance(scene, DeviceScene) else DeviceScene(scene, device=device)
    feats = features or dev.features
    kernel = get_kernel(feats, dev.device)
    camera = camera or Camera()
    sky = sky or Sky.black()
    cam = camera_params(camera, width, height)
    n = width * height
    film = wp.zeros(n, dtype=wp.vec3d, device=dev.device)
    counters = wp.zeros((n, 2), dtype=wp.int64, device=dev.device)   # rays traced, samples dropped
    tiles = [(p, min(n, p + tile_pixels)) for p in range(0, n, tile_pixels)]
    nthreads = max(1, min(threads or os.cpu_count() or 1, len(tiles)))
    per_pass = max(PASS_SAMPLES, PASS_WORK // n)
    sky_kind, sky_color = int(sky.kind), wp.vec3(*sky.color)
    seed32, bilinear = wp.uint32(seed & 0xFFFFFFFF), int(texture_filter == "bilinear")

    def work(tile: tuple[int, int], stop, done) -> None:
        lo, hi = tile
        for s0 in range(0, spp, per_pass):
            if stop.is_set():
                return
            count = min(per_pass, spp - s0)
            wp.launch(kernel, dim=hi - lo, device=dev.device, inputs=[
                dev.arrays, cam, width, lo, sample_offset + s0, count, max_depth, sky_kind, sky_color,
                seed32, bilinear, film, counters])
            done(count * (hi - lo))

    report = _progress_reporter(progress, n * spp)
    try:
        run_jobs(tiles, work, nthreads, report)   # Ctrl-C: workers stop, then KeyboardInterrupt
    finally:
        report(None)
    c = counters.numpy().sum(axis=0)
    last_stats = RenderStats(feats, int(c[1]), int(c[0]), len(tiles), nthreads)
    sums = film.numpy().reshape(height, width, 3)
    return Film(sums, spp)


def _check_args(width, height, spp, max_depth, seed, sample_offset, texture_filter, tile_pixels) -> None:
    for name, v in (("width", width), ("height", height), ("spp", spp), ("max_depth", max_depth),
                    ("tile_pixels", tile_pixels)):
        if not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"{name} must be a positive integer, got {v!r}")
    if width * height > MAX_PIXELS:
        raise ValueError(f"image of {width}x{height} pixels is too large (at most {MAX_PIXELS} pixels)")
    if sample_offset < 0 or sample_offset + spp > 2**31 - 1:
        raise ValueError("sample indices must lie in [0, 2**31)")
    if not isinstance(seed, (int, np.integer)):
        raise ValueError(f"seed must be an integer, got {seed!r}")
    if texture_filter not in ("nearest", "bilinear"):
        raise ValueError(f"texture_filter must be 'nearest' or 'bilinear', got {texture_filter!r}")


def _progress_reporter(progress: bool | ProgressFn, total: int) -> Callable[[int | None], None]:
    """A function taking increments (None closes the bar), or a no-op."""
    if progress is False or progress is None:
        return lambda inc: None
    bar = None
    if not callable(progress):
        from .progress import ProgressBar
        bar = progress = ProgressBar(total, delay=0.0)
    state = {"done": 0}

    def report(inc: int | None) -> None:
        if inc is None:
            if bar is not None:
                bar.close()
        elif inc:
            state["done"] += inc
            progress(state["done"], total)
    return report
