"""Cameras (perspective) and KHR_lights_punctual lights, placed by their nodes, and the renderer's
camera and lights made from them."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from warp_spt.gltf.document import Document, _err
from warp_spt.scene.parts import FileCamera


# a glTF camera is the readers' shared record (its ``node`` the glTF node that places it)
GltfCamera = FileCamera


@dataclass
class GltfLight:
    """A KHR_lights_punctual light placed by its node, as written (:meth:`to_scene`: the light the
    renderer draws)."""

    name: str
    kind: str                    # "point", "spot" or "directional"
    color: tuple[float, float, float]
    intensity: float
    position: tuple[float, float, float]
    direction: tuple[float, float, float]     # the node's -Z
    range: float | None = None
    inner_cone: float = 0.0
    outer_cone: float = math.pi / 4

    def to_scene(self):
        """The renderer's light (``warp_spt.scene.lights``): glTF's candela (point, spot) taken as
        W/sr and its lux (directional) as irradiance, one to one in the renderer's units, times the
        colour; a directional light's -Z is where its light goes, so the sun lies the other way;
        cone angles from radians to degrees. ``range`` is not used: light falls off as 1 / r^2."""
        from warp_spt.scene.lights import PointLight, SpotLight, SunLight

        power = tuple(float(c) * float(self.intensity) for c in self.color)
        name = self.name or self.kind
        if self.kind == "directional":
            return SunLight(direction=tuple(-float(c) for c in self.direction), color=power, name=name)
        if self.kind == "spot":
            outer = math.degrees(self.outer_cone)
            return SpotLight(position=self.position, direction=self.direction, intensity=power,
                             inner_deg=min(math.degrees(self.inner_cone), outer), outer_deg=outer, name=name)
        return PointLight(position=self.position, intensity=power, name=name)


class CamerasLights(Document):
    def _camera(self, k: int, node: int, world: np.ndarray) -> GltfCamera:
        c = self.item("cameras", k)
        ptr = f"/cameras/{k}"
        kind = self.get(c, "type", str, ptr, required=True)
        name = self.get(c, "name", str, ptr, "")
        if kind != "perspective":
            self.warnings.append(f"{self.path}: {ptr}: {kind} cameras are not read (only perspective ones)")
            kind_ok = False
        else:
            kind_ok = True
        p = self.obj(c, "perspective", ptr, required=kind_ok) if kind_ok else {}
        yfov = self.get(p, "yfov", float, f"{ptr}/perspective", 0.8, required=kind_ok)
        if not 0 < yfov < math.pi:
            raise _err(self.path, f"{ptr}/perspective/yfov", f"yfov {yfov:g} must lie in (0, pi) radians")
        aspect = self.get(p, "aspectRatio", float, f"{ptr}/perspective")
        if aspect is not None and not aspect > 0:
            raise _err(self.path, f"{ptr}/perspective/aspectRatio", f"aspectRatio {aspect:g} must be positive")
        direction, up = _unit(world[:3, :3] @ [0, 0, -1]), _unit(world[:3, :3] @ [0, 1, 0])
        if direction is None or up is None:
            raise _err(self.path, f"/nodes/{node}", "the camera's node transform is singular")
        return FileCamera(name=name, index=k, node=node, position=tuple(float(c) for c in world[:3, 3]), direction=direction, up=up,
                          yfov=yfov, aspect=aspect, znear=self.get(p, "znear", float, f"{ptr}/perspective", 0.0),
                          kind=kind, path=str(self.path))

    def _light(self, ref: dict, ptr: str, world: np.ndarray) -> GltfLight:
        k = self.get(ref, "light", int, ptr, required=True)
        lights = self.get(self.obj(self.obj(self.doc, "extensions", ""), "KHR_lights_punctual", "/extensions"),
                          "lights", list, "/extensions/KHR_lights_punctual", [])
        if not 0 <= k < len(lights) or not isinstance(lights[k], dict):
            raise _err(self.path, f"{ptr}/light", f"light index {k} is out of range: the file has {len(lights)} lights")
        lptr = f"/extensions/KHR_lights_punctual/lights/{k}"
        light = lights[k]
        kind = self.get(light, "type", str, lptr, required=True)
        if kind not in ("point", "spot", "directional"):
            raise _err(self.path, f"{lptr}/type", f"expected point, spot or directional, got {kind!r}")
        spot = self.obj(light, "spot", lptr)
        out = GltfLight(
            name=self.get(light, "name", str, lptr, ""), kind=kind,
            color=tuple(self.numbers(light, "color", lptr, 3, [1.0, 1.0, 1.0])),
            intensity=self.get(light, "intensity", float, lptr, 1.0),
            position=tuple(float(c) for c in world[:3, 3]), direction=_unit(world[:3, :3] @ [0, 0, -1]) or (0.0, 0.0, -1.0),
            range=self.get(light, "range", float, lptr),
            inner_cone=self.get(spot, "innerConeAngle", float, f"{lptr}/spot", 0.0),
            outer_cone=self.get(spot, "outerConeAngle", float, f"{lptr}/spot", math.pi / 4))
        # the extension's ranges, each naming its member; then the renderer's light's own bounds
        if not all(0.0 <= c <= 1.0 for c in out.color):
            raise _err(self.path, f"{lptr}/color", f"each component must lie in [0, 1] (linear RGB), got {list(out.color)}")
        if not out.intensity >= 0.0:
            raise _err(self.path, f"{lptr}/intensity", f"must be at least 0, got {out.intensity:g}")
        if out.range is not None and not out.range > 0.0:
            raise _err(self.path, f"{lptr}/range", f"must be above 0, got {out.range:g}")
        if kind == "spot" and not 0.0 <= out.inner_cone < out.outer_cone <= math.pi / 2:
            raise _err(self.path, f"{lptr}/spot", f"expected 0 <= innerConeAngle < outerConeAngle <= pi/2 (radians), "
                       f"got {out.inner_cone:g} and {out.outer_cone:g}")
        try:
            out.to_scene()
        except ValueError as err:
            raise _err(self.path, lptr, str(err)) from None
        return out


def _unit(v: np.ndarray) -> tuple[float, float, float] | None:
    n = float(np.linalg.norm(v))
    return tuple(float(c) for c in np.asarray(v) / n) if n > 0 and math.isfinite(n) else None


def choose_camera(cameras: list[GltfCamera], choice: str | int, width: int, height: int):
    """The renderer's :class:`~warp_spt.scene.camera.Camera` for the camera named ``choice`` (or at
    index ``choice`` in file order) among ``cameras`` (``Scene.cameras``), for a ``width`` x
    ``height`` image: the file's vertical field of view is kept (the horizontal one follows from the
    image's aspect, as glTF viewers do), a pinhole, with the camera's own up direction (so its roll is
    kept). Raises ValueError naming the cameras there are."""
    from warp_spt.scene.camera import Camera

    if not cameras:
        raise ValueError("the model files define no cameras")
    names = [c.name for c in cameras]
    text = str(choice)
    if text in names:
        if names.count(text) > 1:
            raise ValueError(f"{names.count(text)} cameras are named {text!r}; give an index (0..{len(cameras) - 1})")
        cam = cameras[names.index(text)]
    elif text.lstrip("-").isdigit() and 0 <= int(text) < len(cameras):
        cam = cameras[int(text)]
    else:
        listed = ", ".join(f"{k}: {n!r}" if n else f"{k} (unnamed)" for k, n in enumerate(names))
        raise ValueError(f"no camera {text!r}; the files have {len(cameras)} camera{'s' * (len(cameras) > 1)}: "
                         f"{listed}")
    if cam.kind != "perspective":       # the file and its JSON pointer, as a reader's error names them
        where = f"{cam.path}: " if cam.path else ""
        raise ValueError(f"{where}/cameras/{cam.index}: camera {text!r} is {cam.kind}; only perspective cameras "
                         "can be looked through")
    camera = Camera(position=cam.position, direction=cam.direction, fov=cam.fov_degrees(width, height),
                    aperture=0.0, focus=1.0, up=cam.up)
    camera.validate()
    return camera
