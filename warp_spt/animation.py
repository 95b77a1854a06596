"""Animation: OBJ sequences, camera paths, one image per frame, GIF previews.

::

    frames = warp_spt.animation.parse_frames("0:24")
    path = warp_spt.animation.CameraPath.load("orbit.json")
    for k, image in warp_spt.animation.render_animation(["room.obj", "wave_{frame:04d}.obj"], ["room.mtl"],
                                                        frames, path, width=320, height=240, spp=32):
        warp_spt.save_image(f"frame_{k:04d}.png", image)

An OBJ path containing ``{frame`` is a template, formatted with ``frame=k`` (``str.format``); the
other files are static and parsed once (:class:`ObjSequence`); their meshes are uploaded once
(here, or once per cluster worker, where they are also shipped once), and each frame rebuilds only
its changed meshes and the top-level structures over them. A camera is one :class:`Camera` or
a :class:`CameraPath` of keyframes, interpolated per frame: positions linearly, view directions
by spherical linear interpolation, fov, focus and aperture linearly.

Every frame is rendered with the same ``seed``, so frame k is one deterministic image, the same
whether it is rendered alone, in a sequence or on a cluster (and noise stays put on screen
instead of flickering).
"""

from __future__ import annotations

import json
import math
import time
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np

from .camera import Camera
from .errors import SceneError
from .scene import ObjData, Scene

FRAME_FIELD = "{frame"


def parse_frames(text: str) -> range:
    """``a:b[:step]`` -> range(a, b, step) (b excluded, as in Python); ``k`` alone is frame k only."""
    parts = text.split(":")
    try:
        nums = [int(p) for p in parts]
    except ValueError:
        raise ValueError(f"frames {text!r}: expected START:STOP[:STEP] or one frame number, "
                         "all integers") from None
    if len(nums) == 1:
        nums = [nums[0], nums[0] + 1]
    if len(nums) not in (2, 3):
        raise ValueError(f"frames {text!r}: expected START:STOP[:STEP]")
    start, stop, step = nums[0], nums[1], nums[2] if len(nums) == 3 else 1
    if start < 0 or step < 1 or stop <= start:
        raise ValueError(f"frames {text!r}: need 0 <= START < STOP and STEP >= 1")
    return range(start, stop, step)


def is_template(path: str) -> bool:
    """True for an OBJ path that names one file per frame, e.g. ``wave_{frame:04d}.obj``."""
    return FRAME_FIELD in str(path)


def frame_path(template: str, frame: int) -> str:
    """The file name of ``frame`` (``template.format(frame=frame)``); a plain path is returned as is."""
    if not is_template(template):
        return str(template)
    try:
        return str(template).format(frame=frame)
    except (KeyError, IndexError, ValueError) as err:
        raise ValueError(f"cannot format {template!r} with frame={frame}: {err}") from None


# ---------------------------------------------------------------------------------------------
# Camera paths


def slerp(a: np.ndarray, b: np.ndarray, t: float) -> np.ndarray:
    """Spherical linear interpolation between the directions of ``a`` and ``b`` (unit result).

    Nearly parallel directions fall back to a normalised linear blend (the same limit, stable).
    """
    a = np.asarray(a, np.float64) / np.linalg.norm(a)
    b = np.asarray(b, np.float64) / np.linalg.norm(b)
    cos = float(np.clip(np.dot(a, b), -1.0, 1.0))
    angle = math.acos(cos)
    if angle < 1e-6:
        v = (1.0 - t) * a + t * b
    else:
        v = (math.sin((1.0 - t) * angle) * a + math.sin(t * angle) * b) / math.sin(angle)
    return v / np.linalg.norm(v)


@dataclass(frozen=True)
class Keyframe:
    """A camera at a frame number."""

    frame: float
    camera: Camera


