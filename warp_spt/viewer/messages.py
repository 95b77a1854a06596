"""Every message a page sends, checked in one place before it touches a session's state.

:func:`parse` turns the text of a websocket frame into a JSON object (no NaN or Infinity, nesting
bounded); :func:`checked` takes an object (from the browser host or the Jupyter widget) and returns
a new one holding only the fields its type declares, each of its kind and within its bounds:
numbers finite and bounded so that no step of navigation overflows (``1e308`` dolly steps, an
``Infinity`` size), integers that fit a float (a 400-digit parameter value), strings short.
Anything else is a ValueError naming the field and what it must be; the session answers it with a
notice and changes nothing.
"""

from __future__ import annotations

import json
import math
from typing import Any, Callable

MAX_NESTING = 8              # the deepest message the page sends is 2 levels: {"value": [r, g, b]}
MAX_TEXT = 4096              # characters of a string field (an output name)
MAX_STEPS = 1000.0           # dolly/zoom steps of one message (a wheel sends about 1)
MAX_DRAG = 1000.0            # orbit/pan drag of one message, in view widths
MAX_VALUE = 1e38             # a setting's or parameter's number: within float32 (the checks after say more)
MAX_PARAM_SIZE = 64          # numbers in one parameter value (colours 3, procedural vectors up to 16)
MAX_COMMAND_SIDE = 65536     # -res of the copied command line, as the page's fields allow
AXES = ("x", "y", "z", "-x", "-y", "-z")


def _reject_constant(name: str):
    raise ValueError(f"the page sent {name}, which is not a number")


def parse(text: str) -> dict:
    """The JSON object in ``text``; ValueError for anything else (not JSON, NaN or Infinity,
    nested deeper than MAX_NESTING, not an object)."""
    depth = 0
    in_string = escaped = False
    for ch in text:          # bounded before json recurses (deep nesting raises RecursionError)
        if in_string:
            if escaped:
                escaped = False
            elif ch == "\\":
                escaped = True
            elif ch == '"':
                in_string = False
        elif ch == '"':
            in_string = True
        elif ch in "[{":
            depth += 1
            if depth > MAX_NESTING:
                raise ValueError(f"the page sent a message nested more than {MAX_NESTING} deep")
        elif ch in "]}":
            depth -= 1
    try:
        message = json.loads(text, parse_constant=_reject_constant)
    except ValueError as err:
        raise ValueError(f"the page sent a message that is not JSON: {err}") from None
    if not isinstance(message, dict):
        raise ValueError("the page sent a message that is not a JSON object")
    return message


