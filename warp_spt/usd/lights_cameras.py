"""UsdLux lights and UsdGeom cameras onto the renderer's: a distant light is the sun, a sphere light an
emitting sphere (a point light with ``treatAsPoint``), rect and disk lights emitting surfaces, a dome
light the sky (its texture the environment map); a camera the shared :class:`FileCamera` record.

A light's radiance is ``color * intensity * 2^exposure`` (UsdLux), tinted by the blackbody colour of
its ``colorTemperature`` where ``enableColorTemperature`` is set, divided by its area where it is
``normalize``d; a distant light's is taken as the sun's irradiance, as glTF's lux are."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from warp_spt.scene.errors import SceneError
from warp_spt.scene.parts import FileCamera


@dataclass
class UsdLight:
    """A UsdLux light the renderer draws as one of its punctual lights (``to_scene``: that light)."""

    prim: str
    light: object

    def to_scene(self):
        return self.light


def _unit(v) -> tuple[float, float, float]:
    v = np.asarray(v, np.float64)
    n = float(np.linalg.norm(v))
    return tuple(float(c) for c in v / n) if n > 0 else (0.0, 0.0, -1.0)


def radiance(lux, time) -> tuple[float, float, float]:
    """``color * intensity * 2^exposure`` of a UsdLux.LightAPI, tinted by its colour temperature."""
    def get(attr, default):
        v = attr.Get(time) if attr else None
        return default if v is None else v

    from pxr import UsdLux

    colour = tuple(float(c) for c in get(lux.GetColorAttr(), (1.0, 1.0, 1.0)))
    if get(lux.GetEnableColorTemperatureAttr(), False):
        # UsdLux's own blackbody colour (linear Rec. 709, luminance 1) tints the colour
        tint = UsdLux.BlackbodyTemperatureAsRgb(float(get(lux.GetColorTemperatureAttr(), 6500.0)))
        colour = tuple(c * float(t) for c, t in zip(colour, tint))
    scale = float(get(lux.GetIntensityAttr(), 1.0)) * 2.0 ** float(get(lux.GetExposureAttr(), 0.0))
    return tuple(c * scale for c in colour)


def normalized(lux, time) -> bool:
    attr = lux.GetNormalizeAttr()
    return bool(attr.Get(time)) if attr else False


def distant(prim, world: np.ndarray, time) -> UsdLight:
    """The sun: its light goes along the prim's -Z, so the sun lies along +Z; ``angle`` is the diameter."""
    from pxr import UsdLux

    from warp_spt.scene.lights import MAX_SUN_RADIUS_DEG, SunLight

    d = UsdLux.DistantLight(prim)
    angle = d.GetAngleAttr().Get(time)
    radius = min(max(float(0.53 if angle is None else angle) / 2.0, 0.0), MAX_SUN_RADIUS_DEG)
    return UsdLight(str(prim.GetPath()), SunLight(direction=_unit(world[:3, :3] @ [0.0, 0.0, 1.0]),
                                                  color=radiance(d.LightAPI(), time), radius_deg=radius,
                                                  name=prim.GetName()))


def camera(prim, world: np.ndarray, index: int, time, path: str) -> FileCamera:
    """A UsdGeom.Camera looking down its -Z with +Y up; the vertical field of view from its
    vertical aperture and focal length (both in tenths of a unit: their ratio is what counts)."""
    from pxr import UsdGeom

    cam = UsdGeom.Camera(prim)
    focal = float(cam.GetFocalLengthAttr().Get(time) or 50.0)
    vertical = float(cam.GetVerticalApertureAttr().Get(time) or 15.2908)
    horizontal = float(cam.GetHorizontalApertureAttr().Get(time) or 20.955)
    where = str(prim.GetPath())
    if not focal > 0 or not vertical > 0 or not horizontal > 0:
        raise SceneError(path, 0, f"{where}: focalLength and the apertures must be positive, got {focal:g}, "
                         f"{horizontal:g} and {vertical:g}")
    kind = "perspective" if cam.GetProjectionAttr().Get(time) in (None, "perspective") else "orthographic"
    direction, up = world[:3, :3] @ [0.0, 0.0, -1.0], world[:3, :3] @ [0.0, 1.0, 0.0]
    if not np.linalg.norm(direction) > 0 or not np.linalg.norm(up) > 0:
        raise SceneError(path, 0, f"{where}: the camera's transform is singular")
    near = cam.GetClippingRangeAttr().Get(time)
    return FileCamera(name=prim.GetName(), index=index, node=-1, position=tuple(float(c) for c in world[:3, 3]),
                      direction=_unit(direction), up=_unit(up), yfov=2.0 * math.atan(vertical / (2.0 * focal)),
                      aspect=horizontal / vertical, znear=float(near[0]) if near is not None else 0.0, kind=kind)


def disk_polygon(radius: float, segments: int = 48) -> np.ndarray:
    """(segments, 3) points of a disk in the XY plane, counter-clockwise seen from +Z."""
    a = np.linspace(0.0, 2.0 * math.pi, segments, endpoint=False)
    return np.stack([radius * np.cos(a), radius * np.sin(a), np.zeros(segments)], axis=1)


def area_surface(prim, time) -> tuple[np.ndarray, np.ndarray, float]:
    """(points, triangles, area) of a rect or disk light in its own space: it emits along its -Z, so
    its triangles face -Z."""
    from pxr import UsdLux

    if prim.IsA(UsdLux.RectLight):
        r = UsdLux.RectLight(prim)
        w, h = float(r.GetWidthAttr().Get(time) or 1.0), float(r.GetHeightAttr().Get(time) or 1.0)
        pts = np.array([[-w / 2, -h / 2, 0], [w / 2, -h / 2, 0], [w / 2, h / 2, 0], [-w / 2, h / 2, 0]], np.float64)
        area = w * h
    else:
        radius = float(UsdLux.DiskLight(prim).GetRadiusAttr().Get(time) or 0.5)
        pts = disk_polygon(radius)
        area = math.pi * radius * radius
    n = len(pts)
    tri = np.stack([np.zeros(n - 2, np.int32), np.arange(2, n), np.arange(1, n - 1)], axis=1).astype(np.int32)
    return pts, tri, area
