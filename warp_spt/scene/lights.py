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

The kinds are declared in :data:`PUNCTUAL_KINDS`: each :class:`PunctualKind` names its record (the
dataclass) and its fields (:class:`LightField`: the keyword of light files and ``--light``, the
record's field, its type and bounds). The records check their values from their declaration
(:func:`check_fields`), and :func:`parse_light` reads a light file's line or a ``--light`` flag's
words against it (``warp_spt.io.light_file``), so a new punctual kind is its record and one
:func:`register_punctual_kind` call, with no parser edit (its device side: ``warp_spt.emitters``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from warp_spt.scene.limits import MAX_COORDINATE, MAX_RADIANCE, MIN_DIRECTION
from warp_spt.scene.numbers import plain_float

KIND_SUN, KIND_POINT, KIND_SPOT = 0, 1, 2
MAX_SUN_RADIUS_DEG = 45.0     # a wider "sun" is a sky: an environment or the gradient sky

# Field types of a light kind's declaration: what a file's keyword takes and the record checks
VECTOR = "vector"    # three finite numbers (``nonzero``: not all 0), e.g. a position or direction
COLOUR = "colour"    # one number (a grey) or three, each in [low, high]
ANGLE = "angle"      # one number of degrees in [low, high]
WORD = "word"        # one word (a name)


@dataclass(frozen=True)
class LightField:
    """One field of a light kind: ``keyword`` in light files and ``--light``, ``field`` the record's
    attribute, ``type`` one of VECTOR, COLOUR, ANGLE, WORD, and its bounds."""

    keyword: str
    field: str
    type: str
    low: float | None = None
    high: float | None = None
    nonzero: bool = False


@dataclass(frozen=True)
class PunctualKind:
    """A punctual light kind: ``name`` (a light file line's first word), its ``record`` (a frozen
    dataclass whose ``__post_init__`` calls :func:`check_fields`) and its ``fields``, in the order
    errors list them. ``numbered``: ``--light`` names an unnamed one ``light0``, ``light1``... (a
    sun keeps its record's default name)."""

    name: str
    record: type
    fields: tuple[LightField, ...]
    numbered: bool = True


PUNCTUAL_KINDS: dict[str, PunctualKind] = {}     # a plugin registry: name -> declaration, in order


def register_punctual_kind(kind: PunctualKind) -> PunctualKind:
    """Declare ``kind`` (replacing an earlier one of its name): the light file and ``--light`` take it."""
    PUNCTUAL_KINDS[kind.name] = kind
    return kind


def punctual_kind(record: type) -> PunctualKind:
    """The declaration of the kind whose record is ``record``."""
    return next(k for k in PUNCTUAL_KINDS.values() if k.record is record)


def check_fields(light) -> None:
    """Check and normalise a record's fields from its declaration (ValueError naming the light and
    field): vectors and colours become tuples of 3 floats, angles floats."""
    name = light.name
    for f in punctual_kind(type(light)).fields:
        v = getattr(light, f.field)
        if f.type == VECTOR:
            v = _vec(name, f.field, v, nonzero=f.nonzero)
        elif f.type == COLOUR:
            v = _colour(name, f.field, v, f.low, f.high)
        elif f.type == ANGLE:
            v = _angle(name, f.field, v, f.low, f.high)
        object.__setattr__(light, f.field, v)


def _vec(name: str, field: str, v, nonzero: bool = False) -> tuple[float, float, float]:
    try:
        t = tuple(float(x) for x in v)
    except (TypeError, ValueError):
        raise ValueError(f"light {name!r}: {field} must be 3 numbers, got {v!r:.60}") from None
    if len(t) != 3 or not all(math.isfinite(x) for x in t):
        raise ValueError(f"light {name!r}: {field} must be 3 finite numbers, got {v!r:.60}")
    if nonzero and not any(t):
        raise ValueError(f"light {name!r}: {field} must not be zero")
    size = max(abs(x) for x in t)
    # a direction is normalised in float32 on the device: 1e20 squared overflows (the sun then shone
    # from below the horizon); a position as far as geometry may lie
    if nonzero and not MIN_DIRECTION <= size <= MAX_COORDINATE:
        raise ValueError(f"light {name!r}: {field} must not be huge or tiny: its largest component must lie in "
                         f"[{MIN_DIRECTION:g}, {MAX_COORDINATE:g}] in size, got {v!r:.60}")
    if not nonzero and size > MAX_COORDINATE:
        raise ValueError(f"light {name!r}: {field} must lie within +-{MAX_COORDINATE:g}, got {v!r:.60}")
    return t


def _colour(name: str, field: str, v, low: float, high: float) -> tuple[float, float, float]:
    """One number (grey) or three, each in [low, high]."""
    if isinstance(v, (int, float)):
        v = (v, v, v)
    t = _vec(name, field, v)
    if not all(low <= x <= high for x in t):
        raise ValueError(f"light {name!r}: {field} must be in [{low:g}, {high:g}], got {t}")
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
        check_fields(self)


@dataclass(frozen=True)
class PointLight:
    """Radiant intensity ``intensity`` (W/sr, RGB) from ``position``, the same in every direction."""

    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    intensity: tuple[float, float, float] = (1.0, 1.0, 1.0)
    name: str = "light"
    kind = KIND_POINT

    def __post_init__(self):
        check_fields(self)


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
        check_fields(self)
        if self.inner_deg > self.outer_deg:
            raise ValueError(f"light {self.name!r}: inner_deg ({self.inner_deg:g}) must not be above outer_deg "
                             f"({self.outer_deg:g})")
        if self.outer_deg <= 0.0:
            raise ValueError(f"light {self.name!r}: outer_deg must be above 0")


# The built-in kinds, in the order of their device index (KIND_*). Bounds: radiance and intensity as
# every emitter's (scene.limits); a spot's cone within a hemisphere.
NAME = LightField("name", "name", WORD)
register_punctual_kind(PunctualKind("sun", SunLight, (
    LightField("direction", "direction", VECTOR, nonzero=True), LightField("color", "color", COLOUR, 0.0, MAX_RADIANCE),
    LightField("radius", "radius_deg", ANGLE, 0.0, MAX_SUN_RADIUS_DEG), NAME), numbered=False))
register_punctual_kind(PunctualKind("point", PointLight, (
    LightField("position", "position", VECTOR), LightField("intensity", "intensity", COLOUR, 0.0, MAX_RADIANCE), NAME)))
register_punctual_kind(PunctualKind("spot", SpotLight, (
    LightField("position", "position", VECTOR), LightField("direction", "direction", VECTOR, nonzero=True),
    LightField("intensity", "intensity", COLOUR, 0.0, MAX_RADIANCE), LightField("inner", "inner_deg", ANGLE, 0.0, 90.0),
    LightField("outer", "outer_deg", ANGLE, 0.0, 90.0), NAME)))
assert [k.record.kind for k in PUNCTUAL_KINDS.values()] == [KIND_SUN, KIND_POINT, KIND_SPOT]

PUNCTUAL_TYPES = tuple(k.record for k in PUNCTUAL_KINDS.values())


# ---------------------------------------------------------------------------------------------
# A light from words: a line of a light file or a --light flag (warp_spt.io.light_file's syntax)


def _numbers(words: list[str], k: int, n: int, keyword: str) -> list[float]:
    got = []
    for w in words[k:k + n]:
        try:
            got.append(plain_float(w))
        except ValueError:
            break
    if len(got) < n:
        raise ValueError(f"{keyword} needs {n} number{'s' if n > 1 else ''}, got {' '.join(words[k:k + n]) or 'none'}")
    return got


def _kinds_text() -> str:
    """The registered kinds as a phrase: "sun, point or spot"."""
    names = list(PUNCTUAL_KINDS)
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} or {names[-1]}"


def parse_light(words: list[str], default_name: str | None = None):
    """One light from the words of a line (ValueError with what was expected); ``default_name``
    names it when the line does not and its kind is ``numbered`` (``--light``)."""
    if not words:
        raise ValueError(f"expected a light: {_kinds_text()}, then keyword values")
    kind = PUNCTUAL_KINDS.get(words[0].lower())
    if kind is None:
        raise ValueError(f"expected the kind of light ({_kinds_text()}), got {words[0]!r}")
    keys = {f.keyword: f for f in kind.fields}
    fields: dict = {}
    k = 1
    while k < len(words):
        key = words[k].lower()
        if key not in keys:
            raise ValueError(f"a {kind.name} light takes {', '.join(keys)}; got {words[k]!r}")
        f = keys[key]
        if f.field in fields:
            raise ValueError(f"{key} given twice")
        k += 1
        if f.type == WORD:
            if k >= len(words):
                raise ValueError(f"{key} needs a word")
            fields[f.field] = words[k]
            k += 1
        elif f.type == COLOUR:
            vals = _numbers(words, k, 1, key)
            more = _numbers(words, k, 3, key) if k + 2 < len(words) and _is_number(words[k + 1]) else None
            fields[f.field] = tuple(more) if more else (vals[0],) * 3
            k += 3 if more else 1
        else:
            n = {VECTOR: 3, ANGLE: 1}[f.type]
            vals = _numbers(words, k, n, key)
            fields[f.field] = tuple(vals) if n == 3 else vals[0]
            k += n
    if "name" not in fields and default_name and kind.numbered:
        fields["name"] = default_name
    try:
        return kind.record(**fields)
    except ValueError as err:      # the record's words for its fields, the file's keywords here
        text = str(err).replace(f"light {fields.get('name', kind.record.name)!r}: ", "")
        for f in kind.fields:
            text = text.replace(f.field, f.keyword) if f.field != f.keyword else text
        raise ValueError(text) from None


def _is_number(word: str) -> bool:
    try:
        plain_float(word)
        return True
    except ValueError:
        return False


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
