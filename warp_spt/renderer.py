"""render(): split the image into tiles, launch the specialised kernel from a thread pool, return linear HDR.

Warp runs a CPU kernel on one thread and releases the GIL while it runs, so tiles launched from a
pool of Python threads use every core. Each pixel's samples are summed in a fixed order (passes of
PASS_SAMPLES in sample order), so the image depends only on the seed, never on threads or tiles.
"""

from __future__ import annotations

import os
import time
import warnings as _warnings
from dataclasses import dataclass, field, fields, replace
from typing import Callable

import numpy as np
import warp as wp

from .camera import Camera
from .device_scene import DeviceScene, Features
from .film import Film
from .framing import recentre
from .integrators import DEFAULT_INTEGRATOR, RenderParams, camera_params, check_integrator, get_kernel
from .lights import light_table, sky_emits
from .parallel import run_jobs
from .proctex import nonfinite_textures
from .samplers import DEFAULT_SAMPLER, SAMPLERS
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


@dataclass(frozen=True)
class RenderSettings:
    """Everything a render needs besides the scene and the camera.

    ``spp`` samples per pixel starting at global sample index ``sample_offset`` (renders of disjoint
    sample ranges can be merged, see :class:`warp_spt.film.Film`); ``max_depth`` counts surface hits
    as in the seed; ``sky`` defaults to the seed's (blue) BlackSky; ``integrator`` and ``sampler`` are
    names from ``warp_spt.integrators.INTEGRATORS`` and ``warp_spt.samplers.SAMPLERS``;
    ``roulette_depth`` starts Russian roulette after that many hits (0: off; the seed integrator
    ignores it); ``threads`` defaults to every core; ``features`` overrides the scene's own feature set
    (a superset gives the same image, slower); ``device`` is used when a host Scene is uploaded.
    """

    width: int = 500
    height: int = 500
    spp: int = 16
    max_depth: int = 6
    sky: Sky | None = None
    seed: int = 0
    integrator: str = DEFAULT_INTEGRATOR
    sampler: str = DEFAULT_SAMPLER
    roulette_depth: int = 0
    texture_filter: str = "nearest"
    sample_offset: int = 0
    threads: int | None = None
    tile_pixels: int = TILE_PIXELS
    features: Features | None = None
    device: str = "cpu"


@dataclass
class RenderStats:
    """What a render did (:func:`render_scene` and :func:`warp_spt.progressive.render_progressive`).

    ``seconds`` is wall time: for render_scene the launches (kernel compile excluded), for
    render_progressive the time since its ``started`` (upload and compile included);
    ``render_seconds`` is the launches only, for both. ``passes``, ``stopped_by`` and the per-pass
    lists describe progressive renders (a plain render is one pass stopped by its spp).
    """

    features: Features | None = None
    integrator: str = ""
    sampler: str = ""
    seconds: float = 0.0
    rays: int = 0             # closest-hit rays traced (shadow rays not counted)
    dropped_samples: int = 0  # non-finite samples discarded (should always be 0)
    tiles: int = 0
    threads: int = 1
    nonfinite_textures: tuple[str, ...] = ()   # procedural textures found returning NaN/inf (see proctex)
    passes: int = 1
    pixel_samples: int = 0
    render_seconds: float = 0.0
    stopped_by: str = "spp"   # "spp", "time", "error", "samples", "callback", "interrupt"
    setup_seconds: float = 0.0   # progressive: from ``started`` to the first launch (load, upload, compile)
    launches: int = 0
    pass_errors: list[float] = field(default_factory=list)   # estimated relative error after each pass
    pass_seconds: list[float] = field(default_factory=list)  # ``seconds`` at the end of each pass


