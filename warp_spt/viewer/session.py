"""The viewer's state machine, shared by the browser and the Jupyter hosts.

A :class:`Session` owns the scene, the orbit camera (:mod:`.navigation`), the render settings and
one background render thread. A host passes it the front end's messages (:meth:`Session.handle`)
and gets back JSON-able messages with binary buffers (frames, files) through listeners.

How rendering stays responsive: every change bumps a version number. While the camera moves (a
drag, or within SETTLE_SECONDS of the last change) the thread renders low-resolution previews
of the newest version, a few samples per pixel (:func:`preview_plan`); once it settles, it refines at full size pass by pass. A pass
is cut into bands of rows (``render_scene(..., rows=...)``), each a fraction of a second, and the
version is checked between bands: a new interaction abandons the pass within one band. Threads
are never killed.

How samples add up: the refined image is kept as BATCHES batch sums, as
``warp_spt.render_progressive`` keeps them (docs/error.md): batch b renders with that renderer's
seed for batch b (``rendering.schedule.batch_seed``) and continues its own sample sequence
(``sample_offset``), so batches are independent and their spread gives each pixel's standard error,
batch b draws the sample stream of ``render_progressive``'s batch b, and the image is an exact
float64 sum of the samples.
"""

from __future__ import annotations

import copy
import math
import os
import tempfile
import threading
import time
import traceback
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from warp_spt.rendering.schedule import batch_seed
from warp_spt.scene.families import DEFAULT_SAMPLER
from warp_spt.scene.limits import MAX_DEPTH, MAX_ENV_ROTATE, MAX_RADIANCE, MAX_SPP, MAX_VIEW_PIXELS

from . import display, lighting, messages, navigation
from .command import CommandSpec, command_line
from .raycast import first_hit

BATCHES = 8                  # independent sample streams of the refined image (error estimate)
SETTLE_SECONDS = 0.25        # no change for this long: the camera has stopped, refine
DRAG_TIMEOUT = 2.0           # a drag without events for this long has ended (a lost "interact" message)
PASS_SECONDS = 0.5           # aim of a refine pass: the display updates about twice a second
BAND_SECONDS = 0.12          # aim of one render call: the longest a new interaction waits
# A preview costs one sample per PREVIEW_PIXELS_PER_SAMPLE pixels of the view, spent as preview_scale
# says: 1/8 of the view's size per side at 4 spp by default. At equal samples (equal time) it shows the
# view with 0.087 RMS error against a converged image where the 1/4-size 1-spp preview had 0.194
# (scripts/measure_viewer_preview.py, docs/viewer.md).
PREVIEW_PIXELS_PER_SAMPLE = 16
PREVIEW_SECONDS = 0.05       # a preview renders in this long at most (20 fps), shrinking if it must...
MAX_PREVIEW_SHRINK = 2.0     # ...but to no less than half the preview_scale size per side
MAX_PASS_SPP = 256
SLOW_CALL_SECONDS = 1.0      # a render call this slow is compiling a kernel: say so on the page
SKY_NAMES = ("blue", "gradient", "pink", "studio", "black", "color", "environment")
DISPLAY_KEYS = ("exposure", "tonemap", "error_map")   # change the picture, not the render

SHARED_NOTICE = ("this view is open in {n} other tab(s): they show the same render, and a change here "
                 "changes it there too")
JOINED_NOTICE = "another tab opened this view ({n} in all): a change in any of them changes them all"

Listener = Callable[[dict, list], None]


@dataclass(frozen=True)
class ViewSettings:
    """Everything the page can set besides the camera. ``sky`` is one of SKY_NAMES ("blue" is
    the seed's BlackSky, ``-sky 0``; "studio" the studio look's grey); ``sky_color`` is the "color"
    sky's radiance; ``exposure``
    is in stops; ``preview_scale`` divides the view size while the camera moves."""

    width: int = 384
    height: int = 288
    integrator: str = "nee"
    sampler: str = DEFAULT_SAMPLER
    max_depth: int = 6
    sky: str = "blue"
    sky_color: tuple = (0.5, 0.5, 0.5)
    env_path: str = ""              # the "environment" sky's map file (--env), its turn and strength
    env_rotate: float = 0.0
    env_strength: float = 1.0
    env_background: tuple | None = None   # what camera rays that miss see (--env-background); None: the map
    # lights and a fog the page adds (viewer/lighting.py; the command line's --sun, --light, --fog);
    # positions in world coordinates; (0, 0, 0) directions are placed when the scene loads
    sun: bool = False
    sun_direction: tuple = (0.0, 0.0, 0.0)     # towards the sun
    sun_color: tuple = (1.0, 1.0, 1.0)         # its irradiance on a surface facing it
    sun_radius: float = 0.0                    # angular radius, degrees (0: a delta light)
    lamp: str = "off"                          # "off", "point" or "spot"
    lamp_position: tuple = (0.0, 0.0, 0.0)
    lamp_intensity: tuple = (1.0, 1.0, 1.0)    # W/sr
    lamp_direction: tuple = (0.0, 0.0, 0.0)    # where a spot shines
    lamp_angle: float = 30.0                   # a spot's outer cone angle, degrees
    fog: bool = False
    fog_sigma_a: tuple = (0.01, 0.01, 0.01)    # per unit length
    fog_sigma_s: tuple = (0.05, 0.05, 0.05)
    fog_g: float = 0.0                         # Henyey-Greenstein asymmetry, |g| <= 0.999999
    max_spp: int = 1024
    preview_scale: int = 8
    exposure: float = 0.0
    tonemap: str = "seed"           # until the first load: the command line's (rendering.first_view.tone_map)
    error_map: bool = False


def make_sky(settings: ViewSettings, environment=None, keyed: bool = True):
    """The :class:`warp_spt.Sky` the settings name; ``environment``: the "environment" sky's map (an
    :class:`warp_spt.scene.environment.EnvironmentMap` read from ``env_path``, kept by the session so
    that the light table built for it is reused); ``keyed``: the studio's key light is shown (else
    its sky is the dimmer fill beside the user's lights, ``studio.studio_sky``)."""
    from warp_spt import Sky
    from warp_spt.scene.studio import studio_sky

    if settings.sky == "environment":
        if environment is None:
            raise ValueError("the environment sky needs a map: give its file (.hdr, .exr, .pfm) first")
        return Sky.environment(environment, rotate=settings.env_rotate, strength=settings.env_strength,
                               background=settings.env_background)
    return {"blue": Sky.black, "gradient": Sky.gradient, "pink": Sky.pink,
            "studio": lambda: studio_sky(keyed), "black": lambda: Sky.constant(0.0, 0.0, 0.0),
            "color": lambda: Sky.constant(*settings.sky_color)}[settings.sky]()


