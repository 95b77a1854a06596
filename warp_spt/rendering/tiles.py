"""render(): split the image into tiles, launch the specialised kernel from a thread pool, return linear HDR.

Warp runs a CPU kernel on one thread and releases the GIL while it runs, so tiles launched from a
pool of Python threads use every core. Each pixel's samples are summed in a fixed order (passes of
PASS_SAMPLES in sample order), so the image depends only on the seed, never on threads or tiles.
"""

from __future__ import annotations

import time
import warnings as _warnings

import numpy as np
import warp as wp

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.device.proctex import nonfinite_textures
from warp_spt.integrators import fast_inputs
from warp_spt.rendering.film import Film
from warp_spt.rendering.result import RenderResult, RenderStats
from warp_spt.rendering.schedule import pass_ranges, samples_per_pass
from warp_spt.rendering.settings import RenderSettings, settings_from
from warp_spt.rendering.setup import Bound, bind
from warp_spt.runtime.progress import ProgressFn, progress_reporter
from warp_spt.runtime.threads import cores, run_jobs
from warp_spt.scene.camera import Camera
from warp_spt.scene.model import Scene


def render(scene: Scene | DeviceScene, camera: Camera | None = None, *,
           progress: bool | ProgressFn = False, **settings) -> np.ndarray:
    """Render ``scene`` and return a float32 (height, width, 3) array of linear radiance.

    Keyword arguments are the fields of :class:`RenderSettings`. ``progress`` is True for a tqdm bar
    or a callable ``(done, total)`` in samples x pixels, called on the calling thread. Ctrl-C stops the
    workers and re-raises KeyboardInterrupt. :func:`render_scene` returns the film and stats too.

    Given a host :class:`Scene`, it warns (``UserWarning``) when the camera sees no geometry at all,
    as the command line does: a 64-pixel-wide probe through the camera (a ``wp.Mesh`` per mesh: 0.7 s
    against the upload's 2.0 s for a million triangles, ``benchmarks/bench_view_checks.py``); a
    :class:`DeviceScene` is not probed.
    """
    rs = settings_from(settings)
    image = render_scene(scene, camera, rs, progress=progress).image       # checks every argument
    if isinstance(scene, Scene):         # a user's call: say so when the image shows nothing
        from warp_spt.rendering.first_view import sees_nothing
        problem = sees_nothing(scene, camera or Camera(), rs.width, rs.height)
        if problem:
            _warnings.warn(problem.replace("use --frame", "use warp_spt.quick_view, Camera.frame"),
                           UserWarning, stacklevel=2)
    return image


def quick_view(scene, *, width: int = 384, height: int = 288, spp: int = 16, camera: Camera | None = None,
               up: str | None = None, studio: bool | None = None, sky: "Sky | None" = None, **settings) -> np.ndarray:
    """The command line's first image of a scene, in one call: a float32 (height, width, 3) linear image.

    ``scene`` is a :class:`Scene` or OBJ file names (loaded as ``warp-spt -obj`` loads them: a bare
    model gets clay, a mesh without normals smooth ones by angle). The view is
    :func:`warp_spt.first_view`'s: recentred, Y up for a standard OBJ, framed,
    and the studio look for a scene with no light of its own (its key left out for the scene's
    sun, point or spot lights, or an environment map ``sky``: they light it); its notes are Python warnings
    (``UserWarning``) when they warn. ``save_image(path, image, tonemap="filmic")`` writes it with the
    command line's tone map for a standard file (``first_view(scene).tonemap``; the seed's curve,
    ``save_image``'s default, for the seed's scenes). Other keywords are :class:`RenderSettings` fields."""
    from warp_spt.rendering.first_view import first_view

    if not isinstance(scene, Scene):
        from warp_spt.io.loader import load_scene
        names = [scene] if isinstance(scene, (str, bytes)) or hasattr(scene, "__fspath__") else list(scene)
        scene = load_scene(names, default_material="auto", smooth_angle="auto")
    if camera is not None and up is None:           # a camera of the caller's keeps its own up axis
        from warp_spt.scene.camera import AXES
        up = next((name for name, v in AXES.items() if tuple(map(float, camera.up)) == v), None)
    fv = first_view(scene, camera, width=width, height=height, up=up, studio=studio, sky=sky)
    for w in fv.warnings:
        _warnings.warn(w, UserWarning, stacklevel=2)
    rs = settings_from({"width": width, "height": height, "spp": spp, **settings,
                        **({"sky": fv.sky} if fv.sky is not None else {})})
    return render_scene(fv.scene, fv.camera, rs).image


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
    b = bind(scene, camera, settings, rows=rows)
    rs, width = b.settings, b.width
    first, stop = rows or (0, b.height)
    film, counters, keep = _window_arrays(first * width, stop * width, b.dev.device)
    tiles = [(p, min(stop * width, p + rs.tile_pixels)) for p in range(first * width, stop * width, rs.tile_pixels)]
    nthreads = max(1, min(rs.threads or cores(), len(tiles)))
    passes = pass_ranges(rs.spp, width, b.height)

    def work(tile: tuple[int, int], stop, done) -> None:
        lo, hi = tile
        for s0, count in passes:
            if stop.is_set():
                return
            wp.launch(b.kernel, dim=hi - lo, device=b.dev.device,
                      inputs=fast_inputs(b.scene_args(b.params(lo, s0, count)), film, counters))
            done(count * (hi - lo))

    report = progress_reporter(progress, (stop - first) * width * rs.spp)
    start = time.perf_counter()
    own = b.integrator.render_passes        # an integrator with a pass schedule of its own (guided)
    launches = len(tiles) * len(passes)
    try:
        if own is None:
            run_jobs(tiles, work, nthreads, report)   # Ctrl-C: workers stop, then KeyboardInterrupt
        else:
            launches = own(b, tiles, film, counters, nthreads, report, samples_per_pass(width, b.height))
        wp.synchronize_device(b.dev.device)     # CUDA launches return at once: time the work itself
    finally:
        report(None)
    seconds = time.perf_counter() - start
    c = keep[1].numpy().sum(axis=0)
    stats = RenderStats(b.features, rs.integrator, rs.sampler, seconds, int(c[0]), int(c[1]), len(tiles), nthreads,
                        pixel_samples=(stop - first) * width * rs.spp, render_seconds=seconds,
                        launches=launches)
    if stats.dropped_samples and b.features.procedural:
        _warn_nonfinite(b, stats)
    sums = keep[0].numpy().reshape(stop - first, width, 3)
    result = RenderResult(Film(sums, rs.spp), stats, rs)
    return result if b.integrator.passes is None else b.integrator.passes(b, result)


def _warn_nonfinite(b: Bound, stats: RenderStats) -> None:
    """Name the procedural textures that return NaN or infinity (they dropped samples)."""
    stats.nonfinite_textures = tuple(nonfinite_textures(b.dev.scene, b.dev.device))
    _warnings.warn(f"{stats.dropped_samples} non-finite samples dropped; procedural texture(s) returning "
                   f"NaN or infinity: {', '.join(stats.nonfinite_textures) or 'none found by probing'}",
                   RuntimeWarning, stacklevel=3)


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


