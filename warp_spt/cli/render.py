"""The runner of a single image on this machine: load, view checks, render (plain or budgeted), save."""

from __future__ import annotations

import time
from dataclasses import replace
from typing import TextIO

from warp_spt.cli.budget_flags import check_denoiser, check_outputs
from warp_spt.cli.common import (
    EXIT_OK,
    PROG,
    CompileNotice,
    RunError,
    check_files,
    check_registry_names,
    init_warp,
    load_texture_modules,
    out_of_memory,
    say_for,
    scene_files,
    warm_up,
)
from warp_spt.cli.options import Options, settings_of
from warp_spt.cli.progressive import render_and_save
from warp_spt.cli.view_checks import first_image_defaults, media_integrator, prepare_view, with_flag_lights
from warp_spt.runtime.progress import ProgressBar
from warp_spt.runtime.signals import deferred_signals


def run_image(opts: Options, err: TextIO, started: float) -> int:
    """Load, render and save one image on this machine as ``opts`` says (errors propagate)."""
    objs, mtls = scene_files(opts)
    check_files(objs, mtls, opts.out, env=opts.env.path if opts.env else None,
                volume=opts.volume[0] if opts.volume else None)
    check_outputs(opts.budget, RunError)
    check_denoiser(opts.budget, RunError)
    say = say_for(opts, err)
    init_warp(opts)
    check_registry_names(opts)
    import numpy as np

    from warp_spt.images.files import save_image
    from warp_spt.io.loader import load_scene
    from warp_spt.rendering.tiles import render_scene
    from warp_spt.io.mtl import builtin_clay
    from warp_spt.scene.model import Scene
    from warp_spt.scene.recentre import describe_bounds

    load_texture_modules(opts, say)
    start = time.perf_counter()
    try:
        scene = load_scene(objs, mtls, warn=lambda message: None,   # collected in scene.warnings, shown below
                           default_material=opts.default_material, smooth_angle=opts.smooth_angle) \
            if objs else Scene.empty(builtin_clay())      # --volume alone
    except MemoryError:
        raise RunError("out of memory while loading the scene: its files or textures are too large for "
                       "this machine's memory") from None
    for warning in scene.warnings:
        say(f"warning: {warning}")
    scene = with_flag_lights(opts, scene, say)   # --sun, --light, --lights beside the scene's own; --volume; --fog
    opts = media_integrator(opts, scene, say)
    what = (f"the built-in demo ({opts.demo or 'default'})" if opts.uses_demo_scene else
            f"{len(objs)} model file(s)" if objs else "the volume alone")
    dropped = f" ({scene.dropped_degenerate:,} of zero area dropped)" if scene.dropped_degenerate else ""
    if scene.instanced:         # the triangles held, then as many as the instances place
        dropped += f", {sum(len(m.indices) * m.placements for m in scene.meshes):,} placed by instances"
    say(f"loaded {what}: {scene.num_triangles:,} triangles{dropped}, {len(scene.spheres)} spheres, "
        f"{describe_bounds(scene)} in {time.perf_counter() - start:.1f} s; rendering {opts.width}x{opts.height}, "
        f"{opts.budget.samples(opts.spp)}, depth {opts.depth}")
    opts = first_image_defaults(opts, scene, say)      # the tone map; the denoiser when installed
    notice = CompileNotice(say)
    loaded = scene                  # the host Scene: prepare_view may hand back a DeviceScene
    scene, camera, sky = prepare_view(opts, scene, say, notice=notice)
    if opts.budget.active:      # passes, budgets and error estimates (cli/progressive.py)
        return render_and_save(replace(opts, camera=camera, sky=sky), scene, say=say, started=started, err=err)
    settings = settings_of(opts, sky=sky)
    with notice:
        warm_up(render_scene, scene, camera, settings)
    bar = None if opts.quiet else ProgressBar(opts.width * opts.height * opts.spp, file=err)
    start = time.perf_counter()
    try:
        result = render_scene(scene, camera, settings, progress=bar or False)
    except Exception as error:
        if not out_of_memory(error):
            raise
        texels = sum(int(np.prod(t.shape[:2])) for t in loaded.textures)
        raise RunError(f"out of memory while uploading and rendering the scene ({loaded.num_triangles:,} triangles, "
                       f"{texels:,} texels) at {opts.width}x{opts.height}: try a smaller -res or fewer "
                       "--threads, or a smaller scene") from None
    finally:
        if bar is not None:
            with deferred_signals():    # never interrupt tqdm while it holds its lock
                bar.close()
    seconds = time.perf_counter() - start
    image, dropped = result.image, result.stats.dropped_samples
    if dropped:     # shown even with --quiet: the image is wrong somewhere (docs/limits.md)
        print(f"{PROG}: warning: {dropped} samples were not finite and were dropped; the image is biased "
              "there (please report this scene)", file=err)
    save_image(opts.out, image, tonemap=opts.tonemap, exposure=opts.exposure)
    rate = opts.width * opts.height * opts.spp / max(seconds, 1e-9)
    say(f"wrote {opts.out} ({seconds:.1f} s, {rate / 1e6:.2f} M samples/s)")
    return EXIT_OK
