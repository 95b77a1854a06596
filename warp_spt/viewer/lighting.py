"""The viewer's lights and fog: a sun, a lamp (point or spot) and a fog the page adds to the scene.

They are :class:`warp_spt.viewer.session.ViewSettings` fields (``sun*``, ``lamp*``, ``fog*``),
checked by key like every "set" message, and become the records the command line's ``--sun``,
``--light`` and ``--fog`` make (``warp_spt.scene.lights``, ``warp_spt.scene.media``), added to the
scene's own lights and replacing its fog's coefficients. Positions are in world coordinates, as
the copied command line writes them; the session moves them into its recentred frame.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from warp_spt.scene.limits import MAX_COORDINATE, MAX_RADIANCE, MIN_DIRECTION
from warp_spt.scene.media import scene_fog

LAMP_KINDS = ("off", "point", "spot")
VECTORS = ("sun_direction", "sun_color", "lamp_position", "lamp_intensity", "lamp_direction",
           "fog_sigma_a", "fog_sigma_s", "env_background")
LIGHT_KEYS = ("sun", "sun_direction", "sun_color", "sun_radius", "lamp", "lamp_position", "lamp_intensity",
              "lamp_direction", "lamp_angle")
FOG_KEYS = ("fog", "fog_sigma_a", "fog_sigma_s", "fog_g")
UNPLACED = (0.0, 0.0, 0.0)      # sun_direction and lamp_direction before the scene's load chose them


def vector(value, key: str) -> tuple[float, float, float] | None:
    """``value`` as 3 floats (``env_background`` may be None: the map itself is the backdrop)."""
    if value is None and key == "env_background":
        return None
    try:
        t = tuple(float(v) for v in value)
    except (TypeError, ValueError):
        raise ValueError(f"{key} must be 3 numbers, got {value!r:.60}") from None
    if len(t) != 3 or not all(math.isfinite(v) for v in t):
        raise ValueError(f"{key} must be 3 finite numbers, got {value!r:.60}")
    if key in ("sun_direction", "lamp_direction") and t == UNPLACED:
        raise ValueError(f"{key} must not be zero (it is a direction)")
    return t


def check(settings) -> None:
    """ValueError naming the key for lights or a fog the renderer must not see (the records' own
    checks, and the bounds of scene/limits.py on positions and directions)."""
    s = settings
    if s.lamp not in LAMP_KINDS:
        raise ValueError(f"lamp must be one of {', '.join(LAMP_KINDS)}, got {s.lamp!r:.60}")
    for key in ("sun_direction", "lamp_direction"):
        v = getattr(s, key)
        if v != UNPLACED and not MIN_DIRECTION <= max(abs(x) for x in v) <= MAX_COORDINATE:
            raise ValueError(f"{key} must be a direction with its largest component in "
                             f"[{MIN_DIRECTION:g}, {MAX_COORDINATE:g}], got {v}")
    if max(abs(x) for x in s.lamp_position) > MAX_COORDINATE:
        raise ValueError(f"lamp_position must lie within +-{MAX_COORDINATE:g}, got {s.lamp_position}")
    if s.env_background is not None and not all(0.0 <= c <= MAX_RADIANCE for c in s.env_background):
        raise ValueError(f"env_background colour values must lie in [0, {MAX_RADIANCE:g}], got {s.env_background}")
    _records(s, np.zeros(3))            # the records check colours, radius and angles, on or off
    fog(s, None, force=True)


def _records(s, offset) -> tuple:
    """(the sun, the lamp as a point light, as a spot light): the records of the page's values,
    checked whether or not they are on (the page hears of a bad value when it sends it)."""
    from warp_spt.scene.lights import PointLight, SpotLight, SunLight

    position = tuple(float(p - o) for p, o in zip(s.lamp_position, offset))
    try:
        sun = SunLight(direction=s.sun_direction if s.sun_direction != UNPLACED else (0.0, 0.0, 1.0),
                       color=s.sun_color, radius_deg=s.sun_radius, name="sun")
        point = PointLight(position=position, intensity=s.lamp_intensity, name="lamp")
        spot = SpotLight(position=position, direction=s.lamp_direction if s.lamp_direction != UNPLACED
                         else (0.0, 0.0, -1.0), intensity=s.lamp_intensity, outer_deg=s.lamp_angle, name="lamp")
    except ValueError as err:       # "light 'sun': color must be ..." -> "sun color must be ..."
        raise ValueError(str(err).replace("light 'sun': ", "sun_").replace("light 'lamp': ", "lamp_")
                         .replace("lamp_outer_deg", "lamp_angle")
                         .replace("sun_radius_deg", "sun_radius")) from None
    return sun, point, spot


def lights(s, offset) -> list:
    """The page's lights that are on, in the session's frame (world = session + ``offset``)."""
    sun, point, spot = _records(s, offset)
    return ([sun] if s.sun else []) + {"off": [], "point": [point], "spot": [spot]}[s.lamp]


def fog(s, base, force: bool = False):
    """The fog: the scene's own (``base``, a grid keeps its density) or a homogeneous one, with the
    page's coefficients; None when the fog is off (``force``: built anyway, to check the values)."""
    from warp_spt.scene.media import Medium

    if not (s.fog or force):
        return None
    medium = replace(base if base is not None else Medium(), sigma_a=s.fog_sigma_a, sigma_s=s.fog_sigma_s, g=s.fog_g)
    return medium.check("fog")