class CameraPath:
    """Camera keyframes at increasing frame numbers; :meth:`at` interpolates (and holds the ends)."""

    def __init__(self, keys: Sequence[Keyframe]) -> None:
        if not keys:
            raise ValueError("a camera path needs at least one keyframe")
        for i, (k0, k1) in enumerate(zip(keys, keys[1:])):
            if not k1.frame > k0.frame:
                raise ValueError(f"keyframe {i + 2}: frame {k1.frame} does not follow frame {k0.frame}")
            a, b = (np.asarray(k.camera.direction, np.float64) for k in (k0, k1))
            if np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)) < -0.9999:
                raise ValueError(f"keyframes {i + 1} and {i + 2}: opposite view directions; "
                                 "the turn between them is ambiguous (add a keyframe between)")
        self.keys = [Keyframe(k.frame, replace(k.camera, direction=_unit(k.camera.direction))) for k in keys]

    @property
    def frames(self) -> range:
        """First to last keyframe, inclusive (integer frames)."""
        return range(math.ceil(self.keys[0].frame), math.floor(self.keys[-1].frame) + 1)

    def at(self, frame: float) -> Camera:
        """The camera at ``frame``: interpolated between the keyframes around it, held outside them."""
        keys = self.keys
        if frame <= keys[0].frame:
            return keys[0].camera
        if frame >= keys[-1].frame:
            return keys[-1].camera
        i = max(j for j, k in enumerate(keys) if k.frame <= frame)
        k0, k1 = keys[i], keys[i + 1]
        t = (frame - k0.frame) / (k1.frame - k0.frame)
        c0, c1 = k0.camera, k1.camera

        def lerp(x, y):
            return (1.0 - t) * np.asarray(x, np.float64) + t * np.asarray(y, np.float64)

        return Camera(position=tuple(float(v) for v in lerp(c0.position, c1.position)),
                      direction=tuple(float(v) for v in slerp(c0.direction, c1.direction, t)),
                      fov=float(lerp(c0.fov, c1.fov)), aperture=float(lerp(c0.aperture, c1.aperture)),
                      focus=float(lerp(c0.focus, c1.focus)))

    @classmethod
    def load(cls, path: str | Path) -> "CameraPath":
        """Read a JSON camera path (see :meth:`from_json`); errors name the file and keyframe."""
        try:
            text = Path(path).read_text(encoding="utf-8")
        except OSError as err:
            raise SceneError(str(path), 0, f"cannot read camera path: {err.strerror or err}") from None
        except UnicodeDecodeError:
            raise SceneError(str(path), 0, "camera path is not UTF-8 text") from None
        try:
            data = json.loads(text)
        except json.JSONDecodeError as err:
            raise SceneError(str(path), err.lineno, f"invalid JSON: {err.msg}") from None
        try:
            return cls.from_json(data)
        except ValueError as err:
            raise SceneError(str(path), 0, str(err)) from None

    @classmethod
    def from_json(cls, data) -> "CameraPath":
        """``{"keyframes": [{"frame": 0, "position": [x, y, z], "direction": [x, y, z], "fov": 38,
        "focus": 27, "aperture": 0.001}, ...]}`` (or the list alone); fov, focus and aperture
        default to the previous keyframe's, then to :class:`Camera`'s defaults."""
        keys = data.get("keyframes") if isinstance(data, dict) else data
        if not isinstance(keys, list) or not keys:
            raise ValueError('expected {"keyframes": [...]} with at least one keyframe')
        out: list[Keyframe] = []
        prev = Camera()
        for i, k in enumerate(keys, 1):
            if not isinstance(k, dict):
                raise ValueError(f"keyframe {i}: expected an object, got {type(k).__name__}")
            unknown = set(k) - {"frame", "position", "direction", "fov", "focus", "aperture"}
            if unknown:
                raise ValueError(f"keyframe {i}: unknown field(s) {sorted(unknown)}")
            for name in ("frame", "position", "direction"):
                if name not in k:
                    raise ValueError(f"keyframe {i}: missing {name!r}")
            cam = Camera(position=_vec3(k["position"], i, "position"),
                         direction=_vec3(k["direction"], i, "direction"),
                         fov=_number(k.get("fov", prev.fov), i, "fov"),
                         aperture=_number(k.get("aperture", prev.aperture), i, "aperture"),
                         focus=_number(k.get("focus", prev.focus), i, "focus"))
            try:
                cam.validate()
            except ValueError as err:
                raise ValueError(f"keyframe {i}: {err}") from None
            out.append(Keyframe(_number(k["frame"], i, "frame"), cam))
            prev = cam
        return cls(out)

    def to_json(self) -> dict:
        """The JSON form read by :meth:`from_json`."""
        return {"keyframes": [{"frame": k.frame, "position": list(k.camera.position),
                               "direction": list(k.camera.direction), "fov": k.camera.fov,
                               "focus": k.camera.focus, "aperture": k.camera.aperture} for k in self.keys]}


