"""The one render set-up: from (scene, camera, settings) to everything a kernel launch needs.

Every renderer (tiles, the progressive driver, both gradient paths, the cluster's workers, the
albedo/normal pass) calls :func:`bind`, which checks the settings and the camera, recentres a host
:class:`Scene` and uploads it, picks the sky, the feature set and the kernel, and packs the camera,
the light table and the textures: a :class:`Bound`. Launch sites then ask the Bound for the
kernel's inputs (:meth:`Bound.scene_args`, :meth:`Bound.params`) instead of spelling them out.

Kernels come in *kinds* (``KERNEL_KINDS``: a registry of :class:`KernelKind` records): "fast" (the
integrator's forward kernel, here), "aov" (the denoiser's albedo/normal pass,
``warp_spt.rendering.aux_buffers``), "replay" and "tape" (gradients, ``warp_spt.diff``, which sit
above this layer and register their kinds when imported).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any, Callable

import warp as wp

from warp_spt.device.camera_rays import CameraParams, camera_params
from warp_spt.upload.device_scene import DeviceScene, Features, Textures
from warp_spt.emitters import Lights, declare_sky, light_table
from warp_spt.device.media_table import interface_media
from warp_spt.integrators import Integrator, RenderParams, get_integrator, get_kernel
from warp_spt.rendering.settings import RenderSettings, check_args, check_rows
from warp_spt.scene.camera import Camera
from warp_spt.scene.model import Scene
from warp_spt.scene.recentre import recentre
from warp_spt.scene.sky import Sky

SEED_MASK = 0xFFFFFFFF      # kernels take the seed as a uint32: its low 32 bits


@dataclass(frozen=True)
class KernelKind:
    """A kind of kernel the set-up can pick: ``build(bound) -> kernel`` (compiled and loaded on
    ``bound.dev.device``; from the bound's integrator, sampler, features and settings),
    ``features(scene's features, settings, sky) -> features`` (the feature set it is compiled for),
    and ``lights``: whether it reads the light table (else ``Bound.lights`` is None)."""

    name: str
    build: Callable[["Bound"], wp.Kernel]
    features: Callable[[Features, RenderSettings, Sky], Features]
    lights: bool = True


def render_features(scene_features: Features, rs: RenderSettings, sky: Sky) -> Features:
    """The features a path-tracing kernel is compiled for: the scene's own with what the light kinds
    declare the sky needs (whether it emits, whether it is an environment map), under the settings'
    override where one is given (which must still cover them: ``Features.covering``)."""
    own = scene_features.with_lights(declare_sky(sky))
    return rs.features.covering(own) if rs.features else own


KERNEL_KINDS: dict[str, KernelKind] = {}


def register_kind(kind: KernelKind) -> KernelKind:
    """Add a kernel kind (one line per kind, in the module that builds it); returns it."""
    KERNEL_KINDS[kind.name] = kind
    return kind


register_kind(KernelKind(
    "fast", lambda b: get_kernel(b.features, b.dev.device, b.integrator.name, b.settings.sampler),
    render_features))


@dataclass
class Bound:
    """Everything a launch needs: the device scene, the camera (recentred with the scene), the
    settings, the sky, the features, the integrator's record, the kernel, the packed camera, the
    light table (None for kinds without lights), the textures, the integrator's own data
    (``Integrator.prepare``; None without it) and its parameters' values (``Integrator.options``
    of the settings' ``integrator_options``: every parameter, checked, defaults filled in)."""

    dev: DeviceScene
    camera: Camera
    settings: RenderSettings
    sky: Sky
    features: Features
    integrator: Integrator
    kind: KernelKind
    kernel: wp.Kernel | None = None
    cam: CameraParams | None = None
    lights: Lights | None = None
    tex: Textures | None = None
    data: Any = None
    options: dict = field(default_factory=dict)

    @property
    def width(self) -> int:
        return self.settings.width

    @property
    def height(self) -> int:
        return self.settings.height

    @property
    def pixels(self) -> int:
        return self.settings.width * self.settings.height

    def params(self, pixel_start: int = 0, first: int = 0, count: int | None = None,
               seed: int | None = None) -> RenderParams:
        """The kernel's RenderParams for ``count`` samples (default: the settings' spp) of the pixels
        from ``pixel_start``, from sample ``settings.sample_offset + first``; ``seed`` overrides the
        settings' (the progressive batches' own seeds)."""
        rs = self.settings
        p = RenderParams()
        p.width, p.pixel_start = rs.width, pixel_start
        p.sample_start, p.sample_count = rs.sample_offset + first, rs.spp if count is None else count
        p.max_depth, p.roulette_depth = rs.max_depth, rs.roulette_depth
        p.seed = wp.uint32((rs.seed if seed is None else seed) & SEED_MASK)
        return p

    def scene_args(self, rp: RenderParams, *, materials=None, textures=None, lights=None, geometry=None) -> list:
        """The inputs every path kernel (fast, replay, tape) starts with, in their order: geometry,
        materials, textures, lights, camera, render parameters. ``materials``/``textures``/``lights``/
        ``geometry`` replace the scene's (the gradients' per-tile aliases carrying ``.grad``)."""
        return [self.dev.geometry if geometry is None else geometry, self.dev.materials if materials is None else materials,
                self.tex if textures is None else textures, self.lights if lights is None else lights,
                self.cam, rp]


def check_inputs(scene, camera) -> None:
    """TypeError, naming what was expected, for a scene or camera of the wrong type (the API's
    callers; an AttributeError from deep inside said nothing)."""
    if not isinstance(scene, (Scene, DeviceScene)):
        raise TypeError(f"scene must be a warp_spt.Scene (from warp_spt.load_scene) or a DeviceScene, "
                        f"got {type(scene).__name__}")
    check_camera_type(camera)


def check_camera_type(camera) -> None:
    """TypeError unless ``camera`` is a Camera or None."""
    if camera is not None and not isinstance(camera, Camera):
        raise TypeError(f"camera must be a warp_spt.Camera or None, got {type(camera).__name__}")


def check(rs: RenderSettings, camera: Camera | None, rows: tuple[int, int] | None = None) -> None:
    """Raise ValueError for settings, a camera or rows a kernel must not see (before any upload)."""
    if not isinstance(rs, RenderSettings):
        raise TypeError(f"settings must be a warp_spt.RenderSettings, got {type(rs).__name__}")
    check_camera_type(camera)
    check_args(rs)
    (camera or Camera()).validate(rs.width, rs.height)
    check_rows(rows, rs.height)


def upload(scene: Scene | DeviceScene, camera: Camera | None, device: str) -> tuple[DeviceScene, Camera]:
    """A DeviceScene and its camera: a host Scene far from the origin is shifted to it in float64
    first (scene and camera together); a DeviceScene is used as it is."""
    if not isinstance(scene, DeviceScene):
        scene, camera, _ = recentre(scene, camera)
        scene = DeviceScene(scene, device=device)
    return scene, camera or Camera()


def kernel_kind(mode: str) -> KernelKind:
    """The registered kernel kind ``mode`` (ValueError naming the registered ones otherwise; the
    gradient kinds register when ``warp_spt.diff`` is imported)."""
    if mode not in KERNEL_KINDS:
        raise ValueError(f"unknown kernel kind {mode!r}; registered: {', '.join(sorted(KERNEL_KINDS))}")
    return KERNEL_KINDS[mode]


def scene_sky(dev: DeviceScene, rs: RenderSettings) -> Sky:
    """The sky a render sees: the settings' (an override), else the scene's own, else the seed's
    BlackSky (TypeError for a scene sky that is not a :class:`Sky`)."""
    own = getattr(dev.scene, "sky", None)
    if own is not None and not isinstance(own, Sky):
        raise TypeError(f"scene.sky must be a warp_spt.Sky (e.g. warp_spt.load_environment('sky.hdr')) or None, "
                        f"got {type(own).__name__}")
    return rs.sky or own or Sky.black()


def bind(scene: Scene | DeviceScene, camera: Camera | None = None, settings: RenderSettings | None = None, *,
         mode: str = "fast", rows: tuple[int, int] | None = None) -> Bound:
    """Check, upload and pick the kernel of ``mode`` (a ``KERNEL_KINDS`` name): the one set-up of
    every renderer. The kernel is loaded on the calling thread, before any worker launches it."""
    rs = settings or RenderSettings()
    kind = kernel_kind(mode)
    check(rs, camera, rows)                 # settings first: ValueErrors name them before the scene's type
    check_inputs(scene, camera)
    dev, camera = upload(scene, camera, rs.device)
    if wp.get_device(dev.device).is_cuda:
        # a CUDA launch runs all its threads at once: each pass is one launch over the whole image,
        # from one host thread (CPU tiles and worker threads would only serialise on the stream)
        rs = replace(rs, tile_pixels=max(rs.tile_pixels, rs.width * rs.height), threads=1)
    sky = scene_sky(dev, rs)
    b = Bound(dev, camera, rs, sky, kind.features(dev.features, rs, sky), get_integrator(rs.integrator), kind)
    b.options = b.integrator.options(rs.integrator_options)
    if b.features.media and mode == "fast" and not b.integrator.media:
        raise ValueError(f"the scene has participating media (a fog or an interior medium): integrator "
                         f"{b.integrator.name!r} ignores them; render it with integrator 'volpath'")
    if b.features.media and mode in ("tape", "replay"):
        check_media_gradients(dev, b.integrator, mode)
    b.kernel = kind.build(b)
    b.cam = camera_params(camera, rs.width, rs.height)
    b.lights = light_table(dev, sky, camera.up) if kind.lights else None
    b.tex = dev.textures(rs.texture_filter)
    if b.integrator.prepare is not None:
        b.data = b.integrator.prepare(b)
    return b


def check_media_gradients(dev: DeviceScene, integrator: Integrator, mode: str) -> None:
    """ValueError for a gradient render of a scene with media that would be wrong: through the tape
    (``volpath``'s trackers have no unrolled form), through an integrator that ignores media, or with
    two media behind pass-through boundaries (a shadow ray's derivatives follow two media, the one it
    starts in and one across such boundaries; docs/volumes.md, Gradients)."""
    where = "the scene has participating media (a fog or an interior medium)"
    if not integrator.media:
        raise ValueError(f"{where}: integrator {integrator.name!r} ignores them; use integrator 'volpath'")
    if mode != "replay":
        raise ValueError(f"{where}: their gradients are path replay's (mode='prb' or 'auto'), not the tape's")
    if len(interface_media(dev.scene)) > 1:
        raise ValueError(f"{where}: gradients with more than one medium behind pass-through (index_matched) "
                         f"boundaries are not supported (docs/volumes.md, Gradients)")


def device_kernel(dev: DeviceScene, rs: RenderSettings, mode: str = "fast") -> wp.Kernel:
    """Only the kernel :func:`bind` would pick for ``dev`` and ``rs`` (compiled and loaded): what a
    cluster worker prepares under its lock when it uploads a scene."""
    kind = kernel_kind(mode)
    sky = scene_sky(dev, rs)
    return kind.build(Bound(dev, Camera(), rs, sky, kind.features(dev.features, rs, sky),
                            get_integrator(rs.integrator), kind))