@dataclass
class RenderResult:
    """Every render's result: the image, per-pixel standard error and sample counts, the sums, stats.

    ``image`` float32 (H, W, 3) linear radiance; ``std_error`` float32 (H, W, 3), the estimated
    standard error of each pixel's mean (NaN where there is no estimate: a plain :func:`render_scene`
    has one random stream per pixel and gives none; render_progressive gives one wherever two batches
    have samples); ``spp`` int64 (H, W) samples per pixel; ``relative_error`` the image's estimated
    relative error (docs/error.md; NaN without an estimate). ``film`` holds the float64 sums and
    sample count, which merge exactly (None when pixels have different counts: adaptive sampling).
    ``sums``/``counts`` are render_progressive's batch buffers, (B, H, W, 3) and (B, H, W).
    """

    film: Film | None
    stats: RenderStats
    settings: RenderSettings | None = field(repr=False, default=None)
    image: np.ndarray | None = field(repr=False, default=None)
    std_error: np.ndarray | None = field(repr=False, default=None)
    spp: np.ndarray | None = field(repr=False, default=None)
    relative_error: float = float("nan")
    sums: np.ndarray | None = field(repr=False, default=None)
    counts: np.ndarray | None = field(repr=False, default=None)

    def __post_init__(self) -> None:
        if self.image is None:
            self.image = self.film.image()
        h, w = self.image.shape[:2]
        if self.spp is None:
            self.spp = np.full((h, w), self.film.spp, dtype=np.int64)
        if self.std_error is None:
            self.std_error = np.full((h, w, 3), np.nan, dtype=np.float32)

    @property
    def spp_total(self) -> int:
        """Samples per pixel when every pixel has the same count, else the largest count."""
        return int(self.spp.max())

    @classmethod
    def from_batches(cls, sums: np.ndarray, counts: np.ndarray, stats: RenderStats,
                     settings: RenderSettings | None = None) -> "RenderResult":
        """A result from batch buffers (:func:`warp_spt.progressive.result_from_batches`)."""
        from .progressive import result_from_batches      # progressive imports this module

        return result_from_batches(sums, counts, stats, settings)


_SETTING_NAMES = {f.name for f in fields(RenderSettings)}


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


def settings_from(kw: dict) -> RenderSettings:
    """A :class:`RenderSettings` from keyword arguments; a TypeError names any unknown ones."""
    unknown = set(kw) - _SETTING_NAMES
    if unknown:
        raise TypeError(f"unknown render setting(s): {', '.join(sorted(unknown))}")
    return RenderSettings(**kw)


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
    per_pass = max(PASS_SAMPLES, PASS_WORK // n)

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


def check_args(rs: RenderSettings) -> None:
    """Raise ValueError naming the first setting of ``rs`` a kernel must not see (sizes, sample indices,
    seed, roulette depth, texture filter, integrator and sampler names)."""
    for name in ("width", "height", "spp", "max_depth", "tile_pixels"):
        v = getattr(rs, name)
        if not isinstance(v, (int, np.integer)) or v < 1:
            raise ValueError(f"{name} must be a positive integer, got {v!r}")
    if rs.width * rs.height > MAX_PIXELS:
        raise ValueError(f"image of {rs.width}x{rs.height} pixels is too large (at most {MAX_PIXELS} pixels)")
    if rs.sample_offset < 0 or rs.sample_offset + rs.spp > 2**31 - 1:
        raise ValueError("sample indices must lie in [0, 2**31)")
    if not isinstance(rs.seed, (int, np.integer)):
        raise ValueError(f"seed must be an integer, got {rs.seed!r}")
    if not isinstance(rs.roulette_depth, (int, np.integer)) or rs.roulette_depth < 0:
        raise ValueError(f"roulette_depth must be a non-negative integer, got {rs.roulette_depth!r}")
    if rs.texture_filter not in ("nearest", "bilinear"):
        raise ValueError(f"texture_filter must be 'nearest' or 'bilinear', got {rs.texture_filter!r}")
    check_integrator(rs.integrator)
    if rs.sampler not in SAMPLERS:
        raise ValueError(f"unknown sampler {rs.sampler!r}; choose from {', '.join(sorted(SAMPLERS))}")


def _check_rows(rows, height: int) -> None:
    if rows is not None and not (isinstance(rows, tuple) and len(rows) == 2
                                 and all(isinstance(r, (int, np.integer)) for r in rows)
                                 and 0 <= rows[0] < rows[1] <= height):
        raise ValueError(f"rows must be (first, stop) with 0 <= first < stop <= height, got {rows!r}")


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


def progress_reporter(progress: bool | ProgressFn, total: int) -> Callable[[int | None], None]:
    """A progress sink for ``total`` units: a function taking increments (None closes it).

    ``progress`` is False/None (a no-op), True (a tqdm bar) or a callable ``(done, total)``, which is
    called with the running sum on the thread that reports.
    """
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