def number(value: Any, name: str, low: float = -MAX_VALUE, high: float = MAX_VALUE) -> float:
    """``value`` as a finite float in [low, high] (a bool is no number)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"{name} must be a number, got {value!r:.60}")
    if isinstance(value, int) and not -MAX_VALUE <= value <= MAX_VALUE:     # before float() overflows
        raise ValueError(f"{name} must lie in [{low:g}, {high:g}], got an integer of {len(str(abs(value)))} digits")
    v = float(value)
    if not (math.isfinite(v) and low <= v <= high):
        raise ValueError(f"{name} must be a finite number in [{low:g}, {high:g}], got {value!r:.60}")
    return v


def integer(value: Any, name: str, low: int, high: int) -> int:
    """``value`` as an int in [low, high]: a JSON integer, or a float with no fraction (the page's
    Number(input.value) sends 384 or 384.0)."""
    v = number(value, name, low, high)
    if v != math.floor(v):
        raise ValueError(f"{name} must be a whole number in [{low}, {high}], got {value!r:.60}")
    return int(v)


def text(value: Any, name: str) -> str:
    if not isinstance(value, str) or len(value) > MAX_TEXT:
        raise ValueError(f"{name} must be a string of at most {MAX_TEXT} characters")
    return value


def boolean(value: Any, name: str) -> bool:
    if not isinstance(value, bool):
        raise ValueError(f"{name} must be true or false, got {value!r:.60}")
    return value


def numbers(value: Any, name: str, size: int | None = None) -> float | list[float]:
    """A number, or a flat list of numbers (exactly ``size`` when given, else at most MAX_PARAM_SIZE)."""
    if not isinstance(value, list):
        if size is not None:
            raise ValueError(f"{name} must be a list of {size} numbers, got {value!r:.60}")
        return number(value, name)
    if (size is not None and len(value) != size) or not 0 < len(value) <= MAX_PARAM_SIZE:
        raise ValueError(f"{name} must be a list of {size or f'at most {MAX_PARAM_SIZE}'} numbers")
    return [number(v, f"{name}[{k}]") for k, v in enumerate(value)]


def _choice(choices) -> Callable[[Any, str], str]:
    def check(value: Any, name: str) -> str:
        if value not in choices:
            raise ValueError(f"{name} must be one of {', '.join(choices)}, got {value!r:.60}")
        return value
    return check


def _optional(check: Callable) -> Callable:
    return lambda value, name: None if value is None else check(value, name)


_DRAG = lambda v, n: number(v, n, -MAX_DRAG, MAX_DRAG)          # noqa: E731
_STEPS = lambda v, n: number(v, n, -MAX_STEPS, MAX_STEPS)       # noqa: E731
_FRACTION = lambda v, n: number(v, n, 0.0, 1.0)                 # noqa: E731
_SIDE = _optional(lambda v, n: integer(v, n, 1, MAX_COMMAND_SIDE))

# The fields of each message type (docs/viewer.md, "Protocol"): name -> (check, required).
FIELDS: dict[str, dict[str, tuple[Callable, bool]]] = {
    "hello": {}, "frame": {}, "reset": {}, "reload": {},
    "interact": {"active": (boolean, True)},
    "orbit": {"dx": (_DRAG, True), "dy": (_DRAG, True)},
    "pan": {"dx": (_DRAG, True), "dy": (_DRAG, True)},
    "dolly": {"steps": (_STEPS, True)},
    "zoom": {"steps": (_STEPS, True)},
    "pick": {"x": (_FRACTION, True), "y": (_FRACTION, True)},
    "up": {"axis": (_choice(AXES), True)},
    "set": {"key": (text, True), "value": (lambda v, n: v, True)},       # the value: by key, below
    "param": {"name": (text, True), "value": (numbers, True)},
    "command": {"width": (_SIDE, False), "height": (_SIDE, False),
                "spp": (_optional(lambda v, n: integer(v, n, 1, 1 << 20)), False),
                "out": (_optional(text), False)},
    "save": {"format": (_optional(text), False)},
}

# "set": the value's kind by key (ViewSettings' fields and the camera's fov and aperture); ranges
# and choices are checked by the session (viewer.session.checked_settings) on the typed value.
_INT = lambda v, n: integer(v, n, -(1 << 31), 1 << 31)           # noqa: E731
_VEC3 = lambda v, n: numbers(v, n, 3)                             # noqa: E731
SET_VALUES: dict[str, Callable] = {
    "width": _INT, "height": _INT, "max_depth": _INT, "max_spp": _INT, "preview_scale": _INT,
    "integrator": text, "sampler": text, "sky": text, "tonemap": text,
    "exposure": number, "fov": number, "aperture": number,
    "sky_color": lambda v, n: numbers(v, n, 3),
    "env_path": text, "env_rotate": number, "env_strength": number,
    "env_background": _optional(lambda v, n: numbers(v, n, 3)),
    "error_map": boolean,
    # the page's lights and fog (viewer/lighting.py checks their ranges)
    "sun": boolean, "sun_direction": _VEC3, "sun_color": _VEC3, "sun_radius": number,
    "lamp": text, "lamp_position": _VEC3, "lamp_intensity": _VEC3, "lamp_direction": _VEC3, "lamp_angle": number,
    "fog": boolean, "fog_sigma_a": _VEC3, "fog_sigma_s": _VEC3, "fog_g": number,
}


def checked(message: Any) -> dict:
    """A new message holding only ``message``'s declared fields, checked (ValueError otherwise)."""
    if not isinstance(message, dict):
        raise ValueError("the page sent a message that is not a JSON object")
    kind = message.get("type")
    if not isinstance(kind, str) or kind not in FIELDS:
        raise ValueError(f"unknown message {kind!r:.60}")
    out: dict = {"type": kind}
    for name, (check, required) in FIELDS[kind].items():
        if name not in message:
            if required:
                raise ValueError(f"a {kind!r} message needs {name!r}")
            continue
        value = check(message[name], name)
        if value is not None:                 # an optional field sent as null: as if left out
            out[name] = value
    if kind == "set":
        # by key, null included (the generic rule above drops a null; some keys take one, others refuse it)
        out["value"] = SET_VALUES.get(out["key"], _scalar)(message["value"], out["key"])
    return out


def _scalar(value: Any, name: str):
    """A setting this module does not list: one bool, bounded number or short string (the session
    refuses names that are not settings)."""
    if isinstance(value, bool):
        return value
    if isinstance(value, str):
        return text(value, name)
    return number(value, name)

