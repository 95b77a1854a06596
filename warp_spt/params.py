"""Scene parameters addressed by name, as Mitsuba's ``traverse``: read, set and differentiate them.

``parameters(scene, camera, sky)`` lists what a user can edit and what gradients reach:

* ``"<material>.diffuse"``, ``.reflect``, ``.refract``, ``.emission``: RGB colours (3,);
* ``"<material>.roughness"`` (probability of the diffuse lobe, in [0, 1]) and ``.fuzz`` (>= 0), ();
* ``"<material>.<slot>_map"`` for each image texture, named after the first material slot that uses
  it (slots diffuse, reflect, refract, emission): its texels (h, w, 3), row 0 the image's top row;
* ``"sky.color"`` (3,) for a constant sky;
* ``"camera.position"`` and ``"camera.direction"`` (3,): settable, not differentiated (see
  ``warp_spt.gradients``); :meth:`SceneParameters.differentiable` lists the others.

Values are validated before they reach a kernel (finite; colours and texels >= 0; roughness in
[0, 1]; fuzz >= 0; a non-zero direction). Setting a material value updates both the host Scene and
the device arrays, and recomputes the scene's Features (a roughness leaving 1 needs the mirror lobe
compiled in) and its light table (an emission change re-weights light sampling).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .camera import Camera
from .device_scene import DeviceScene, _features
from .scene import SLOT_DIFFUSE, SLOT_EMISSION, SLOT_REFLECT, SLOT_REFRACT, Scene
from .sky import SKY_CONSTANT, Sky
from .textures import tile_view

COLOR_FIELDS = ("diffuse", "reflect", "refract", "emission")
SCALAR_FIELDS = ("roughness", "fuzz")
MATERIAL_FIELDS = COLOR_FIELDS + SCALAR_FIELDS
_SLOT_NAMES = {SLOT_DIFFUSE: "diffuse", SLOT_REFLECT: "reflect", SLOT_REFRACT: "refract",
               SLOT_EMISSION: "emission"}


@dataclass(frozen=True)
class ParamInfo:
    """Where a named parameter lives: ``kind`` is "material", "texture", "sky" or "camera";
    ``field`` the material field / camera attribute; ``index`` the material row or texture index."""

    name: str
    kind: str
    field: str
    index: int
    shape: tuple[int, ...]


class SceneParameters:
    """The editable, differentiable parameters of one DeviceScene seen by one camera under one sky.

    ``params[name]`` returns a numpy copy; ``params[name] = value`` validates and applies it.
    ``params.camera`` and ``params.sky`` are the current camera and sky (frozen dataclasses, replaced
    when set).
    """

    def __init__(self, scene: DeviceScene | Scene, camera: Camera | None = None, sky: Sky | None = None):
        self.scene = scene if isinstance(scene, DeviceScene) else DeviceScene(scene)
        self.camera = camera or Camera()
        self.sky = sky or Sky.black()
        self._info = _describe(self.scene.scene, self.sky)

    # --- the mapping -------------------------------------------------------------------------
    def names(self) -> list[str]:
        return list(self._info)

    def __iter__(self):
        return iter(self._info)

    def __len__(self) -> int:
        return len(self._info)

    def __contains__(self, name: object) -> bool:
        return name in self._info

    def differentiable(self) -> list[str]:
        """The names :func:`warp_spt.gradients.render_gradients` differentiates."""
        return [n for n, p in self._info.items() if p.kind != "camera"]

    def info(self, name: str) -> ParamInfo:
        if name not in self._info:
            raise KeyError(f"no parameter {name!r}; parameters are: {', '.join(self._info)}")
        return self._info[name]

    def __getitem__(self, name: str) -> np.ndarray:
        p = self.info(name)
        s = self.scene.scene
        if p.kind == "material":
            return np.array(getattr(s.materials, p.field)[p.index], dtype=np.float32)
        if p.kind == "texture":
            return np.array(s.textures[p.index], dtype=np.float32)
        if p.kind == "sky":
            return np.array(self.sky.color, dtype=np.float32)
        return np.array(getattr(self.camera, p.field), dtype=np.float32)

    def __setitem__(self, name: str, value) -> None:
        p = self.info(name)
        v = np.asarray(value, dtype=np.float64)
        if v.shape != p.shape:
            raise ValueError(f"{name}: expected shape {p.shape}, got {v.shape}")
        _check_value(p, v)
        if p.kind == "material":
            self._set_material(p, v)
        elif p.kind == "texture":
            self._set_texture(p, v)
        elif p.kind == "sky":
            self.sky = Sky.constant(*v)
        else:
            self.camera = replace(self.camera, **{p.field: tuple(float(x) for x in v)})

    def update(self, values: dict) -> None:
        for k, v in values.items():
            self[k] = v

    # --- writing through to host and device ------------------------------------------------------
    def _set_material(self, p: ParamInfo, v: np.ndarray) -> None:
        dev = self.scene
        getattr(dev.scene.materials, p.field)[p.index] = v
        arr = getattr(dev.materials, p.field)
        host = arr.numpy()
        host[p.index] = v
        arr.assign(host)
        self._refresh()

    def _set_texture(self, p: ParamInfo, v: np.ndarray) -> None:
        dev = self.scene
        dev.scene.textures[p.index] = v.astype(np.float32)
        texels, tiles = dev._atlas
        host = texels.numpy()
        tile_view(host, tiles.numpy()[p.index])[...] = v
        texels.assign(host)
        self._refresh()

    def _refresh(self) -> None:
        """Features and light table follow the new values."""
        dev = self.scene
        dev.features = _features(dev.scene)
        dev._lights.clear()


def parameters(scene: DeviceScene | Scene, camera: Camera | None = None, sky: Sky | None = None) -> SceneParameters:
    """The named parameters of ``scene`` (uploaded if it is a host Scene); see the module docstring."""
    return SceneParameters(scene, camera, sky)


def _describe(scene: Scene, sky: Sky) -> dict[str, ParamInfo]:
    info: dict[str, ParamInfo] = {}
    mt = scene.materials
    for row, mname in enumerate(mt.names):
        for f in MATERIAL_FIELDS:
            n = f"{mname}.{f}"
            info[n] = ParamInfo(n, "material", f, row, (3,) if f in COLOR_FIELDS else ())
    for k, img in enumerate(scene.textures):
        uses = np.argwhere(mt.tex == k)
        if len(uses):
            row, slot = (int(x) for x in uses[0])
            n = f"{mt.names[row]}.{_SLOT_NAMES[slot]}_map"
        else:
            n = f"texture{k}"
        info[n] = ParamInfo(n, "texture", "texels", k, tuple(np.shape(img)))
    if sky.kind == SKY_CONSTANT:
        info["sky.color"] = ParamInfo("sky.color", "sky", "color", 0, (3,))
    for f in ("position", "direction"):
        info[f"camera.{f}"] = ParamInfo(f"camera.{f}", "camera", f, 0, (3,))
    return info


def _check_value(p: ParamInfo, v: np.ndarray) -> None:
    if not np.all(np.isfinite(v)):
        raise ValueError(f"{p.name}: values must be finite")
    if p.field == "roughness" and not 0.0 <= float(v) <= 1.0:
        raise ValueError(f"{p.name}: roughness must be in [0, 1], got {float(v)}")
    if p.kind in ("material", "texture", "sky") and p.field != "roughness" and np.any(v < 0):
        raise ValueError(f"{p.name}: values must be >= 0")
    if p.field == "direction" and not np.any(v != 0):
        raise ValueError(f"{p.name}: the view direction must not be zero")
