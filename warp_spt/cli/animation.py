"""The runner of ``--frames`` / ``--camera-path`` / ``--gif`` and of ``--cluster`` / ``--workers`` renders.

The library half (camera paths, OBJ sequences, :func:`warp_spt.animation.render_animation`) lives in
:mod:`warp_spt.animation`; this module turns options into calls of it and writes the files.
"""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager
from dataclasses import replace

import numpy as np

from warp_spt.animation import CameraPath, ObjSequence, render_animation
from warp_spt.cli.common import load_texture_modules, say_for
from warp_spt.cli.options import settings_of
from warp_spt.cli.view_checks import first_image_defaults, frame_view, media_integrator, with_flag_lights
from warp_spt.images.files import save_gif
from warp_spt.io.templates import frame_path
from warp_spt.runtime.signals import ignored_by_children

CONNECT_SECONDS = 5.0      # a scheduler on the network answers at once; waiting 30 s says nothing more


def _run_budgeted(opts, scene, say, started: float | None) -> int:
    """One image on the cluster until --time-budget or --target-error (-sr: the maximum) is met."""
    from warp_spt.cli.common import EXIT_OK
    from warp_spt.images.files import save_image
    from warp_spt.rendering.progressive import UNLIMITED_SPP

    b = opts.budget
    rs = replace(settings_of(opts), spp=opts.spp if b.spp_given else UNLIMITED_SPP)

    def on_pass(res) -> None:
        say(f"round {res.stats.passes}: {res.spp_total} spp, {res.stats.seconds:.1f} s, "
            f"estimated relative error {100 * res.relative_error:.2f}%")

    with cluster_client(opts) as client:
        from warp_spt import cluster
        res = cluster.render_progressive(client, scene, opts.camera, rs, time_budget=b.time_budget,
                                         target_error=b.target_error, on_pass=on_pass, started=started)
    save_image(opts.out, res.image, tonemap=opts.tonemap, exposure=opts.exposure)
    say(f"wrote {opts.out} ({res.spp_total} spp, {res.stats.seconds:.1f} s since start, stopped by "
        f"{res.stats.stopped_by}); estimated relative error of the image: {100 * res.relative_error:.2f}%")
    return EXIT_OK


def workers_warning(workers: int) -> str | None:
    """The warning for --workers N with N >= this machine's cores, else None: every worker process renders
    on as many threads as there are cores (runtime.threads.cores), so N of them compete for the same
    cores, and one process, without the cluster's overhead, is usually faster."""
    from warp_spt.runtime.threads import cores

    n = cores()
    if workers < n:
        return None
    return (f"warning: --workers {workers} on a {n}-core machine: each worker already uses every core; "
            "one process is usually faster")


@contextmanager
def cluster_client(opts):
    """The Dask client that ``--cluster`` or ``--workers`` asks for (closed after), or None."""
    if not (opts.cluster or opts.workers):
        yield None
        return
    from warp_spt.cli.common import RunError
    try:
        from warp_spt import cluster
    except ImportError as err:
        raise RunError(str(err)) from None
    if opts.workers:
        with quiet_local_workers(), cluster.local_client(opts.workers) as client:
            yield client
        return
    try:
        context = cluster.connect(opts.cluster, timeout=CONNECT_SECONDS)
        client = context.__enter__()
    except (OSError, TimeoutError, ValueError, TypeError) as err:
        raise RunError(f"cannot connect to the cluster at {opts.cluster} within {CONNECT_SECONDS:g} s: "
                       f"{err}") from None
    try:
        yield client
    finally:
        context.__exit__(None, None, None)


@contextmanager
def quiet_local_workers():
    """Local workers forked from a fork server that ignores SIGINT: a Ctrl-C in the terminal reaches
    the whole process group, and workers starting up printed tracebacks; this process alone handles
    it (one line, status 130) and stops the workers through their client."""
    import multiprocessing.forkserver

    import dask

    # The fork server starts multiprocessing's resource tracker, a process that outlives this one and,
    # after a Ctrl-C cut the cluster's start short, warned on our stderr about the semaphores it
    # cleans up. It takes the interpreter's -W options from sys.warnoptions: silence just that.
    tracker_quiet = "ignore::UserWarning:multiprocessing.resource_tracker"
    if tracker_quiet not in sys.warnoptions:
        sys.warnoptions.append(tracker_quiet)
    with dask.config.set({"distributed.worker.multiprocessing-method": "forkserver"}):
        with ignored_by_children():
            # a worker forked as this process exits ends quietly (see the module); distributed's own
            # preload (itself, numpy...) saves each worker its imports
            multiprocessing.forkserver.set_forkserver_preload(["warp_spt.runtime.forkserver_preload",
                                                               "distributed", "numpy"])
            multiprocessing.forkserver.ensure_running()
        yield


