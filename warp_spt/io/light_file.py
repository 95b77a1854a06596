"""Light files (``--lights FILE``) and ``--light`` specifications: one light a line.

::

    # a comment; blank lines are ignored
    sun   direction 0.4 -0.3 1   color 3 3 2.8   radius 0.27
    point position 0 2 0         intensity 50
    spot  position 0 3 0  direction 0 -1 0  intensity 200 180 160  inner 15  outer 30  name key

The first word is the kind (``sun``, ``point``, ``spot``); then ``keyword value...`` pairs in any
order: three numbers for ``position`` and ``direction``, one (grey) or three for ``color`` /
``intensity``, one number of degrees for ``radius``, ``inner`` and ``outer``, a word for ``name``.
Units as ``warp_spt.scene.lights``: a sun's ``color`` is its irradiance and ``direction`` points
towards it; a point or spot light's ``intensity`` is W/sr; a spot's ``direction`` is where it
shines. Unset keywords take the records' defaults (a white sun of radius 0 straight up, intensity
1, a spot's cone 0 to 45 degrees). Every error names the file and line.
"""

from __future__ import annotations

from warp_spt.io.tokens import normalise_text, read_file
from warp_spt.scene.errors import SceneError
from warp_spt.scene.lights import PointLight, SpotLight, SunLight
from warp_spt.scene.numbers import plain_float

# kind -> (record, {keyword: (field, how many numbers: 3, "colour" = 1 or 3, 1 = an angle, 0 = a word)})
_COMMON = {"name": ("name", 0)}
KINDS = {
    "sun": (SunLight, {"direction": ("direction", 3), "color": ("color", "colour"),
                       "radius": ("radius_deg", 1), **_COMMON}),
    "point": (PointLight, {"position": ("position", 3), "intensity": ("intensity", "colour"), **_COMMON}),
    "spot": (SpotLight, {"position": ("position", 3), "direction": ("direction", 3),
                         "intensity": ("intensity", "colour"), "inner": ("inner_deg", 1),
                         "outer": ("outer_deg", 1), **_COMMON}),
}


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


def parse_light(words: list[str], default_name: str | None = None):
    """One light from the words of a line (ValueError with what was expected)."""
    if not words:
        raise ValueError("expected a light: sun, point or spot, then keyword values")
    kind = words[0].lower()
    if kind not in KINDS:
        raise ValueError(f"expected the kind of light (sun, point or spot), got {words[0]!r}")
    record, keys = KINDS[kind]
    fields: dict = {}
    k = 1
    while k < len(words):
        key = words[k].lower()
        if key not in keys:
            raise ValueError(f"a {kind} light takes {', '.join(keys)}; got {words[k]!r}")
        field, n = keys[key]
        if field in fields:
            raise ValueError(f"{key} given twice")
        k += 1
        if n == 0:
            if k >= len(words):
                raise ValueError(f"{key} needs a word")
            fields[field] = words[k]
            k += 1
        elif n == "colour":
            vals = _numbers(words, k, 1, key)
            more = _numbers(words, k, 3, key) if k + 2 < len(words) and _is_number(words[k + 1]) else None
            fields[field] = tuple(more) if more else (vals[0],) * 3
            k += 3 if more else 1
        else:
            vals = _numbers(words, k, n, key)
            fields[field] = tuple(vals) if n == 3 else vals[0]
            k += n
    if "name" not in fields and default_name:
        fields["name"] = default_name
    try:
        return record(**fields)
    except ValueError as err:      # the record's words for its fields, the file's keywords here
        text = str(err).replace(f"light {fields.get('name', record.name)!r}: ", "")
        for keyword, (field, _) in keys.items():
            text = text.replace(field, keyword) if field != keyword else text
        raise ValueError(text) from None


def _is_number(word: str) -> bool:
    try:
        plain_float(word)
        return True
    except ValueError:
        return False


def load_lights(path: str) -> list:
    """The lights of a light file (SceneError naming the file and line)."""
    text = normalise_text(read_file(path, "light"), path, "light").decode("utf-8", errors="replace")
    lights = []
    for lineno, line in enumerate(text.split("\n"), 1):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        try:
            lights.append(parse_light(words))
        except ValueError as err:
            raise SceneError(path, lineno, str(err)) from None
    return lights