def sky_command(settings: ViewSettings, studio: bool = False) -> tuple[str | None, tuple]:
    """(-sky name, "studio" or None, --sky-color value) for :class:`.command.CommandSpec`; "studio"
    (no sky flag) when the studio look is on and its sky shown."""
    if settings.sky in ("blue", "gradient", "pink", "environment") or (studio and settings.sky == "studio"):
        return settings.sky, (0.0, 0.0, 0.0)
    return None, make_sky(settings).color


def _read_environment(path: str):
    """The map of an environment file (ValueError naming the file, as the command line's)."""
    import warp_spt

    return warp_spt.load_environment(path).env


def checked_settings(settings: ViewSettings, key: str, value) -> ViewSettings:
    """``settings`` with ``key`` set to ``value`` converted to the field's type; ValueError if invalid."""
    import warp_spt

    kinds = {f.name: f.type for f in fields(ViewSettings)}
    if key not in kinds:
        raise ValueError(f"unknown setting {key!r}")
    current = getattr(settings, key)
    if key in lighting.VECTORS:
        value = lighting.vector(value, key)
    elif isinstance(current, bool):
        value = bool(value)
    elif isinstance(current, tuple):
        value = tuple(float(v) for v in value)
    else:
        value = type(current)(value)
    choices = {"integrator": _progressive_integrators(), "sampler": warp_spt.SAMPLERS, "sky": SKY_NAMES,
               "tonemap": ("srgb", "seed", "filmic")}
    if key in choices and value not in choices[key]:
        raise ValueError(f"{key} must be one of {', '.join(sorted(choices[key]))}, got {value!r}")
    limits = {"width": (8, 4096), "height": (8, 4096), "max_depth": (1, MAX_DEPTH), "max_spp": (1, MAX_SPP),
              "preview_scale": (1, 16), "exposure": (-20.0, 20.0), "env_rotate": (-MAX_ENV_ROTATE, MAX_ENV_ROTATE),
              "env_strength": (0.0, MAX_RADIANCE)}
    if key in limits and not limits[key][0] <= value <= limits[key][1]:
        raise ValueError(f"{key} must lie in [{limits[key][0]}, {limits[key][1]}], got {value}")
    if key == "sky_color":
        warp_spt.Sky.constant(*value)          # Sky validates a colour (ValueError)
    new = replace(settings, **{key: value})
    lighting.check(new)                        # the page's lights and fog, as their records check them
    if new.width * new.height > MAX_VIEW_PIXELS:     # the refined image's batch sums: docs/viewer.md
        raise ValueError(f"a view of {new.width}x{new.height} is more than the {MAX_VIEW_PIXELS:,} pixels a view "
                         "may have (1920x1080 fits); render larger images with the copied command line")
    return new


def preview_plan(settings: ViewSettings, budget: float | None = None, smallest: int = 8) -> tuple[int, int, int]:
    """The preview's (width, height, spp): the view's size divided by ``preview_scale`` (no side below
    ``smallest`` pixels) at the spp that spends one sample per PREVIEW_PIXELS_PER_SAMPLE view
    pixels; where that is more than ``budget`` samples (what renders in PREVIEW_SECONDS), the size
    shrinks by up to MAX_PREVIEW_SHRINK times more per side at the same spp (fewer, better pixels
    beat more, noisier ones: docs/viewer.md). The same factor on both axes (the page stretches it)."""
    cap = min(settings.width, settings.height) / smallest
    f = max(1.0, min(float(settings.preview_scale), cap))
    spp = max(1, round(f * f / PREVIEW_PIXELS_PER_SAMPLE))
    if budget:
        f = min(max(f, math.sqrt(settings.width * settings.height * spp / budget)), MAX_PREVIEW_SHRINK * f)
    f = max(1.0, min(f, cap))
    return max(1, round(settings.width / f)), max(1, round(settings.height / f)), spp