def placed(s, given, up, camera, centre, size: float):
    """``s`` with what the caller left unset placed for this scene (``size``: its bounds' diagonal):
    the sun behind the camera's left shoulder and high (towards it: up, back, left); the lamp a
    quarter of the size above the centre (under a room's ceiling, above a model), shining down, with
    an intensity that gives irradiance 1 at the centre; a fog whose optical depth across the scene
    is about 0.6 (``scene.media.scene_fog``: sigma_s 0.5 / size, sigma_a 0.1 / size), whatever the
    scene's units."""
    u = np.asarray(up, np.float64)
    d = np.asarray(camera.direction, np.float64)
    d /= np.linalg.norm(d)
    left = np.cross(u, d)
    left = left / np.linalg.norm(left) if np.linalg.norm(left) > 1e-9 else np.zeros(3)
    fields = {}
    if "sun_direction" not in given:
        fields["sun_direction"] = tuple(float(x) for x in 1.5 * u - d + 0.5 * left)
    if "lamp_position" not in given:
        fields["lamp_position"] = tuple(float(x) for x in np.clip(np.asarray(centre) + 0.25 * size * u,
                                                                  -MAX_COORDINATE, MAX_COORDINATE))
    if "lamp_direction" not in given:
        fields["lamp_direction"] = tuple(float(-x) for x in u)
    if "lamp_intensity" not in given:
        fields["lamp_intensity"] = (min(float((0.25 * size) ** 2), MAX_RADIANCE),) * 3
    for key, value in scene_fog(size).items():      # the command line's rule for a --fog without them
        if f"fog_{key}" not in given:
            fields[f"fog_{key}"] = value
    return replace(s, **fields)


def from_scene_fog(s, medium, given):
    """``s`` showing the scene's own fog (on, its coefficients) where the caller set none."""
    if medium is None or "fog" in given:
        return s
    fields = {"fog": True}
    for key, name in (("fog_sigma_a", "sigma_a"), ("fog_sigma_s", "sigma_s"), ("fog_g", "g")):
        if key not in given:
            fields[key] = getattr(medium, name)
    return replace(s, **fields)


def command_flags(s, base_fog) -> tuple[list[str], list[str]]:
    """(the ``warp-spt`` flags of the page's lights and fog, notes on what they cannot say)."""
    from .command import number

    vec = lambda v: [number(x) for x in v]          # noqa: E731
    args, notes = [], []
    if s.sun:
        args += ["--sun", *vec(s.sun_direction)]
        args += ["--sun-color", *vec(s.sun_color)] if s.sun_color != (1.0, 1.0, 1.0) else []
        args += ["--sun-radius", number(s.sun_radius)] if s.sun_radius else []
    if s.lamp != "off":
        args += ["--light", s.lamp, "position", *vec(s.lamp_position), "intensity", *vec(s.lamp_intensity)]
        if s.lamp == "spot":
            args += ["direction", *vec(s.lamp_direction), "outer", number(s.lamp_angle)]
    if s.fog:
        m = fog(s, base_fog)
        for name in ("sigma_a", "sigma_s", "emission"):
            v = getattr(m, name)
            if name != "emission" or any(v):
                args += ["--fog", f"{name}=" + ",".join(vec(v))]
        args += ["--fog", f"g={number(m.g)}"] if m.g else []
        args += ["--fog", f"majorant={number(m.majorant)}"] if m.majorant != 1.0 else []
        if m.density is not None:
            notes.append("the fog's density grid is not on the command line (--fog is homogeneous)")
    return args, notes