def written_files(out: str | None, frames, gif: str | None) -> str:
    """The files a run wrote, for its done line: the first and last of a sequence (never the
    {frame} template), or the one file, and the GIF."""
    parts = []
    if out:
        names = [frame_path(out, k) for k in frames]
        parts.append(names[0] if len(set(names)) == 1 else f"{names[0]} .. {names[-1]} ({len(names)} files)")
    if gif:
        parts.append(gif)
    return ", ".join(parts)


def run_cli(opts, err, started: float | None = None) -> int:
    """``warp-spt`` with --frames / --camera-path / --gif / --cluster / --workers: render and write the frames."""
    from warp_spt.cli.common import (
        EXIT_OK,
        check_files,
        check_registry_names,
        init_warp,
        scene_files,
    )
    from warp_spt.images.files import save_image, to_display
    from warp_spt.runtime.progress import ProgressBar

    say = say_for(opts, err)
    objs, mtls = scene_files(opts)
    check_files((), (), None, env=opts.env.path if opts.env else None)    # before any model is read
    path = CameraPath.load(opts.camera_path) if opts.camera_path else None
    seq = ObjSequence(objs, mtls, default_material=opts.default_material, fps=opts.fps,
                      smooth_angle=opts.smooth_angle)
    frames = opts.frames or (path.frames if path is not None else seq.default_frames() or range(0, 1))
    for k in frames:                       # every frame's inputs and outputs, before any rendering
        check_files(seq.paths(k), mtls, frame_path(opts.out, k) if opts.out else None)
    hidden = set(seq.check(frames))        # and every frame's pose
    shown = [k for k in frames if k not in hidden]

    def standin():                         # what a leading frame that hides everything is viewed as
        return seq.scene(shown[0]) if shown else None
    if opts.gif:                           # written after the last frame: checked before the first
        check_files((), (), opts.gif, "--gif")
    init_warp(opts)
    check_registry_names(opts)
    load_texture_modules(opts, say)
    start = time.perf_counter()
    first = seq.scene(frames[0])
    for warning in first.warnings:
        say(f"warning: {warning}")
    where = (f"the cluster at {opts.cluster}" if opts.cluster else
             f"{opts.workers} local worker processes" if opts.workers else "this machine")
    spp = opts.budget.samples(opts.spp)
    say(f"loaded frame {frames[0]}: {first.num_triangles:,} triangles, {len(first.spheres)} spheres in "
        f"{time.perf_counter() - start:.1f} s; rendering {len(frames)} frame(s) of {opts.width}x{opts.height}, "
        f"{spp}, depth {opts.depth} on {where}")
    if opts.workers and (warning := workers_warning(opts.workers)):
        say(warning)
    opts = media_integrator(opts, with_flag_lights(opts, first), say)   # a fog or interiors: volpath for every frame
    opts = first_image_defaults(opts, first, say, denoise=False)     # the tone map
    if opts.animated:
        # no camera given: one framing over every frame's bounds, so that what moves moves in the picture
        free = not (opts.cam_explicit or path is not None or opts.file_camera is not None or opts.uses_demo_scene)
        bounds = seq.bounds(shown) if free and len(frames) > 1 else None
        view = frame_view(opts, say, standin, bounds)

        def images(client, progress):
            return render_animation(seq, mtls, frames, path or opts.camera, settings_of(opts), client=client,
                                    progress=progress, view=view)
    else:            # one image on a cluster: the view (recentring, framing, sky) of the single-process CLI
        from warp_spt.cli.common import CompileNotice
        with CompileNotice(say):
            scene, camera, sky = frame_view(opts, say, standin)(first, opts.camera)
        opts = replace(opts, camera=camera, sky=sky)
        if opts.budget.active:
            return _run_budgeted(opts, scene, say, started)

        def images(client, progress):
            from warp_spt.cluster import render_scene
            return [(frames[0], render_scene(client, scene, camera, settings_of(opts), progress=progress).image)]
    bar = None if opts.quiet else ProgressBar(len(frames) * opts.width * opts.height * opts.spp, file=err)
    previews: dict[int, np.ndarray] = {}
    start = time.perf_counter()
    try:
        with cluster_client(opts) as client:
            for k, image in images(client, bar or False):
                if opts.out:
                    save_image(frame_path(opts.out, k), image, tonemap=opts.tonemap, exposure=opts.exposure)
                if opts.gif:
                    previews[k] = to_display(image, opts.tonemap, opts.exposure)
    finally:
        if bar is not None:
            from warp_spt.runtime.signals import deferred_signals
            with deferred_signals():    # never interrupt tqdm while it holds its lock (as cli.run)
                bar.close()
    if opts.gif:
        save_gif(opts.gif, [previews[k] for k in sorted(previews)])
    seconds = time.perf_counter() - start
    say(f"wrote {written_files(opts.out, frames, opts.gif)} ({len(frames)} frame(s), {seconds:.1f} s)")
    return EXIT_OK