def _unit(v) -> tuple[float, float, float]:
    a = np.asarray(v, np.float64)
    return tuple(float(x) for x in a / np.linalg.norm(a))   # type: ignore[return-value]


def _number(v, i: int, name: str) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise ValueError(f"keyframe {i}: {name} must be a finite number, got {v!r}")
    return float(v)


def _vec3(v, i: int, name: str) -> tuple[float, float, float]:
    if not isinstance(v, list) or len(v) != 3:
        raise ValueError(f"keyframe {i}: {name} must be a list of 3 numbers, got {v!r}")
    return tuple(_number(x, i, name) for x in v)   # type: ignore[return-value]


def camera_at(camera: Camera | CameraPath | None, frame: int) -> Camera:
    """The camera of ``frame``: a fixed camera, or the path interpolated there."""
    if isinstance(camera, CameraPath):
        return camera.at(frame)
    return camera or Camera()


# ---------------------------------------------------------------------------------------------
# OBJ sequences


class ObjSequence:
    """A scene per frame from OBJ templates and static files; only files whose name changes are re-read.

    ``loads`` counts OBJ files parsed (tests check that static files are parsed once).
    """

    def __init__(self, objs: Sequence[str], mtls: Sequence[str] = ()) -> None:
        self.objs = [str(p) for p in objs]
        self.mtls = [str(p) for p in mtls]
        self.loads = 0
        self._parsed: dict[str, ObjData] = {}
        self._last_scene: tuple[tuple[str, ...], Scene] | None = None

    @property
    def animated(self) -> bool:
        """True when some OBJ path is a per-frame template."""
        return any(is_template(p) for p in self.objs)

    def paths(self, frame: int) -> list[str]:
        """The OBJ files of ``frame``."""
        return [frame_path(p, frame) for p in self.objs]

    def scene(self, frame: int) -> Scene:
        """The validated scene of ``frame`` (the same object while no file name changes)."""
        from .loader import load_scene
        from .obj import load_obj

        paths = tuple(self.paths(frame))
        if self._last_scene is not None and self._last_scene[0] == paths:
            return self._last_scene[1]
        wanted = set(paths)
        self._parsed = {p: d for p, d in self._parsed.items() if p in wanted}   # drop other frames' files
        for p in paths:
            if p not in self._parsed:
                self._parsed[p] = load_obj(p)
                self.loads += 1
        scene = load_scene([self._parsed[p] for p in paths], self.mtls, warn=lambda message: None)
        self._last_scene = (paths, scene)
        return scene


# ---------------------------------------------------------------------------------------------
# Rendering


def render_animation(objs: Sequence[str] | ObjSequence, mtls: Sequence[str] = (), frames: Sequence[int] = (0,),
                     camera: Camera | CameraPath | None = None, settings=None, *, client=None, options=None,
                     progress=False, **kw) -> Iterator[tuple[int, np.ndarray]]:
    """Render ``frames``; yield ``(frame, float32 (H, W, 3) image)`` as each frame finishes.

    ``settings`` is a :class:`warp_spt.renderer.RenderSettings`, or its fields are given as keywords.
    Without ``client`` frames render here, in order, and a mesh that does not change between frames
    is uploaded once. With a ``dask.distributed`` Client every frame's sample ranges become cluster
    tasks (``options``: a :class:`warp_spt.cluster.ClusterOptions`; see :mod:`warp_spt.cluster`),
    each mesh is shipped and uploaded once per worker, and frames come in the order they finish.
    Either way frame k is the same image as a single render of its scene and camera (same seed for
    every frame). ``progress`` (True or a callable ``(done, total)``) counts samples x pixels of the
    whole run.
    """
    from .renderer import RenderSettings

    seq = objs if isinstance(objs, ObjSequence) else ObjSequence(objs, mtls)
    frames = list(frames)
    if settings is not None and kw:
        raise TypeError("give either settings or keyword settings, not both")
    rs = settings if settings is not None else RenderSettings(**kw)
    if client is not None:
        yield from _render_on_cluster(client, seq, frames, camera, rs, options, progress)
        return
    yield from _render_here(seq, frames, camera, rs, progress)


