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
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Callable, Iterator, Sequence

import numpy as np

from warp_spt.io.templates import frame_path, is_template
from warp_spt.scene.camera import Camera
from warp_spt.scene.errors import SceneError
from warp_spt.scene.limits import MAX_FPS, MIN_FPS
from warp_spt.scene.model import ObjData, Scene
from warp_spt.scene.sky import Sky

MAX_CAMERA_PATH_BYTES = 64 << 20   # keyframes of a long animation fit in a fraction of this

# prepares one frame as a single render would: (scene, camera) -> (scene, camera, sky or None)
View = Callable[[Scene, Camera], tuple[Scene, Camera, 'Sky | None']]

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
        from warp_spt.io.tokens import normalise_text, read_file

        path = str(path)
        raw = normalise_text(read_file(path, "camera path", limit=MAX_CAMERA_PATH_BYTES), path, "camera path")
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            raise SceneError(path, 0, "camera path is not UTF-8 text") from None
        try:
            data = json.loads(text)
        except json.JSONDecodeError as err:
            raise SceneError(path, err.lineno, f"invalid JSON: {err.msg}") from None
        except RecursionError:
            raise SceneError(path, 0, "invalid camera path: JSON nested too deeply") from None
        except ValueError as err:       # e.g. an integer past Python's 4,300-digit limit
            raise SceneError(path, 0, f"invalid JSON: {err}") from None
        try:
            return cls.from_json(data)
        except ValueError as err:
            raise SceneError(path, 0, str(err)) from None

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

    ``loads`` counts OBJ files parsed (tests check that static files are parsed once). ``lights``
    (sun, point and spot lights: ``warp_spt.SunLight``...) join every frame's own lights, ``fog`` (a
    ``warp_spt.scene.media.Medium``) fills every frame, ``sky`` (a ``warp_spt.Sky``, an environment map
    included) is every frame's own sky: all part of the scene, so they travel with it to a cluster's
    workers (the command line's ``--sun``, ``--light``, ``--fog`` and ``--env``).
    """

    def __init__(self, objs: Sequence[str], mtls: Sequence[str] = (), *, default_material: str = "checker",
                 fps: float = 24.0, smooth_angle: float | str | None = None, lights: Sequence = (),
                 fog=None, sky=None) -> None:
        from warp_spt.scene.lights import PUNCTUAL_TYPES

        for light in lights:
            if not isinstance(light, PUNCTUAL_TYPES):
                raise TypeError(f"lights must be SunLight, PointLight or SpotLight records, got {type(light).__name__}")
        if fog is not None:
            fog.check("fog")
        self.lights, self.fog, self.sky = tuple(lights), fog, sky
        self.objs = [str(p) for p in objs]
        self.mtls = [str(p) for p in mtls]
        self.default_material = default_material     # as load_scene's: "checker", "clay" or "auto"
        if not MIN_FPS <= float(fps) <= MAX_FPS:      # also NaN
            raise ValueError(f"fps must lie in [{MIN_FPS:g}, {MAX_FPS:g}], got {fps!r}")
        self.fps = float(fps)                         # an animated glTF's frame k is posed at k / fps seconds
        self.smooth_angle = smooth_angle             # as load_scene's
        self.loads = 0
        self._parsed: dict[str, ObjData] = {}
        self._last_scene: tuple[tuple, Scene] | None = None     # ((paths, frame or None), scene)

    @property
    def animated(self) -> bool:
        """True when some OBJ path is a per-frame template."""
        return any(is_template(p) for p in self.objs)

    def default_frames(self) -> range | None:
        """The frames that cover the animated glTF files' time ranges at ``fps`` (from frame 0, at time
        0), or None when no static file is an animated glTF."""
        from warp_spt.io.loader import read_model

        end = None
        for p in self.objs:
            if is_template(p):
                continue
            if p not in self._parsed:
                self._parsed[p] = read_model(p)
                self.loads += 1
            span = getattr(self._parsed[p].extras, "time_range", None)
            if span is not None:
                end = max(end or 0.0, span[1])
        return None if end is None else range(0, int(math.floor(end * self.fps + 1e-9)) + 1)

    def check(self, frames: Sequence[int]) -> list[int]:
        """Pose every animated glTF at every frame before the first is rendered, so that a frame whose
        pose is out of range (keys of 1e30) ends the run before any work, not part-way: SceneError
        naming the file, the frame and what is wrong. Returns the frames whose every object is hidden
        (scaled to nothing; rendered empty). One parse of each animated file per frame."""
        from warp_spt.io.loader import read_model

        for p in self.objs:
            if not is_template(p) and p not in self._parsed:
                self._parsed[p] = read_model(p)
                self.loads += 1
        animated = [p for p in self.objs if not is_template(p)
                    and getattr(self._parsed[p].extras, "time_range", None) is not None]
        hidden = []
        for k in frames if animated else ():
            empty = not any(self._has_geometry(self._parsed[p]) for p in self.objs if p not in animated)
            for p in animated:
                try:
                    posed = self._posed(p, k)
                except SceneError as err:
                    raise SceneError(err.path, err.line, f"at frame {k} ({k / self.fps:g} s): {err.message}") from None
                empty = empty and not self._has_geometry(posed)
            if empty and not any(is_template(p) for p in self.objs):
                hidden.append(k)
        return hidden

    def bounds(self, frames: Sequence[int]) -> np.ndarray | None:
        """(2, 3) float64 world bounds of ``frames``' scenes together (frames that hide everything
        left out), or None when none has geometry: what an animation without a camera is framed
        over, once (``cli.view_checks.frame_view``). Costs one more load of each frame's scene."""
        from warp_spt.scene.camera import exact_bounds

        boxes = []
        for k in frames:
            scene = self.scene(k)
            if not scene.hidden:
                boxes.append(exact_bounds(scene))
        if not boxes:
            return None
        boxes = np.asarray(boxes)
        return np.stack([boxes[:, 0].min(axis=0), boxes[:, 1].max(axis=0)])

    @staticmethod
    def _has_geometry(d: ObjData) -> bool:
        return bool(len(d.faces) or len(d.spheres) or getattr(d.extras, "placed", ()))

    def paths(self, frame: int) -> list[str]:
        """The OBJ files of ``frame``."""
        return [frame_path(p, frame) for p in self.objs]

    def scene(self, frame: int) -> Scene:
        """The validated scene of ``frame`` (the same object while no file name changes)."""
        from warp_spt.io.loader import load_scene, read_model

        paths = tuple(self.paths(frame))
        wanted = set(paths)
        self._parsed = {p: d for p, d in self._parsed.items() if p in wanted}   # drop other frames' files
        for p in paths:
            if p not in self._parsed:
                self._parsed[p] = read_model(p)
                self.loads += 1
        # an animated glTF is posed again for each frame (its nodes move; its file is the same)
        posed = [p for p in paths if getattr(self._parsed[p].extras, "time_range", None) is not None]
        key = (paths, frame if posed else None)
        if self._last_scene is not None and self._last_scene[0] == key:
            return self._last_scene[1]
        data = [self._posed(p, frame) if p in posed else self._parsed[p] for p in paths]
        scene = load_scene(data, self.mtls, warn=lambda message: None, default_material=self.default_material,
                           smooth_angle=self.smooth_angle, hidden_ok=bool(posed))
        if self.lights or self.fog is not None or self.sky is not None:
            scene = replace(scene, lights=[*scene.lights, *self.lights],
                            fog=scene.fog if self.fog is None else self.fog,
                            sky=scene.sky if self.sky is None else self.sky)
        self._last_scene = (key, scene)
        return scene

    def _posed(self, path: str, frame: int):
        from warp_spt.io.loader import read_model

        return read_model(path, time=frame / self.fps)