class Accumulator:
    """The refined image of one version: per-batch float64 sums and sample counts.

    Every pass covers every pixel, so a batch's count is the same for all pixels. Passes go in
    rounds, one pass per batch with the same samples each (:meth:`pass_spp`), so after every round
    the batches are equal in size: their means are then identically distributed whatever the
    sampler does within a batch, and their spread is an unbiased estimate of the error."""

    def __init__(self, version: int, height: int, width: int, batches: int = BATCHES, seed: int = 0):
        self.version, self.height, self.width = version, height, width
        self.sums = np.zeros((batches, height, width, 3), dtype=np.float64)
        self.counts = np.zeros(batches, dtype=np.int64)
        self.seeds = [batch_seed(seed, b) for b in range(batches)]
        self.passes = 0
        self.seconds = 0.0
        self.round_spp = 1

    @property
    def spp(self) -> int:
        return int(self.counts.sum())

    @property
    def next_batch(self) -> int:
        return self.passes % len(self.counts)

    def pass_spp(self, wanted: int, max_spp: int) -> int:
        """Samples for the next pass: chosen at the start of a round (1 in the first, so an image
        and then an error estimate appear at once; later ``wanted``), and no more than keeps the
        rest of ``max_spp`` a whole number of rounds, so a multiple of the batch count ends equal."""
        batches = len(self.counts)
        if self.next_batch == 0 and self.passes > 0:
            self.round_spp = max(1, min(wanted, (max_spp - self.spp) // batches))
        return max(1, min(self.round_spp, max_spp - self.spp))

    def add(self, batch: int, sums: np.ndarray, spp: int, seconds: float) -> None:
        """A finished pass: ``spp`` more samples of batch ``batch`` in every pixel."""
        self.sums[batch] += sums
        self.counts[batch] += spp
        self.passes += 1
        self.seconds += seconds

    def statistics(self) -> tuple[np.ndarray, np.ndarray]:
        """(mean image, standard error of each pixel's mean), float32 (H, W, 3).

        The variance of the mean is the between-batch mean square sum_b n_b (m_b - m)^2 / (k - 1)
        over the k batches with samples, divided by the pixel's n samples; NaN while k < 2."""
        n = self.counts.astype(np.float64)
        used = n > 0
        total = n.sum()
        mean = self.sums.sum(axis=0) / max(total, 1.0)
        k = int(used.sum())
        if k < 2:
            return mean.astype(np.float32), np.full(mean.shape, np.nan, dtype=np.float32)
        between = np.zeros_like(mean)
        for b in np.flatnonzero(used):        # batch by batch: no copy of all the batches at once
            d = self.sums[b] / n[b] - mean
            between += n[b] * (d * d)
        between /= k - 1
        return mean.astype(np.float32), np.sqrt(between / total).astype(np.float32)


@dataclass
class _Shown:
    """The last picture published: enough to redraw it with other display settings."""

    image: np.ndarray
    std_error: np.ndarray | None
    meta: dict


class Session:
    """One interactive view of a scene: camera, settings, a render thread, messages in and out.

    ``scene`` is a :class:`warp_spt.Scene`; or give ``loader`` (a function returning one, such as
    ``lambda: warp_spt.load_scene(objs, mtls)``), which is called on the render thread and again
    on "reload": a :class:`warp_spt.SceneError` is then shown on the page. ``camera`` defaults to
    the seed's camera for the built-in demo (``objs`` empty) and to ``Camera.frame`` otherwise.
    ``objs``/``mtls`` are the file names the copied command line names; ``up`` the world's up
    axis ("z" or "y"...). ``studio`` True/False forces the studio look on or off (None: the rule);
    ``smooth_angle`` is what the file loader was given (for the copied command line). ``settings``
    are :class:`ViewSettings` fields.

    The first view is the command line's (:func:`warp_spt.rendering.first_view.first_view`): the
    scene recentred if far off, Y up for a standard OBJ, framed, and, for a scene with no light of
    its own and no ``sky`` setting, the studio look (its ground and key light placed from the first
    camera, the "studio" sky); the display's tone map is the command line's.
    """

    def __init__(self, scene=None, camera=None, *, loader: Callable | None = None, objs: Sequence[str] = (),
                 mtls: Sequence[str] = (), up: str | None = None, studio: bool | None = None,
                 smooth_angle: float | str = "auto", start: bool = True, **settings):
        if scene is None and loader is None:
            raise ValueError("give a scene or a loader")
        self.objs, self.mtls = tuple(map(str, objs)), tuple(map(str, mtls))
        self._cond = threading.Condition()
        self._settings = ViewSettings()
        for key, value in settings.items():      # the page's bounds hold for the first view too
            self._settings = checked_settings(self._settings, key, value)
        self._sky_given = "sky" in settings or "sky_color" in settings
        self._integrator_given = "integrator" in settings
        self._given = frozenset(settings)        # placed by the caller: the load does not place them
        self._own_lights: list = []      # the loaded scene's lights and fog, to which the page's are added
        self._own_fog = None
        self._relight = False            # the page's lights or fog changed: the scene is uploaded again
        self._meshes: dict = {}          # uploaded meshes, reused by those uploads (DeviceScene's cache)
        self._environment = _read_environment(self._settings.env_path) if self._settings.env_path else None
        self._studio_given = studio      # --studio / --no-studio; None: the rule
        self._smooth_angle = smooth_angle
        self._studio = False             # the first view added the studio look
        self._key = None                 # then the studio's key light, shown while no light of the user's is on
        self._offset = np.zeros(3)       # world = the session's coordinates + offset (recentring)
        self._given_camera = camera
        self._up = up or _axis_name(camera.up if camera is not None else (0.0, 0.0, 1.0))
        self._up_given = up is not None or camera is not None    # else warp_spt.up_axis's rule, on load
        # the scene is read (loader) and uploaded on the render thread, so a host starts at once;
        # material edits write through to the host scene, so a given one is copied, never changed
        self._loader = loader or (lambda: copy.deepcopy(scene))
        self._can_reload = loader is not None
        self._scene = self._params = None
        self._subject = None             # the scene without the studio's ground and light: what is framed
        self._rig = self._home = None
        self._version = self._preview_version = 0
        self._last_change, self._interacting = time.monotonic(), False
        self._pending: dict = {}
        self._edits: set[str] = set()    # parameters changed on the page (not on the command line)
        self._failed_version = -1        # a version whose render failed: not retried until a change
        self._reload = True
        self._error: str | None = None
        self._acc: Accumulator | None = None
        self._shown: _Shown | None = None
        self._frame: tuple[dict, list] | None = None
        self._rate = 0.0                 # pixel-samples per second of the last render calls
        self._preview_rate = 0.0         # ... of the last previews (overheads weigh more there)
        self._preview_times: list[float] = []
        self._listeners: list[Listener] = []
        self._closed = False
        self._thread = threading.Thread(target=self._run, name="warp_spt-viewer", daemon=True)
        if start:
            self._thread.start()

    # ------------------------------------------------------------------ public surface
    def start(self) -> None:
        """Start the render thread of a session made with ``start=False`` (listeners added first
        see every message, the load's included)."""
        self._thread.start()

    @property
    def camera(self):
        """The current view as a :class:`warp_spt.Camera` (None before the scene is loaded)."""
        with self._cond:
            return None if self._rig is None else rig_camera(self._rig)

    @property
    def settings(self) -> ViewSettings:
        return self._settings

    @property
    def version(self) -> int:
        """Counts the changes that restart the render; every frame message carries the one it shows."""
        return self._version

    @property
    def error(self) -> str | None:
        """The scene's or the last render's error message, shown on the page; None if all is well."""
        return self._error

    @property
    def viewers(self) -> int:
        """How many front ends (browser tabs, the Jupyter widget) show this session."""
        with self._cond:
            return len(self._listeners)

    def add_listener(self, listener: Listener) -> None:
        """Call ``listener(message, buffers)`` for every message to the front ends.

        Every front end shows and steers this one session (one render for the machine: a session
        per tab would give each a share of the cores); those already open are told another joined,
        and the new one is told on its "hello" (:data:`SHARED_NOTICE`)."""
        with self._cond:
            others = list(self._listeners)
            self._listeners.append(listener)
        for other in others:
            other({"type": "notice", "level": "info", "text": JOINED_NOTICE.format(n=len(others) + 1)}, [])
            other(self.state(), [])

    def remove_listener(self, listener: Listener) -> None:
        with self._cond:
            if listener not in self._listeners:
                return
            self._listeners.remove(listener)
        self._broadcast(self.state(), [])          # the count of views the pages show

    def handle(self, msg: dict, buffers: Sequence = (), reply: Listener | None = None) -> None:
        """Act on one message of a front end (see docs/viewer.md for the protocol). ``reply`` gets the
        answers meant for that front end only (state, files, the command line); by default every
        listener does. An invalid request is answered with a "notice" message, never raised."""
        reply = reply or self._broadcast
        try:
            msg = messages.checked(msg)        # the one gate: only declared fields, typed and bounded
        except ValueError as err:
            reply({"type": "notice", "level": "error", "text": str(err)}, [])
            return
        handler = getattr(self, f"_on_{msg['type']}", None)
        if handler is None:
            reply({"type": "notice", "level": "error", "text": f"unknown message {msg['type']!r}"}, [])
            return
        try:
            handler(msg, reply)
        except (ValueError, TypeError, KeyError) as err:      # a bad request or value
            reply({"type": "notice", "level": "error", "text": str(err)}, [])
        except Exception as err:       # a bug: shown on the page, the connection stays up
            if os.environ.get("WARP_SPT_TRACEBACK"):
                traceback.print_exc()
            reply({"type": "notice", "level": "error", "text": f"{type(err).__name__}: {err}"}, [])

    def result(self):
        """The refined image so far as a :class:`warp_spt.RenderResult` (image, per-pixel
        ``std_error``, ``spp``, ``relative_error``, per-batch ``sums``/``counts``), or None."""
        with self._cond:
            acc = self._acc
            if acc is None or acc.spp == 0:
                return None
            return _result(acc, self._settings, self._make_sky(self._settings))

    def wait_for(self, spp: int = 1, timeout: float = 60.0):
        """Block until the current view is refined to at least ``spp`` samples per pixel; returns
        :meth:`result`. Raises TimeoutError (or RuntimeError with the page's error message)."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while not (self._acc is not None and self._acc.version == self._version and self._acc.spp >= spp):
                if self._error and self._scene is None:
                    raise RuntimeError(self._error)
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"the view did not reach {spp} spp in {timeout} s")
                self._cond.wait(min(left, 0.5))
        return self.result()

    def command_line(self, width: int | None = None, height: int | None = None, spp: int = 64,
                     out: str = "view.png") -> str:
        """The ``warp-spt`` command that renders the current view at ``width`` x ``height``
        (default: the view's size; one given alone keeps the view's aspect) with ``spp`` samples."""
        s = self._settings
        for name, side in (("width", width), ("height", height)):
            if side is not None and (isinstance(side, bool) or not isinstance(side, (int, np.integer)) or side < 1):
                raise ValueError(f"the command line's {name} must be a positive integer, got {side!r}")
        if width and not height:
            height = max(1, round(width * s.height / s.width))
        elif height and not width:
            width = max(1, round(height * s.width / s.height))
        sky, colour = sky_command(s, self._studio)
        spec = CommandSpec(self.objs, self.mtls, self._up, int(width or s.width), int(height or s.height),
                           int(spp), s.max_depth, sky, colour, s.integrator, s.sampler, s.tonemap, out, s.exposure,
                           studio=self._studio, studio_off=self._studio_given is False,
                           env=(s.env_path, s.env_rotate, s.env_strength) if s.sky == "environment" else None,
                           env_background=s.env_background,
                           lighting=tuple(lighting.command_flags(s, self._own_fog)[0]),
                           smooth_angle=None if self._smooth_angle == "auto" else self._smooth_angle)
        camera = self.camera
        if camera is None:
            raise ValueError("the scene is not loaded yet")
        world = tuple(float(p + o) for p, o in zip(camera.position, self._offset))
        return command_line(replace(camera, position=world), spec)

    def save(self, path: str | os.PathLike) -> None:
        """Write the refined image: .png/.jpg tone mapped as shown (exposure included), .npy, .pfm
        and .exr linear (exposure not applied), through :func:`warp_spt.save_image`."""
        import warp_spt

        res = self.result()
        if res is None:
            raise ValueError("nothing is rendered yet")
        s = self._settings
        warp_spt.save_image(path, res.image, tonemap=s.tonemap, exposure=s.exposure)

    def close(self, timeout: float = 10.0) -> None:
        """Stop the render thread (it finishes the band it is rendering) and drop the listeners."""
        with self._cond:
            self._closed = True
            self._listeners.clear()
            self._cond.notify_all()
        if self._thread.is_alive() and threading.current_thread() is not self._thread:
            self._thread.join(timeout)

    def state(self) -> dict:
        """The "state" message: settings, choices, material parameters, error, files."""
        import warp_spt

        with self._cond:
            return {"type": "state", "settings": asdict(self._settings), "up": self._up,
                    "integrators": sorted(_progressive_integrators()), "samplers": sorted(warp_spt.SAMPLERS),
                    "skies": list(SKY_NAMES), "params": self._param_list(), "error": self._error,
                    "loading": self._scene is None and self._error is None, "can_reload": self._can_reload,
                    "objs": list(self.objs), "mtls": list(self.mtls), "formats": save_formats(),
                    "camera": None if self._rig is None else camera_info(self._rig),
                    "viewers": len(self._listeners)}

    def preview_fps(self) -> float:
        """Previews rendered per second over the last drag (render time only, no transport)."""
        times = self._preview_times[-20:]
        return 0.0 if len(times) < 2 else (len(times) - 1) / max(times[-1] - times[0], 1e-9)

    # ------------------------------------------------------------------ messages
    def _on_hello(self, msg, reply) -> None:
        state = self.state()
        reply(state, [])
        if state["viewers"] > 1:
            reply({"type": "notice", "level": "info", "text": SHARED_NOTICE.format(n=state["viewers"] - 1)}, [])
        if self._frame is not None:
            reply(*self._frame)

    def _on_interact(self, msg, reply) -> None:
        with self._cond:
            self._interacting = bool(msg.get("active"))
            self._last_change = time.monotonic()
            self._cond.notify_all()

    def _on_orbit(self, msg, reply) -> None:
        self._navigate(lambda rig: navigation.orbit(rig, float(msg["dx"]), float(msg["dy"])))

    def _on_pan(self, msg, reply) -> None:
        aspect = self._settings.width / self._settings.height
        self._navigate(lambda rig: navigation.pan(rig, float(msg["dx"]), float(msg["dy"]), aspect))

    def _on_dolly(self, msg, reply) -> None:
        self._navigate(lambda rig: navigation.dolly(rig, float(msg["steps"]), 1e-6 * self._scene_size()))

    def _on_zoom(self, msg, reply) -> None:
        self._navigate(lambda rig: navigation.zoom(rig, float(msg["steps"])))

    def _on_pick(self, msg, reply) -> None:
        rig, scene = self._rig, self._scene
        if rig is None or scene is None:
            return
        s = self._settings
        d = navigation.pixel_ray(rig, float(msg["x"]), float(msg["y"]), s.width / s.height)
        t = first_hit(scene, rig.position, d)
        if t is None:
            reply({"type": "notice", "level": "info", "text": "nothing there: the orbit target is unchanged"}, [])
            return
        self._navigate(lambda r: navigation.retarget(r, r.position + d * t))

    def _on_frame(self, msg, reply) -> None:
        if self._scene is not None:
            self._set_rig(self._framed(self._up))

    def _on_reset(self, msg, reply) -> None:
        with self._cond:
            if self._home is None:
                return
            rig, self._up = self._home
        self._set_rig(rig)

    def _on_up(self, msg, reply) -> None:
        axis = str(msg["axis"])
        if axis not in ("x", "y", "z", "-x", "-y", "-z"):
            raise ValueError(f"up axis must be x, y or z (or negated), got {axis!r}")
        if self._scene is None:
            return
        with self._cond:
            self._up = axis
        self._set_rig(self._framed(axis))
        reply(self.state(), [])

    def _on_set(self, msg, reply) -> None:
        key, value = msg["key"], msg["value"]
        if key in ("fov", "aperture"):
            self._navigate(lambda rig: navigation.with_fov(rig, float(value)) if key == "fov"
                           else replace(rig, aperture=_non_negative(value, "aperture")))
            return
        if key == "env_path":           # read before anything changes: a bad file leaves the view as it was
            environment = _read_environment(str(value)) if str(value).strip() else None
        with self._cond:
            self._settings = checked_settings(self._settings, key, value)
            if key == "env_path":
                self._environment = environment
            if key == "integrator":
                self._integrator_given = True
            # the sky too: an environment map, like the page's lights, replaces the studio's key
            if key in lighting.LIGHT_KEYS or key in lighting.FOG_KEYS or (key == "sky" and self._key is not None):
                self._relight = True
                if key == "fog":
                    self._settings = self._media_integrator(self._settings)
            if key not in DISPLAY_KEYS:
                self._changed()
        if key in DISPLAY_KEYS:
            self._redraw()
        self._broadcast(self.state(), [])

    def _media_integrator(self, s: ViewSettings) -> ViewSettings:
        """``s`` rendering media with volpath (the other integrators refuse them) when a fog or an
        interior medium is there and nobody chose the integrator; back to the default without them."""
        media = s.fog or bool(getattr(self._scene, "interiors", None))
        if self._integrator_given:
            return s
        if media:
            return replace(s, integrator="volpath")
        return replace(s, integrator=ViewSettings.integrator) if s.integrator == "volpath" else s

    def _lit(self, scene, s: ViewSettings):
        """``scene`` with the page's lights beside its own lights and the page's fog; in the studio,
        its key light there or not as the command line's rule says (conventions.studio_look): the
        page's sun or lamp turned on replaces it, turned off brings it back."""
        from warp_spt.scene.studio import with_key

        if self._key is not None:
            scene = with_key(scene, self._key if self._key_on(s) else None)
        return replace(scene, lights=[*self._own_lights, *lighting.lights(s, self._offset)],
                       fog=lighting.fog(s, self._own_fog))

    def _make_sky(self, s: ViewSettings):
        return make_sky(s, self._environment, keyed=self._key is None or self._key_on(s))

    def _key_on(self, s: ViewSettings) -> bool:
        """Whether the studio's key light shows with the page's lights ``s``: the command line's rule
        (conventions.studio_look), under which any light of the user's (the page's, the scene's own
        sun, point or spot lights, an environment map) replaces it."""
        from warp_spt.scene.conventions import STUDIO_KEY, studio_look
        from warp_spt.scene.lights import punctual_lights

        lights = [*self._own_lights, *lighting.lights(s, self._offset)]
        return studio_look(True, emitting=False, user_lights=bool(punctual_lights(lights)), seed_dialect=False,
                           sky_given=True, env_given=s.sky == "environment") == STUDIO_KEY

    def _on_param(self, msg, reply) -> None:
        name = str(msg["name"])
        with self._cond:
            if self._params is None or name not in self._params:
                raise KeyError(f"no parameter {name!r}")
            self._pending[name] = msg["value"]      # applied on the render thread, between renders
            self._changed()

    def _on_command(self, msg, reply) -> None:
        text = self.command_line(msg.get("width"), msg.get("height"), int(msg.get("spp", 64)),
                                 str(msg.get("out") or "view.png"))
        notes = []
        if self._edits:
            notes.append("edited material values are not on the command line: write them into the MTL file")
        notes += lighting.command_flags(self._settings, self._own_fog)[1]
        out = str(msg.get("out") or "view.png")
        if self._settings.exposure and not out.lower().endswith((".png", ".jpg", ".jpeg")):
            notes.append("the exposure is not on the command line: a linear image holds the scene's radiance")
        reply({"type": "command", "text": text, "notes": notes}, [])

    def _on_save(self, msg, reply) -> None:
        fmt = str(msg.get("format", "png")).lower()
        if fmt not in save_formats():
            raise ValueError(f"cannot save as {fmt!r}; choose from {', '.join(save_formats())}")
        res = self.result()
        if res is None:
            raise ValueError("nothing is rendered yet: wait for the first refined pass")
        name = f"view_{res.spp_total}spp.{fmt}"
        with tempfile.TemporaryDirectory() as tmp:
            self.save(Path(tmp) / name)
            data = (Path(tmp) / name).read_bytes()
        reply({"type": "file", "name": name, "mime": _MIME.get(fmt, "application/octet-stream")}, [data])

    def _on_reload(self, msg, reply) -> None:
        if not self._can_reload:
            raise ValueError("this view was given a scene object, not files: nothing to reload")
        with self._cond:
            self._reload = True
            self._error = None
            self._cond.notify_all()
        self._broadcast(self.state(), [])

    # ------------------------------------------------------------------ camera helpers
    def _navigate(self, op: Callable) -> None:
        """Apply a navigation step; one that would give an invalid camera is ignored."""
        with self._cond:
            if self._rig is None:
                return
            rig = op(self._rig)
            rig_camera(rig)          # raises ValueError for a camera the renderer refuses
            self._rig = rig
            self._changed()

    def _set_rig(self, rig) -> None:
        self._navigate(lambda _: rig)

    def _framed(self, up: str):
        from warp_spt import Camera

        s = self._settings
        # called on a camera, frame() takes it as the template: the current fov is kept
        template = Camera if self._rig is None else rig_camera(self._rig)
        cam = template.frame(self._subject, up=up, aspect=s.width / s.height)
        return navigation.rig_from_view(cam.position, cam.direction, cam.up, cam.focus, fov=cam.fov,
                                        aperture=cam.aperture)

    def _first_view(self, scene):
        """The command line's first view of a loaded scene; on a reload, of the current camera."""
        from warp_spt.rendering.first_view import first_view

        s = self._settings
        demo = self._can_reload and not self.objs          # the file loader's built-in demo
        up = self._up if self._up_given or self._rig is not None else None
        if self._rig is not None:                           # a reload keeps the view, in world coordinates
            cam = rig_camera(self._rig)
            cam = replace(cam, position=tuple(float(p + o) for p, o in zip(cam.position, self._offset)))
            return first_view(scene, cam, width=s.width, height=s.height, up=up, demo=demo, fixed=True,
                              sky=self._make_sky(s) if self._sky_given else None,
                              studio=self._studio if not demo else False, user_lights=self._page_lit(s))
        cam = self._given_camera
        if cam is None and demo:
            from warp_spt import Camera
            cam = Camera()                  # the built-in demo keeps the seed's camera, as the CLI does
        # a light from the start lights the studio instead of its key, as --sun does for warp-spt
        return first_view(scene, cam, width=s.width, height=s.height, up=up, demo=demo, studio=self._studio_given,
                          sky=self._make_sky(s) if self._sky_given else None, user_lights=self._page_lit(s))

    @staticmethod
    def _page_lit(s: ViewSettings) -> bool:
        return bool(s.sun or s.lamp != "off")

    def _initial_rig(self, cam):
        """The first view's camera with its pivot at the scene centre's depth."""
        centre = self._subject.bounds.mean(axis=0)
        d = np.asarray(cam.direction, dtype=np.float64) / np.linalg.norm(cam.direction)
        depth = float(np.dot(centre - np.asarray(cam.position), d))
        return navigation.rig_from_view(cam.position, d, cam.up, depth if depth > 0 else cam.focus,
                                        fov=cam.fov, aperture=cam.aperture, focus=cam.focus)

    def _scene_size(self) -> float:
        scene = self._subject
        return 1.0 if scene is None else float(np.linalg.norm(np.ptp(scene.bounds, axis=0))) or 1.0

    def _changed(self) -> None:
        """Call with the lock held: a render-affecting change."""
        self._version += 1
        self._last_change = time.monotonic()
        self._cond.notify_all()

    def _param_list(self) -> list[dict]:
        """Colours and numbers of materials and procedural textures, for the page's editors."""
        p = self._params
        if p is None:
            return []
        out = []
        for name in p.names():
            info = p.info(name)
            if info.kind in ("material", "proc") and info.shape in ((3,), ()):
                value = p[name]
                out.append({"name": name, "group": name.split(".")[0], "field": name.split(".", 1)[1],
                            "kind": "color" if info.shape == (3,) else "number",
                            "value": [float(v) for v in value] if info.shape else float(value)})
        return out

    # ------------------------------------------------------------------ the render thread
    def _run(self) -> None:
        while True:
            job = self._next_job()
            if job is None:
                return
            try:
                job()
            except Exception as err:      # shown on the page; the thread waits for the next change
                if os.environ.get("WARP_SPT_TRACEBACK"):
                    traceback.print_exc()
                self._fail(f"{type(err).__name__}: {err}" if not _is_scene_error(err) else str(err))

    def _next_job(self) -> Callable | None:
        """What to do next, waiting until there is something; None when closed."""
        with self._cond:
            while not self._closed:
                if self._reload:
                    self._reload = False
                    return self._load
                if self._scene is None or self._rig is None:
                    self._cond.wait()
                    continue
                if self._pending:
                    return self._apply_params
                if self._relight:
                    self._relight = False
                    return self._apply_lighting
                job, wait = self._choose()
                if job is not None:
                    return job
                self._cond.wait(wait)
            return None

    def _choose(self) -> tuple[Callable | None, float | None]:
        """(job, None) or (None, seconds to wait; None: until notified). Lock held."""
        if self._failed_version == self._version:
            return None, None
        quiet = time.monotonic() - self._last_change
        moving = quiet < SETTLE_SECONDS or (self._interacting and quiet < DRAG_TIMEOUT)
        if moving:
            if self._preview_version != self._version:
                return self._preview, None
            return None, (SETTLE_SECONDS - quiet if quiet < SETTLE_SECONDS else DRAG_TIMEOUT - quiet)
        s = self._settings
        if self._acc is None or self._acc.version != self._version or (self._acc.height, self._acc.width) != (s.height, s.width):
            self._acc = Accumulator(self._version, s.height, s.width)
        if self._acc.spp < s.max_spp:
            return self._refine, None
        return None, None

    def _snapshot(self):
        with self._cond:
            return self._version, self._settings, rig_camera(self._rig), self._params.scene

    def _preview(self) -> None:
        import warp_spt

        version, s, camera, dev = self._snapshot()
        w, h, spp = preview_plan(s, PREVIEW_SECONDS * self._preview_rate)
        rs = warp_spt.RenderSettings(width=w, height=h, spp=spp, max_depth=s.max_depth,
                                     sky=self._make_sky(s),
                                     integrator=s.integrator, sampler=s.sampler, tile_pixels=_tile(w * h))
        start = time.perf_counter()
        res = self._timed(warp_spt.render_scene, dev, camera, rs)
        seconds = time.perf_counter() - start
        self._measure(w * h * spp, seconds)
        rate = w * h * spp / max(seconds, 1e-9)
        self._preview_rate = rate if not self._preview_rate else 0.5 * self._preview_rate + 0.5 * rate
        with self._cond:
            self._preview_version = version
            self._preview_times = [t for t in self._preview_times[-40:] if time.monotonic() - t < 2.0]
            self._preview_times.append(time.monotonic())
        self._show(res.image, None, {"mode": "preview", "spp": spp, "error": None,
                                     "rate": rate, "fps": self.preview_fps(),
                                     "size": [w, h]}, version)

    def _refine(self) -> None:
        """One pass: ``spp`` more samples of one batch in every pixel, rendered in bands of rows."""
        import warp_spt

        version, s, camera, dev = self._snapshot()
        acc = self._acc
        b, n = acc.next_batch, s.width * s.height
        spp = acc.pass_spp(min(MAX_PASS_SPP, int(PASS_SECONDS * self._rate / n)), s.max_spp)
        band = max(1, int(BAND_SECONDS * max(self._rate, 1.0) / (s.width * spp))) if self._rate > 0 else 8
        rs = warp_spt.RenderSettings(width=s.width, height=s.height, spp=spp, max_depth=s.max_depth,
                                     sky=self._make_sky(s), integrator=s.integrator, sampler=s.sampler,
                                     seed=acc.seeds[b], sample_offset=int(acc.counts[b]),
                                     tile_pixels=_tile(min(band, s.height) * s.width))
        sums = np.empty((s.height, s.width, 3))
        start = time.perf_counter()
        for r0 in range(0, s.height, band):
            if self._version != version or self._closed:
                return                      # abandoned: the view changed
            r1 = min(s.height, r0 + band)
            t0 = time.perf_counter()
            res = self._timed(warp_spt.render_scene, dev, camera, rs, rows=(r0, r1))
            self._measure((r1 - r0) * s.width * spp, time.perf_counter() - t0)
            sums[r0:r1] = res.film.sum
        with self._cond:
            if self._version != version or acc is not self._acc:
                return
            acc.add(b, sums, spp, time.perf_counter() - start)
            mean, se = acc.statistics()
            # the picture is recorded before waiters wake: one that returns from wait_for and redraws
            # (a display setting) draws this pass, not the one before it (under load it drew the preview)
            cleared = self._record(mean, se, {"mode": "refine", "spp": acc.spp,
                                              "error": _finite(warp_spt.relative_error(se, mean)),
                                              "rate": acc.spp * n / max(acc.seconds, 1e-9), "passes": acc.passes,
                                              "size": [s.width, s.height]}, version)
            self._cond.notify_all()
        if cleared is not None:
            self._publish(cleared)

    def _timed(self, call: Callable, *args, **kw):
        """Run a render call; if it is slow (a kernel compiling), tell the page while it runs."""
        timer = threading.Timer(SLOW_CALL_SECONDS, lambda: self._broadcast(
            {"type": "status", "text": "compiling the render kernel for these settings (first time only)..."}, []))
        timer.daemon = True
        timer.start()
        try:
            return call(*args, **kw)
        finally:
            timer.cancel()

    def _measure(self, samples: int, seconds: float) -> None:
        rate = samples / max(seconds, 1e-9)
        self._rate = rate if self._rate <= 0 else 0.7 * self._rate + 0.3 * rate

    def _apply_params(self) -> None:
        """Material edits change the uploaded scene: done here, never while a render runs."""
        with self._cond:
            pending, self._pending = self._pending, {}
        for name, value in pending.items():
            try:
                self._params[name] = value
                self._edits.add(name)
            except (ValueError, TypeError) as err:
                self._broadcast({"type": "notice", "level": "error", "text": str(err)}, [])
        with self._cond:
            self._changed()
        self._broadcast(self.state(), [])

    def _apply_lighting(self) -> None:
        """The page's lights or fog changed: upload the scene again with them (its meshes are
        reused; material edits are kept: they live in the uploaded scene's host copy)."""
        import warp_spt
        from warp_spt.upload.device_scene import DeviceScene

        with self._cond:
            s, params = self._settings, self._params
        dev = DeviceScene(self._lit(params.scene.scene, s), meshes=self._meshes)
        new = warp_spt.parameters(dev)
        with self._cond:
            if self._params is params:          # not replaced by a reload meanwhile
                self._params = new
                self._changed()
        self._broadcast(self.state(), [])

    def _load(self) -> None:
        """(Re)load the scene from the loader; on success keep the view (or make the first one)."""
        import warp_spt

        self._broadcast(self.state(), [])
        try:
            scene = self._loader()
        except Exception as err:
            self._fail(str(err) if _is_scene_error(err) else f"{type(err).__name__}: {err}", scene_lost=True)
            return
        from warp_spt.scene.camera import AXES
        from warp_spt.scene.studio import key_sphere
        from warp_spt.upload.device_scene import DeviceScene

        first = self._rig is None
        fv = self._first_view(scene)
        s = before = self._settings
        if first:       # the page's lights placed for this scene, its own fog shown on the page
            size = float(np.linalg.norm(np.ptp(fv.subject.bounds, axis=0))) or 1.0
            centre = fv.subject.bounds.mean(axis=0) + fv.offset
            s = lighting.placed(s, self._given, AXES[fv.up.axis], fv.camera, centre, size)
            s = lighting.from_scene_fog(s, getattr(fv.scene, "fog", None), self._given)
        placed = {k: getattr(s, k) for k in (*lighting.LIGHT_KEYS, *lighting.FOG_KEYS)
                  if getattr(s, k) != getattr(before, k)}
        self._own_lights, self._own_fog = list(fv.scene.lights), getattr(fv.scene, "fog", None)
        self._key = key_sphere(fv.subject.bounds, fv.up.axis, fv.camera, s.width / s.height) if fv.studio else None
        self._meshes = {}
        self._offset = fv.offset
        dev = DeviceScene(self._lit(fv.scene, s), meshes=self._meshes)
        params = warp_spt.parameters(dev)          # uploads the scene once; edits go through it
        with self._cond:
            self._scene, self._params, self._error, self._edits = fv.scene, params, None, set()
            self._pending.clear()
            self._studio, self._subject = fv.studio, fv.subject
            if first:
                self._settings = replace(self._settings, **placed)     # a page's set meanwhile stays
                self._up = fv.up.axis
                if fv.studio and not self._sky_given:
                    self._settings = replace(self._settings, sky="studio")
                if "tonemap" not in self._given:        # the command line's curve for this scene
                    self._settings = replace(self._settings, tonemap=fv.tonemap)
                self._settings = self._media_integrator(self._settings)   # a fog or an interior medium: volpath
                self._rig = self._initial_rig(fv.camera)
                self._home = (self._rig, self._up)
            self._changed()
        self._broadcast(self.state(), [])
        if first and fv.notes:      # what the first view assumed, in the command line's words
            self._broadcast({"type": "notice", "level": "warning" if fv.warnings else "info",
                             "text": "\n".join(fv.notes)}, [])

    def _fail(self, text: str, scene_lost: bool = False) -> None:
        with self._cond:
            self._error = text
            if scene_lost:
                self._scene = self._params = None
            self._failed_version = self._version      # no retry until something changes
        self._broadcast(self.state(), [])

    # ------------------------------------------------------------------ publishing
    def _show(self, image: np.ndarray, std_error, meta: dict, version: int) -> None:
        with self._cond:
            cleared = self._record(image, std_error, meta, version)
        if cleared is not None:
            self._publish(cleared)

    def _record(self, image: np.ndarray, std_error, meta: dict, version: int) -> bool | None:
        """Make this the picture shown (the caller holds the lock); whether an error was cleared, or
        None where a refine pass of an abandoned view is not shown."""
        if version != self._version and meta["mode"] == "refine":
            return None
        meta = {**meta, "camera": camera_info(self._rig), "view": [self._settings.width, self._settings.height],
                "version": version}
        self._shown = _Shown(image, std_error, meta)
        cleared, self._error = self._error is not None, None     # a render worked: the error is past
        return cleared

    def _publish(self, cleared: bool) -> None:
        """Send the recorded picture (and the state, where an error was cleared)."""
        if cleared:
            self._broadcast(self.state(), [])
        self._redraw()

    def _redraw(self) -> None:
        """Encode the last picture with the current display settings and send it."""
        shown, s = self._shown, self._settings
        if shown is None:
            return
        if s.error_map and shown.std_error is not None:
            rgb = display.error_colours(display.relative_map(shown.std_error, shown.image))
        else:
            rgb = display.tonemapped(shown.image, s.exposure, s.tonemap)
            if shown.meta["mode"] == "preview":
                rgb = display.despeckled(rgb)
        msg = {"type": "frame", **shown.meta, "error_map": bool(s.error_map and shown.std_error is not None),
               "error_range": list(display.ERROR_MAP_RANGE)}
        frame = (msg, [display.encode(rgb)])
        self._frame = frame
        self._broadcast(*frame)

    def _broadcast(self, msg: dict, buffers: list) -> None:
        with self._cond:
            listeners = list(self._listeners)
        for listener in listeners:
            listener(msg, buffers)


def open_session(scene=None, camera=None, *, objs: Sequence[str] = (), mtls: Sequence[str] = (),
                 smooth_angle: float | str = "auto", **kw):
    """A :class:`Session` of ``scene``, or of the files (the built-in demo when ``objs`` is empty),
    loaded on the render thread so that a bad file is reported on the page; ``smooth_angle`` as
    ``warp-spt --smooth-angle`` ("auto": its default)."""
    if scene is not None:
        return Session(scene, camera, objs=objs, mtls=mtls, **kw)
    return Session(camera=camera, loader=file_loader(objs, mtls, smooth_angle), objs=objs, mtls=mtls,
                   smooth_angle=smooth_angle, **kw)


def file_loader(objs: Sequence[str], mtls: Sequence[str], smooth_angle: float | str = "auto"):
    """A function loading the files as the command line does (``default_material="auto"``, smooth
    normals by angle)."""
    def load():
        import warp_spt
        from warp_spt.demo import demo_files

        files = (list(objs), list(mtls)) if objs else demo_files()
        return warp_spt.load_scene(*files, default_material="auto", smooth_angle=smooth_angle)
    return load


# ---------------------------------------------------------------------- helpers
_MIME = {"png": "image/png", "exr": "image/x-exr", "npy": "application/octet-stream", "pfm": "image/x-pfm"}


def save_formats() -> list[str]:
    """What "save image" offers: PNG, linear NPY and PFM, and EXR when OpenEXR is installed."""
    import importlib.util

    return ["png"] + (["exr"] if importlib.util.find_spec("OpenEXR") else []) + ["npy", "pfm"]


def rig_camera(rig: navigation.Rig):
    """The :class:`warp_spt.Camera` of a rig (validated: ValueError for one the renderer refuses)."""
    from warp_spt import Camera

    return Camera.look_at(rig.position, rig.target, up=rig.up, fov=rig.fov, aperture=rig.aperture,
                          focus=rig.focus_distance)


def camera_info(rig: navigation.Rig) -> dict:
    cam = rig_camera(rig)
    return {"position": list(cam.position), "direction": list(cam.direction), "target": rig.target.tolist(),
            "fov": cam.fov, "focus": cam.focus, "aperture": cam.aperture}


def _result(acc: Accumulator, s: ViewSettings, sky):
    """A :class:`warp_spt.RenderResult` of an accumulation (lock held)."""
    import warp_spt

    mean, se = acc.statistics()
    h, w = mean.shape[:2]
    stats = warp_spt.RenderStats(integrator=s.integrator, sampler=s.sampler, seconds=acc.seconds,
                                 passes=acc.passes, pixel_samples=acc.spp * h * w, render_seconds=acc.seconds,
                                 stopped_by="callback")
    settings = warp_spt.RenderSettings(width=w, height=h, spp=acc.spp, max_depth=s.max_depth, sky=sky,
                                       integrator=s.integrator, sampler=s.sampler)
    counts = np.broadcast_to(acc.counts[:, None, None], (len(acc.counts), h, w)).copy()
    return warp_spt.RenderResult(warp_spt.Film(acc.sums.sum(axis=0), acc.spp), stats, settings, mean, se,
                                 np.full((h, w), acc.spp, dtype=np.int64), warp_spt.relative_error(se, mean),
                                 acc.sums.copy(), counts)


def _tile(pixels: int) -> int:
    """Tile size that gives every core two tiles of a small render (the default 4096 would leave
    a 128x96 preview on three tiles)."""
    threads = os.cpu_count() or 1
    return max(256, min(4096, math.ceil(pixels / (2 * threads))))


def _axis_name(up) -> str:
    v = tuple(float(x) for x in up)
    names = {(1.0, 0.0, 0.0): "x", (0.0, 1.0, 0.0): "y", (0.0, 0.0, 1.0): "z",
             (-1.0, 0.0, 0.0): "-x", (0.0, -1.0, 0.0): "-y", (0.0, 0.0, -1.0): "-z"}
    if v not in names:
        raise ValueError(f"the viewer needs an up axis along x, y or z, got {up!r}")
    return names[v]


def _non_negative(value, what: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and v >= 0):
        raise ValueError(f"{what} must be a number >= 0, got {value!r}")
    return v


def _finite(x: float) -> float | None:
    return float(x) if math.isfinite(x) else None


def _is_scene_error(err: BaseException) -> bool:
    import warp_spt

    return isinstance(err, warp_spt.SceneError)


def _progressive_integrators() -> list[str]:
    """The integrators the viewer's progressive passes can render (not ``guided``, which trains
    over passes of its own)."""
    import warp_spt

    return [n for n, r in warp_spt.INTEGRATORS.items() if r.render_passes is None]