def frame_scene(seq: ObjSequence, frame: int, camera: Camera | CameraPath | None) -> tuple[Scene, Camera]:
    """The scene and camera of ``frame``, recentred as a single render recentres them (a no-op for a
    scene near the origin, so its static meshes stay the same arrays)."""
    from .framing import recentre

    scene, cam, _ = recentre(seq.scene(frame), camera_at(camera, frame))
    return scene, cam


def _render_here(seq: ObjSequence, frames: list[int], camera, rs, progress):
    from .device_scene import DeviceScene
    from .renderer import render_scene

    frame_total = rs.width * rs.height * rs.spp
    report = _frames_progress(progress, len(frames) * frame_total)
    dev = None
    meshes: dict[str, object] = {}             # wp.Mesh by content: static meshes are built once
    try:
        for i, k in enumerate(frames):
            scene, cam = frame_scene(seq, k, camera)
            if dev is None or scene is not dev.scene:       # upload again only when the scene changed
                dev = DeviceScene(scene, device=rs.device, meshes=meshes)
                for key in set(meshes) - set(dev.mesh_keys):
                    del meshes[key]
            per_frame = (lambda done, total, base=i * frame_total: report(base + done)) if report else False
            yield k, render_scene(dev, cam, rs, progress=per_frame).image
    finally:
        if report:
            report(None)


def _frames_progress(progress, total: int):
    """A function taking the run's absolute done count (None closes), or None for no progress."""
    if progress is False or progress is None:
        return None
    bar = None
    if not callable(progress):
        from .progress import ProgressBar
        bar = progress = ProgressBar(total, delay=0.0)

    def report(done):
        if done is None:
            if bar is not None:
                bar.close()
        else:
            progress(done, total)
    return report


def _render_on_cluster(client, seq: ObjSequence, frames: list[int], camera, rs, options, progress):
    from . import cluster

    rs = cluster.cluster_settings(rs)
    shared: dict[str, object] = {}           # what is on the cluster already: static meshes go once
    jobs = []
    for k in frames:
        scene, cam = frame_scene(seq, k, camera)
        jobs.append(cluster.Job(cluster.share_scene(client, scene, shared), cam, rs))
    for j, result in cluster.run_jobs(client, jobs, options or cluster.ClusterOptions(), progress=progress):
        yield frames[j], result.image


def save_gif(path: str | Path, images: Sequence[np.ndarray], *, fps: float = 12.0, tonemap: str = "seed") -> None:
    """Write images as an animated GIF preview, one adaptive palette per frame, atomically.

    Linear float images are tone mapped with ``tonemap``; uint8 ones are taken as they are.
    """
    from PIL import Image

    from .film import _TONEMAPS, atomic_write

    if not images:
        raise ValueError("a GIF needs at least one frame")
    if tonemap not in _TONEMAPS:
        raise ValueError(f"unknown tone map {tonemap!r}; expected one of {', '.join(_TONEMAPS)}")
    pictures = [Image.fromarray(im if im.dtype == np.uint8 else _TONEMAPS[tonemap](np.asarray(im, np.float32))
                                ).convert("P", palette=Image.Palette.ADAPTIVE, colors=256) for im in images]
    duration = max(20, round(1000.0 / fps))

    def write(f) -> None:
        pictures[0].save(f, format="GIF", save_all=True, append_images=pictures[1:], duration=duration,
                         loop=0, optimize=True)

    atomic_write(path, write)


# ---------------------------------------------------------------------------------------------
# Command line: the flags --frames, --camera-path, --gif, --cluster, --workers (see warp_spt.cli)

DEFAULT_FRAME_OUT = "frame_{frame:04d}.png"


