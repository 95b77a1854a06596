"""The command line's look at a scene before rendering: the first view's rule for its options.

The rule itself (recentring, up axis, framing, probes, warnings, studio) is
:func:`warp_spt.rendering.first_view.first_view`, shared with the viewer and the API; this module
turns the command's options into its arguments, says its lines, and uploads the result.

* :func:`prepare_view`: one image's view, then the upload.
* :func:`frame_view`: the same view for every frame of an animation.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from warp_spt.cli.common import CompileNotice, RunError, refuse_without_media
from warp_spt.cli.options import TONE_MAPPED
from warp_spt.rendering.first_view import (
    PROBE_SIZE,
    Probe,
    enclosing_object,
    first_view,
    lens_blur_share,
    probe,
    should_frame,
    view_warnings,
)
from warp_spt.scene.camera import Camera
from warp_spt.scene.media import FOG_DEPTH_ABSORB, FOG_DEPTH_SCATTER, scene_fog
from warp_spt.scene.sky import Sky

# the checks' names, where the command line's callers and tests have found them
__all__ = ["PROBE_SIZE", "Probe", "enclosing_object", "frame_view", "lens_blur_share", "prepare_view", "probe",
           "should_frame", "view_warnings"]


def prepare_view(opts, scene, say, notice: "CompileNotice | None" = None) -> tuple[object, Camera, Sky]:
    """The scene (uploaded to the device), camera and sky to render.

    ``scene`` holds the flags' lights and fog already (:func:`with_flag_lights`). The scene is
    recentred if far from the origin, framed when the rule says so (see
    :func:`warp_spt.cli.view_checks.should_frame`), checked for views that show nothing, and given the studio
    preset if asked. The probe's kernel may compile on a first run: ``notice`` announces it.
    """
    from warp_spt.upload.device_scene import DeviceScene

    with notice or CompileNotice(say):
        scene, camera, sky = _view(opts, scene, say)
    return DeviceScene(scene), camera, sky


def frame_view(opts, say, standin=None, bounds=None):
    """The view of each frame of an animation: :func:`_view`, the very preparation of a single image,
    with the frame's camera; a camera path, like -cam, is never replaced by framing, but its up
    axis is the model's (Y for a standard OBJ, Z for the seed's scenes; --up to choose), said once.
    A message that every frame repeats is said once.

    ``bounds``: the (2, 3) world bounds of every frame together (:meth:`ObjSequence.bounds`), given
    when no camera is: the first frame is framed over them, once, and every later frame keeps that
    camera and up axis (an object that moves moves in the picture; a morph does not zoom), with the
    studio's ground and key light placed from them too.

    A frame whose objects are all hidden (:attr:`Scene.hidden`) has nothing to frame or to stand a
    studio ground under: it is viewed as the last frame that has something (before the first,
    ``standin()``'s scene), with that frame's objects taken out and its own lights; with neither, through
    the camera as given."""
    fixed = opts.cam_given or bool(opts.camera_path)
    held: list = [None]             # (camera in world coordinates, up axis) the first frame chose, with bounds
    said: set[str] = set()
    lit: list = [None, None]        # (a frame's loaded scene, it with the flags' lights): one upload while it stays
    shown: list = [None]            # the last frame's scene that has something to draw

    def say_once(msg: str) -> None:
        if msg not in said:
            said.add(msg)
            say(msg)

    def view(scene, camera):
        if scene.hidden:
            return hidden_view(scene, camera)
        shown[0] = scene
        if lit[0] is not scene:
            lit[:] = [scene, with_flag_lights(opts, scene)]
        return framed(lit[1], camera)

    def framed(scene, camera):
        if bounds is None:
            return _view(replace(opts, camera=camera, cam_given=fixed), scene, say_once)
        if held[0] is None:
            fv, env = _first_view(replace(opts, camera=camera, cam_given=fixed), scene, say_once, bounds)
            world = fv.camera.with_(position=tuple(float(p + o) for p, o in zip(fv.camera.position, fv.offset)))
            held[0] = (world, fv.up.axis)
        else:
            world, up = held[0]
            fv, env = _first_view(replace(opts, camera=world, cam_given=True, cam_explicit=True, up=up, frame=False,
                                          view=None, look_at=None), scene, say_once, bounds)
        return _prepared(fv, env, opts)

    def hidden_view(scene, camera):
        if shown[0] is None and standin is not None:
            shown[0] = standin()
        source = shown[0]
        if source is None:
            return with_flag_lights(opts, scene), camera, None
        own = replace(source, lights=scene.lights, fog=scene.fog, sky=scene.sky)
        prepared, cam, sky = framed(with_flag_lights(opts, own), camera)
        # the preparation (recentring, the studio) keeps the scene's own geometry first, in order
        n_spheres = len(source.spheres)
        return replace(prepared, meshes=prepared.meshes[len(source.meshes):], spheres=prepared.spheres[n_spheres:],
                       sphere_material=prepared.sphere_material[n_spheres:], hidden=True), cam, sky
    return view


def with_flag_lights(opts, scene, say=None):
    """``scene`` with the lights of --sun, --light and --lights beside its own, the --volume box and
    the --fog medium: part of the scene, so the probe, every frame and a cluster's workers (the scene
    travels to them) see them as a single image does. ``say``: where the volume's place and the
    fog's coefficients are told (once: a frame's call passes none)."""
    say = say or (lambda line: None)
    if opts.lights:
        scene = replace(scene, lights=[*scene.lights, *opts.lights])
    if getattr(opts, "volume", None) is not None:
        from warp_spt.media.grid import add_volume

        path, fields = opts.volume
        scene, box = add_volume(scene, path, **fields)
        corner = lambda v: "(" + ", ".join(f"{x:.4g}" for x in v) + ")"    # noqa: E731
        say(f"--volume {path}: a box from {corner(box[0])} to {corner(box[1])}, the grid's own bounds, "
            f"filled with its density (sigma_s {_grey(fields.get('sigma_s', (1.0,) * 3))} per unit density "
            "and scene unit)")
    if getattr(opts, "fog", None) is not None:
        fog = opts.fog
        extent = np.ptp(scene.bounds, axis=0)
        size = float(np.linalg.norm(extent)) if np.isfinite(extent).all() and extent.any() else 1.0
        if opts.fog_scaled:
            fog = replace(fog, **scene_fog(size))
        depth = max(fog.sigma_t) * size
        say(f"fog: sigma_s {_grey(fog.sigma_s)}, sigma_a {_grey(fog.sigma_a)} per scene unit, an optical depth "
            f"of {depth:.3g} across the scene ({size:.4g} across)"
            + (f" ({FOG_DEPTH_SCATTER} and {FOG_DEPTH_ABSORB} over its size: --fog without sigma_s and sigma_a)"
               if opts.fog_scaled else ""))
        scene = replace(scene, fog=fog)
    return scene


def _grey(rgb) -> str:
    return f"{rgb[0]:.3g}" if rgb[0] == rgb[1] == rgb[2] else ",".join(f"{x:.3g}" for x in rgb)


def first_image_defaults(opts, scene, say, *, denoise: bool = True):
    """``opts`` with what the command left to the first image (:mod:`warp_spt.rendering.first_view`):
    the tone map (filmic for a standard file, the seed's curve for the seed's scenes; one line says so
    for a standard file's tone-mapped output) and, with ``denoise`` (a single image rendered in this
    process: not the frames of an animation, which would flicker, nor a cluster's image), for a
    .png/.jpg by an integrator without passes of its own, Open Image Denoise when it is installed (the
    denoise itself says so in its line), or one line naming the extra that brings it."""
    from warp_spt.rendering.first_view import STANDARD_TONEMAP, denoise_by_default, seed_look, tone_map

    demo = opts.uses_demo_scene
    mapped = bool(opts.gif) or (opts.out is not None and Path(opts.out).suffix.lower() in TONE_MAPPED)
    if opts.tonemap is None:
        opts = replace(opts, tonemap=tone_map(scene, demo))
        if mapped and opts.tonemap == STANDARD_TONEMAP:
            say(f"tone map: {STANDARD_TONEMAP} (a standard file: highlights roll off below white; "
                "--tonemap seed for the seed's curve, srgb for plain sRGB)")
    if denoise and opts.budget.denoise is None and mapped and _passes_free(opts) and not seed_look(scene, demo):
        if denoise_by_default(scene, demo):
            opts = replace(opts, budget=replace(opts.budget, denoise=True))
        else:
            from warp_spt.runtime.extras import install_hint

            say(f"not denoised ({opts.spp} spp): Intel Open Image Denoise gives a first image a sixth of its "
                f"error for half the render's time again (README, noise and tone): {install_hint('denoise')}")
    return opts


def _passes_free(opts) -> bool:
    """The integrator renders through the progressive renderer (those that train over passes of their
    own refuse its flags)."""
    from warp_spt.integrators import DEFAULT_INTEGRATOR, INTEGRATORS

    return INTEGRATORS[opts.integrator or DEFAULT_INTEGRATOR].render_passes is None


def media_integrator(opts, scene, say):
    """``opts`` with integrator ``volpath`` when ``scene`` has a fog or an interior medium and no
    --integrator was given (the other integrators refuse media), saying so."""
    if not (getattr(scene, "fog", None) is not None or getattr(scene, "interiors", None)):
        return opts
    if not opts.integrator:
        say("participating media: integrator volpath (docs/volumes.md)")
        return replace(opts, integrator="volpath")
    refuse_without_media(opts.integrator, "the scene (a fog or an interior medium)")
    return opts


def _view(opts, scene, say) -> tuple[object, Camera, Sky]:
    """Recentre, choose the up axis, place the camera (keep, or frame), warn, add the studio look:
    :func:`first_view` with the command's options (``--camera``: the model files' camera, never framed).
    ``scene`` already holds the flags' lights and fog (:func:`with_flag_lights`): they count as its
    own light for the studio rule."""
    return _prepared(*_first_view(opts, scene, say), opts)


def _first_view(opts, scene, say, bounds=None):
    """(:func:`first_view` of ``scene`` with the command's options, the --env sky or None);
    ``bounds``: an animation's, see :func:`frame_view`."""
    file_camera = None
    if getattr(opts, "file_camera", None) is not None:
        file_camera = _file_camera(opts, scene)
        opts = replace(opts, camera=file_camera, cam_given=True, frame=False, view=None)
    env = _environment(opts, say) if opts.env is not None else None
    try:
        fv = first_view(scene, opts.camera, width=opts.width, height=opts.height, up=opts.up, studio=opts.studio,
                        sky=env or (opts.sky if opts.sky_given else None), frame=opts.frame, view=opts.view,
                        look_at=opts.look_at, frame_all=opts.frame_all, demo=opts.uses_demo_scene,
                        keep_camera=opts.cam_given, seed_camera=opts.cam_explicit,
                        fixed=opts.cam_explicit or bool(opts.camera_path) or file_camera is not None,
                        quiet_demo=opts.quiet, bounds=bounds, say=say)
    except ValueError as err:
        raise RunError(str(err)) from None
    return fv, env


def _prepared(fv, env, opts) -> tuple[object, Camera, Sky]:
    """The scene, camera and sky to render of a first view."""
    if env is not None:     # a light of the scene, shipped with it (a cluster's workers too), not a setting
        return replace(fv.scene, sky=env), fv.camera, None
    return fv.scene, fv.camera, fv.sky if fv.sky is not None else opts.sky


def _environment(opts, say) -> Sky:
    """The --env map as a sky, with -sky/--sky-color's sky beside it if given (RunError naming the file
    if it cannot be read)."""
    from warp_spt.images.environment import load_environment

    e = opts.env
    try:
        sky = load_environment(e.path, rotate=e.rotate, strength=e.strength, background=e.background,
                               warn=lambda message: say(f"warning: {message}"))
        return sky if e.plus is None else replace(sky, plus=e.plus)
    except ValueError as err:
        raise RunError(str(err)) from None


def _file_camera(opts, scene) -> Camera:
    """The camera --camera names, for this image's aspect (the file's vertical field of view)."""
    from warp_spt.gltf import choose_camera

    try:
        return choose_camera(scene.cameras, opts.file_camera, opts.width, opts.height)
    except ValueError as err:
        raise RunError(f"--camera {opts.file_camera}: {err}") from None