# ---------------------------------------------------------------------------------------------
# Rendering


def render_animation(objs: Sequence[str] | ObjSequence, mtls: Sequence[str] = (), frames: Sequence[int] = (0,),
                     camera: Camera | CameraPath | None = None, settings=None, *, client=None, options=None,
                     progress=False, view: View | None = None, lights: Sequence = (), fog=None,
                     **kw) -> Iterator[tuple[int, np.ndarray]]:
    """Render ``frames``; yield ``(frame, float32 (H, W, 3) image)`` as each frame finishes.

    ``settings`` is a :class:`warp_spt.rendering.settings.RenderSettings`, or its fields are given as keywords.
    Without ``client`` frames render here, in order, and a mesh that does not change between frames
    is uploaded once. With a ``dask.distributed`` Client every frame's sample ranges become cluster
    tasks (``options``: a :class:`warp_spt.cluster.ClusterOptions`; see :mod:`warp_spt.cluster`),
    each mesh is shipped and uploaded once per worker, and frames come in the order they finish.
    Either way frame k is the same image as a single render of its scene and camera (same seed for
    every frame). ``progress`` (True or a callable ``(done, total)``) counts samples x pixels of the
    whole run. ``view(scene, camera) -> (scene, camera, sky or None)`` prepares each frame as a
    single render would (the command line's recentring, framing and studio: the same function, so
    frame k is the image of a single render of frame k's files); without it a frame is recentred only.
    ``lights`` and ``fog`` join every frame's scene (:class:`ObjSequence`'s; with a fog, render with
    ``integrator="volpath"``); an environment is ``settings.sky``, or ``ObjSequence(..., sky=...)``.
    """
    from warp_spt.rendering.settings import RenderSettings

    if isinstance(objs, ObjSequence):
        if lights or fog is not None:
            raise TypeError("give lights and fog to the ObjSequence, not to render_animation as well")
        seq = objs
    else:
        seq = ObjSequence(objs, mtls, lights=lights, fog=fog)
    frames = list(frames)
    if settings is not None and kw:
        raise TypeError("give either settings or keyword settings, not both")
    rs = settings if settings is not None else RenderSettings(**kw)
    if client is not None:
        yield from _render_on_cluster(client, seq, frames, camera, rs, options, progress, view)
        return
    yield from _render_here(seq, frames, camera, rs, progress, view)