def with_animation_options(opts, ns, *, explicit_out: bool):
    """Add the cluster and animation flags of the parsed namespace ``ns`` to ``opts``, validated.

    Without an explicit ``-out`` an animation writes ``frame_{frame:04d}.png``, or only the GIF when
    ``--gif`` is given (then ``opts.out`` is empty).
    """
    from .cli import OUTPUT_SUFFIXES, UsageError

    if ns.cluster and ns.workers:
        raise UsageError("give either --cluster or --workers, not both")
    if ns.camera_path and ns.cam:
        raise UsageError("give either -cam or --camera-path, not both")
    if ns.gif is not None and Path(ns.gif).suffix.lower() != ".gif":
        raise UsageError(f"--gif {ns.gif!r}: the file name must end in .gif")
    try:
        frames = parse_frames(ns.frames) if ns.frames is not None else None
    except ValueError as err:
        raise UsageError(f"argument --frames: {err}") from None
    opts = replace(opts, cluster=ns.cluster, workers=ns.workers, frames=frames, camera_path=ns.camera_path,
                   gif=ns.gif)
    check_budget_flags(opts)
    if not opts.animated:
        return opts
    templates = [p for p in opts.objs if is_template(p)]
    if templates and frames is None and not opts.camera_path:
        raise UsageError(f"-obj {templates[0]!r} names one file per frame: give --frames A:B")
    out = opts.out if explicit_out else ("" if opts.gif else DEFAULT_FRAME_OUT)
    several = frames is None or len(frames) > 1
    if out and several and not is_template(out):
        raise UsageError(f"-out {out!r}: an animation writes one file per frame; "
                         "put {frame} in the name, e.g. frame_{frame:04d}.png")
    for name in templates + ([out] if out else []):
        try:
            frame_path(name, 0)
        except ValueError as err:
            raise UsageError(str(err)) from None
    if out and Path(frame_path(out, 0)).suffix.lower() not in OUTPUT_SUFFIXES:
        raise UsageError(f"-out {out!r}: the file name must end in .png, .npy or .pfm")
    return replace(opts, out=out)


def _run_budgeted(opts, scene, say, started: float | None) -> int:
    """One image on the cluster until --time-budget or --target-error (-sr: the maximum) is met."""
    from .cli import EXIT_OK
    from .film import save_image
    from .progressive import UNLIMITED_SPP

    b = opts.budget
    rs = replace(settings_of(opts), spp=opts.spp if b.spp_given else UNLIMITED_SPP)

    def on_pass(res) -> None:
        say(f"round {res.stats.passes}: {res.spp_total} spp, {res.stats.seconds:.1f} s, "
            f"estimated relative error {100 * res.relative_error:.2f}%")

    with cluster_client(opts) as client:
        from . import cluster
        res = cluster.render_progressive(client, scene, opts.camera, rs, time_budget=b.time_budget,
                                         target_error=b.target_error, on_pass=on_pass, started=started)
    save_image(opts.out, res.image, tonemap=opts.tonemap)
    say(f"wrote {opts.out} ({res.spp_total} spp, {res.stats.seconds:.1f} s since start, stopped by "
        f"{res.stats.stopped_by}); estimated relative error of the image: {100 * res.relative_error:.2f}%")
    return EXIT_OK


@contextmanager
def cluster_client(opts):
    """The Dask client that ``--cluster`` or ``--workers`` asks for (closed after), or None."""
    if not (opts.cluster or opts.workers):
        yield None
        return
    from .cli import RunError
    try:
        from . import cluster
    except ImportError as err:
        raise RunError(str(err)) from None
    if opts.workers:
        with cluster.local_client(opts.workers) as client:
            yield client
        return
    try:
        context = cluster.connect(opts.cluster)
        client = context.__enter__()
    except (OSError, TimeoutError, ValueError) as err:
        raise RunError(f"cannot connect to the cluster at {opts.cluster}: {err}") from None
    try:
        yield client
    finally:
        context.__exit__(None, None, None)


def settings_of(opts):
    """The RenderSettings the command line asks for."""
    from .renderer import RenderSettings

    chosen = {k: v for k, v in (("integrator", opts.integrator), ("sampler", opts.sampler)) if v}
    return RenderSettings(width=opts.width, height=opts.height, spp=opts.spp, max_depth=opts.depth, sky=opts.sky,
                          seed=opts.seed, texture_filter=opts.texture_filter, threads=opts.threads, **chosen)


