"""Punctual lights on the host: the sun (a directional light), point and spot lights.

Units are the renderer's radiometric ones (radiance as the materials' ``emission`` and the sky's
colours): a point or spot light's ``intensity`` is radiant intensity (W/sr per RGB channel), so a
surface at distance r facing it receives irradiance ``intensity / r**2``; the sun's ``color`` is
the irradiance it gives a surface facing it. Angles are in degrees.

* :class:`SunLight`: ``direction`` towards the sun (any length), ``radius_deg`` its angular radius:
  0 is a delta light (one direction); above 0 a disc of directions of constant radiance
  ``color / (pi sin^2 radius)``, so that the irradiance is still ``color``.
* :class:`PointLight`: ``position``, ``intensity``.
* :class:`SpotLight`: a point light that shines along ``direction`` with glTF's smooth falloff,
  ``clamp((cos a - cos outer) / (cos inner - cos outer), 0, 1) ** 2`` at angle ``a`` off its axis.

None of them can be hit by a ray: they are sampled by next-event estimation only (the ``seed``
integrator, pure path tracing, does not see them). ``Scene.lights`` holds them; the device side
is ``warp_spt.emitters.punctual``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from warp_spt.scene.limits import MAX_RADIANCE

KIND_SUN, KIND_POINT, KIND_SPOT = 0, 1, 2
MAX_SUN_RADIUS_DEG = 45.0     # a wider "sun" is a sky: an environment or the gradient sky


def _vec(name: str, field: str, v, nonzero: bool = False) -> tuple[float, float, float]:
    try:
        t = tuple(float(x) for x in v)
    except (TypeError, ValueError):
        raise ValueError(f"light {name!r}: {field} must be 3 numbers, got {v!r:.60}") from None
    if len(t) != 3 or not all(math.isfinite(x) for x in t):
        raise ValueError(f"light {name!r}: {field} must be 3 finite numbers, got {v!r:.60}")
    if nonzero and not any(t):
        raise ValueError(f"light {name!r}: {field} must not be zero")
    return t


def _colour(name: str, field: str, v) -> tuple[float, float, float]:
    """One number (grey) or three, each in [0, MAX_RADIANCE]."""
    if isinstance(v, (int, float)):
        v = (v, v, v)
    t = _vec(name, field, v)
    if not all(0.0 <= x <= MAX_RADIANCE for x in t):
        raise ValueError(f"light {name!r}: {field} must be in [0, {MAX_RADIANCE:g}], got {t}")
    return t


def _angle(name: str, field: str, v, low: float, high: float) -> float:
    try:
        a = float(v)
    except (TypeError, ValueError):
        raise ValueError(f"light {name!r}: {field} must be a number of degrees, got {v!r:.60}") from None
    if not (low <= a <= high):
        raise ValueError(f"light {name!r}: {field} must be in [{low:g}, {high:g}] degrees, got {a:g}")
    return a


@dataclass(frozen=True)
class SunLight:
    """A directional light: irradiance ``color`` from ``direction`` (towards the sun)."""

    direction: tuple[float, float, float] = (0.0, 0.0, 1.0)
    color: tuple[float, float, float] = (1.0, 1.0, 1.0)
    radius_deg: float = 0.0
    name: str = "sun"
    kind = KIND_SUN

    def __post_init__(self):
        object.__setattr__(self, "direction", _vec(self.name, "direction", self.direction, nonzero=True))
        object.__setattr__(self, "color", _colour(self.name, "color", self.color))
        object.__setattr__(self, "radius_deg", _angle(self.name, "radius_deg", self.radius_deg, 0.0,
                                                      MAX_SUN_RADIUS_DEG))


@dataclass(frozen=True)
class PointLight:
    """Radiant intensity ``intensity`` (W/sr, RGB) from ``position``, the same in every direction."""

    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    intensity: tuple[float, float, float] = (1.0, 1.0, 1.0)
    name: str = "light"
    kind = KIND_POINT

    def __post_init__(self):
        object.__setattr__(self, "position", _vec(self.name, "position", self.position))
        object.__setattr__(self, "intensity", _colour(self.name, "intensity", self.intensity))


@dataclass(frozen=True)
class SpotLight:
    """A point light shining along ``direction``: full ``intensity`` within ``inner_deg`` of the
    axis, none beyond ``outer_deg``, glTF's smooth falloff between."""

    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    direction: tuple[float, float, float] = (0.0, 0.0, -1.0)
    intensity: tuple[float, float, float] = (1.0, 1.0, 1.0)
    inner_deg: float = 0.0
    outer_deg: float = 45.0
    name: str = "spot"
    kind = KIND_SPOT

    def __post_init__(self):
        object.__setattr__(self, "position", _vec(self.name, "position", self.position))
        object.__setattr__(self, "direction", _vec(self.name, "direction", self.direction, nonzero=True))
        object.__setattr__(self, "intensity", _colour(self.name, "intensity", self.intensity))
        outer = _angle(self.name, "outer_deg", self.outer_deg, 0.0, 90.0)
        inner = _angle(self.name, "inner_deg", self.inner_deg, 0.0, 90.0)
        if inner > outer:
            raise ValueError(f"light {self.name!r}: inner_deg ({inner:g}) must not be above outer_deg ({outer:g})")
        if outer <= 0.0:
            raise ValueError(f"light {self.name!r}: outer_deg must be above 0")
        object.__setattr__(self, "inner_deg", inner)
        object.__setattr__(self, "outer_deg", outer)


PUNCTUAL_TYPES = (SunLight, PointLight, SpotLight)


def spot_falloff(cos_angle: float, inner_deg: float, outer_deg: float) -> float:
    """glTF's spot falloff at the cosine of the angle off the axis (KHR_lights_punctual's
    recommended form: its scale's denominator at least 1e-3), for checks and the host's weights."""
    ci, co = math.cos(math.radians(inner_deg)), math.cos(math.radians(outer_deg))
    s = min(max((cos_angle - co) / max(1e-3, ci - co), 0.0), 1.0)
    return s * s


def moved(light, offset) -> object:
    """``light`` in a frame whose origin is at ``offset`` (scene.recentre): positions shift."""
    if light.kind == KIND_SUN:
        return light
    return replace(light, position=tuple(float(p - o) for p, o in zip(light.position, offset)))


def punctual_lights(lights) -> list:
    """The punctual lights among a scene's ``lights`` (others, records a loader keeps, are skipped)."""
    return [x for x in lights if isinstance(x, PUNCTUAL_TYPES)]


def unique_names(lights) -> list[str]:
    """The lights' names, made unique by suffixes ``#2``, ``#3``... in order (parameter names)."""
    seen: dict[str, int] = {}
    out = []
    for x in lights:
        n = seen.get(x.name, 0) + 1
        seen[x.name] = n
        out.append(x.name if n == 1 else f"{x.name}#{n}")
    return out