def frame_scene(seq: ObjSequence, frame: int, camera: Camera | CameraPath | None, rs,
                view: View | None = None) -> tuple[Scene, Camera, object]:
    """The scene, camera and settings of ``frame``: prepared by ``view`` (see :func:`render_animation`),
    or recentred as a single render recentres them (a no-op for a scene near the origin, so its
    static meshes stay the same arrays)."""
    from warp_spt.scene.recentre import recentre

    if view is None:
        scene, cam, _ = recentre(seq.scene(frame), camera_at(camera, frame))
        return scene, cam, rs
    scene, cam, sky = view(seq.scene(frame), camera_at(camera, frame))
    return scene, cam, rs if sky is None else replace(rs, sky=sky)


def _render_here(seq: ObjSequence, frames: list[int], camera, rs, progress, view):
    from warp_spt.upload.device_scene import DeviceScene
    from warp_spt.rendering.tiles import render_scene

    frame_total = rs.width * rs.height * rs.spp
    report = _frames_progress(progress, len(frames) * frame_total)
    dev = None
    meshes: dict[str, object] = {}             # wp.Mesh by content: static meshes are built once
    try:
        for i, k in enumerate(frames):
            scene, cam, frame_rs = frame_scene(seq, k, camera, rs, view)
            if dev is None or scene is not dev.scene:       # upload again only when the scene changed
                dev = DeviceScene(scene, device=rs.device, meshes=meshes)
                for key in set(meshes) - set(dev.mesh_keys):
                    del meshes[key]
            per_frame = (lambda done, total, base=i * frame_total: report(base + done)) if report else False
            yield k, render_scene(dev, cam, frame_rs, progress=per_frame).image
    finally:
        if report:
            report(None)


def _frames_progress(progress, total: int):
    """A function taking the run's absolute done count (None closes), or None for no progress."""
    if progress is False or progress is None:
        return None
    bar = None
    if not callable(progress):
        from warp_spt.runtime.progress import ProgressBar
        bar = progress = ProgressBar(total, delay=0.0)

    def report(done):
        if done is None:
            if bar is not None:
                bar.close()
        else:
            progress(done, total)
    return report


def _render_on_cluster(client, seq: ObjSequence, frames: list[int], camera, rs, options, progress, view):
    from warp_spt import cluster

    shared: dict[str, object] = {}           # what is on the cluster already: static meshes go once
    jobs = []
    for k in frames:
        scene, cam, frame_rs = frame_scene(seq, k, camera, rs, view)
        jobs.append(cluster.Job(cluster.share_scene(client, scene, shared), cam, cluster.cluster_settings(frame_rs)))
    for j, result in cluster.run_jobs(client, jobs, options or cluster.ClusterOptions(), progress=progress):
        yield frames[j], result.image


# ---------------------------------------------------------------------------------------------
# Command line: the flags --frames, --camera-path, --gif, --cluster, --workers (see warp_spt.cli.main)