BUDGET_FLAGS = (("adaptive", "--adaptive"), ("min_spp", "--min-spp"), ("save_partial", "--save-partial"),
                ("progressive", "--progressive"), ("error_map", "--error-map"), ("spp_map", "--spp-map"),
                ("denoise", "--denoise"))


def check_budget_flags(opts) -> None:
    """On a cluster only --time-budget and --target-error of the budget flags apply, and to one image."""
    from .cli import UsageError

    b = opts.budget
    if not (opts.cluster or opts.workers or opts.animated) or not b.active:
        return
    where = "an animation" if opts.animated else "a cluster"
    if opts.animated:
        raise UsageError(f"budget and error flags are not supported for {where}: render frames with -sr")
    for name, flag in BUDGET_FLAGS:
        if getattr(b, name):
            raise UsageError(f"{flag} is not supported on {where} (--time-budget and --target-error are)")


def run_cli(opts, err, started: float | None = None) -> int:
    """``warp-spt`` with --frames / --camera-path / --gif / --cluster / --workers: render and write the frames."""
    from .cli import EXIT_OK, PROG, check_files, one_line, scene_files
    from .cli_common import init_warp
    from .film import _TONEMAPS, save_image
    from .progress import ProgressBar

    say = (lambda msg: None) if opts.quiet else (lambda msg: print(f"{PROG}: {one_line(msg)}", file=err))
    objs, mtls = scene_files(opts)
    path = CameraPath.load(opts.camera_path) if opts.camera_path else None
    frames = opts.frames or (path.frames if path is not None else range(0, 1))
    seq = ObjSequence(objs, mtls)
    for k in frames:                       # every frame's inputs and outputs, before any rendering
        check_files(seq.paths(k), mtls, frame_path(opts.out or opts.gif, k))
    init_warp(opts)
    start = time.perf_counter()
    first = seq.scene(frames[0])
    for warning in first.warnings:
        say(f"warning: {warning}")
    where = (f"the cluster at {opts.cluster}" if opts.cluster else
             f"{opts.workers} local worker processes" if opts.workers else "this machine")
    b = opts.budget
    spp = (f"{opts.spp} spp" if not b.active else
           f"until {' or '.join(f for f, v in (('--time-budget', b.time_budget), ('--target-error', b.target_error)) if v)}"
           + (f" (at most {opts.spp} spp)" if b.spp_given else ""))
    say(f"loaded frame {frames[0]}: {first.num_triangles:,} triangles, {len(first.spheres)} spheres in "
        f"{time.perf_counter() - start:.1f} s; rendering {len(frames)} frame(s) of {opts.width}x{opts.height}, "
        f"{spp}, depth {opts.depth} on {where}")
    if opts.animated:
        def images(client, progress):
            return render_animation(seq, mtls, frames, path or opts.camera, settings_of(opts), client=client,
                                    progress=progress)
    else:            # one image on a cluster: the view (recentring, framing, sky) of the single-process CLI
        from .cli import CompileNotice, _view
        with CompileNotice(say):
            scene, camera, sky = _view(opts, first, say)
        opts = replace(opts, camera=camera, sky=sky)
        if opts.budget.active:
            return _run_budgeted(opts, scene, say, started)

        def images(client, progress):
            from .cluster import render_scene
            return [(frames[0], render_scene(client, scene, camera, settings_of(opts), progress=progress).image)]
    bar = None if opts.quiet else ProgressBar(len(frames) * opts.width * opts.height * opts.spp, file=err)
    previews: dict[int, np.ndarray] = {}
    start = time.perf_counter()
    try:
        with cluster_client(opts) as client:
            for k, image in images(client, bar or False):
                if opts.out:
                    save_image(frame_path(opts.out, k), image, tonemap=opts.tonemap)
                if opts.gif:
                    previews[k] = _TONEMAPS[opts.tonemap](image)
    finally:
        if bar is not None:
            from .signals import deferred_signals
            with deferred_signals():    # never interrupt tqdm while it holds its lock (as cli.run)
                bar.close()
    if opts.gif:
        save_gif(opts.gif, [previews[k] for k in sorted(previews)])
    seconds = time.perf_counter() - start
    written = ", ".join(x for x in (opts.out, opts.gif) if x)
    say(f"wrote {written} ({len(frames)} frame(s), {seconds:.1f} s)")
    return EXIT_OK
