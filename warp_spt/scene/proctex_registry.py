"""Procedural textures' host half: what a texture declares, the registry of declarations, and the
references (:class:`ProcRef`) that MTL files and the API make to them. No Warp.

A declaration is a name and a parameter layout (defaults and ranges); the texture's Warp function
lives beside it in :mod:`warp_spt.device.proctex`, registered under the same name by
:func:`warp_spt.device.proctex.texture`. Reading a scene needs only the declarations: an MTL line
``map_Kd proc:noise scale=2`` is checked and packed here, so the MTL reader (``io/mtl.py``) works
without Warp and ``io/`` stays below ``device/``. The built-ins' declarations (:data:`BUILTINS`) are
the one home of their parameters; their Warp functions take them from here.

Syntax and semantics of textures, parameters and ``proc:`` maps: :mod:`warp_spt.device.proctex`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from types import MappingProxyType

import numpy as np

from warp_spt.scene.errors import SceneError
from warp_spt.scene.limits import MAX_RADIANCE
from warp_spt.scene.numbers import plain_float

MAX_PARAMS = 16           # floats in a texture's parameter vector (device.proctex.ProcParams)
PREFIX = "proc:"
MAX_PARAMETER = 1e15      # undeclared numbers: as far as a coordinate may go (scene.limits.MAX_COORDINATE)


@dataclass(frozen=True)
class ProcParam:
    """A declared parameter: its default and the range its numbers may take (``texture(name,
    scale=ProcParam(1.0, 1e-6, 1e6))``). A plain number or RGB triple declares the default range:
    numbers within +-MAX_PARAMETER; an RGB triple is a colour, whose limits are those of the slot it
    fills (reflectance in [0, 1], emission in [0, MAX_RADIANCE]: the material schema's ranges)."""

    default: object
    low: float | None = None
    high: float | None = None


@dataclass(frozen=True)
class ProcTexture:
    """A texture's declaration: its name and parameter layout (its Warp function: device.proctex)."""

    name: str
    params: tuple[tuple[str, tuple[float, ...]], ...]   # (key, default values) in layout order
    ranges: tuple[tuple[float, float], ...] = ()        # (low, high) per key, in layout order

    def layout(self) -> dict[str, tuple[int, int]]:
        """``{key: (offset, size)}`` in the parameter vector."""
        out, offset = {}, 0
        for key, default in self.params:
            out[key] = (offset, len(default))
            offset += len(default)
        return out

    def colours(self) -> tuple[int, ...]:
        """Offsets of the RGB triples (colours) in the parameter vector."""
        return tuple(off for off, size in self.layout().values() if size == 3)

    def check(self, key: str, vals: tuple[float, ...]) -> str | None:
        """Why ``vals`` cannot be ``key``'s values (a scalar outside its declared range; colours are
        checked against their slot by the MTL reader and validate_scene), or None."""
        low, high = dict(zip((k for k, _ in self.params), self.ranges))[key]
        if len(vals) == 1 and not low <= vals[0] <= high:
            return f"{key} of proc:{self.name} must lie in [{low:g}, {high:g}], got {vals[0]:g}"
        if len(vals) == 3 and not all(0.0 <= v <= MAX_RADIANCE for v in vals):
            return f"{key} of proc:{self.name} is a colour: each value in [0, {MAX_RADIANCE:g}], got {vals}"
        return None

    def pack(self, values: dict[str, tuple[float, ...]] | None = None) -> tuple[float, ...]:
        """The parameter vector (MAX_PARAMS floats): defaults overridden by ``values``."""
        vec = [0.0] * MAX_PARAMS
        given = values or {}
        for (key, default), (offset, size) in zip(self.params, self.layout().values()):
            vec[offset:offset + size] = given.get(key, default)
        return tuple(float(np.float32(v)) for v in vec)


def declare(name: str, **params) -> ProcTexture:
    """The declaration of texture ``name`` with these parameters (numbers, RGB triples or
    :class:`ProcParam`), checked; it is registered with its Warp function (device.proctex), not here."""
    if not name or not all(c.isalnum() or c in "_-" for c in name):
        raise ValueError(f"procedural texture name {name!r}: use letters, digits, '_' or '-'")
    declared = {k: v if isinstance(v, ProcParam) else ProcParam(v) for k, v in params.items()}
    layout = tuple((k, _default(name, k, d.default)) for k, d in declared.items())
    ranges = tuple((-MAX_PARAMETER if d.low is None else d.low, MAX_PARAMETER if d.high is None else d.high)
                   for d in declared.values())
    if sum(len(d) for _, d in layout) > MAX_PARAMS:
        raise ValueError(f"procedural texture {name!r}: at most {MAX_PARAMS} parameter values")
    return ProcTexture(name=name, params=layout, ranges=ranges)


def _default(name: str, key: str, value) -> tuple[float, ...]:
    vals = (value,) if isinstance(value, (int, float)) else tuple(value)
    if len(vals) not in (1, 3) or not all(isinstance(v, (int, float)) and math.isfinite(v)
                                          and abs(v) <= MAX_PARAMETER for v in vals):
        raise ValueError(f"procedural texture {name!r}: parameter {key!r} must be a finite number or "
                         f"an RGB triple, got {value!r}")
    return tuple(float(v) for v in vals)


# The built-ins' parameters (their Warp functions in device.proctex read them from here).
BUILTINS = MappingProxyType({t.name: t for t in (
    declare("checker"),
    declare("noise", scale=ProcParam(4.0, -1e6, 1e6), color1=(0.0, 0.0, 0.0), color2=(1.0, 1.0, 1.0)),
    declare("marble", scale=ProcParam(2.0, -1e6, 1e6), turbulence=ProcParam(4.0, -1e6, 1e6),
            color1=(0.92, 0.92, 0.9), color2=(0.25, 0.25, 0.3)),
    declare("wood", scale=ProcParam(1.0, -1e6, 1e6), rings=ProcParam(5.0, -1e6, 1e6),
            color1=(0.75, 0.52, 0.3), color2=(0.45, 0.28, 0.14)),
    declare("grid", cells=ProcParam(10.0, -1e6, 1e6), width=ProcParam(0.05, 0.0, 1.0),
            line=(0.05, 0.05, 0.05), fill=(0.9, 0.9, 0.9)),
)})

_REGISTRY: dict[str, ProcTexture] = dict(BUILTINS)   # a plugin registry, like INTEGRATORS: names -> declarations


def register_declaration(tex: ProcTexture) -> None:
    """Make ``tex`` the declaration of its name (replacing an earlier one); device.proctex's
    ``register_texture`` calls it with the Warp function's registration, so the two agree."""
    _REGISTRY[tex.name] = tex


def get_texture(name: str) -> ProcTexture:
    """The declaration of the registered texture ``name`` (KeyError if none)."""
    return _REGISTRY[name]


def registered() -> list[str]:
    """Names of all registered procedural textures, sorted."""
    return sorted(_REGISTRY)


# ---------------------------------------------------------------------------------------------
# References: MTL statements, the API, scene instances


@dataclass(frozen=True)
class ProcRef:
    """A ``map_* proc:NAME key=value...`` statement: the texture, its packed parameters, where written."""

    name: str
    params: tuple[float, ...]
    mtl_file: str = field(default="<api>", compare=False)     # instances are equal by (name, params)
    line: int = field(default=0, compare=False)
    colours: tuple[int, ...] = field(default=(), compare=False)   # offsets of its RGB triples (validation)


def proc_texture(name: str, **values) -> ProcRef:
    """A procedural texture for a :class:`~warp_spt.scene.model.Material` colour slot, from the API
    (e.g. ``Material("m", diffuse_map=proc_texture("marble", scale=2.0))``)."""
    tex = get_texture(name)
    unknown = set(values) - set(tex.layout())
    if unknown:
        raise ValueError(f"proc:{name} has no parameter(s) {', '.join(sorted(unknown))}")
    given = {k: _default(name, k, v) for k, v in values.items()}
    for key, vals in given.items():
        problem = tex.check(key, vals)
        if problem:
            raise ValueError(problem)
    return ProcRef(name, tex.pack(given), colours=tex.colours())


def parse_proc_map(args: list[bytes], path: str, lineno: int, tag: str,
                   colour_high: float = MAX_RADIANCE) -> ProcRef | None:
    """The MTL hook: a :class:`ProcRef` if the statement's arguments start with ``proc:``, else None.
    ``colour_high``: the largest value the slots that ``tag`` fills take (the material schema's)."""
    if not args or not args[0].decode("latin-1").startswith(PREFIX):
        return None
    name = args[0].decode("latin-1")[len(PREFIX):]
    if name not in _REGISTRY:
        known = ", ".join(registered())
        raise SceneError(path, lineno, f"unknown procedural texture {name!r} after '{tag}' (registered: {known})")
    tex = _REGISTRY[name]
    layout = tex.layout()
    values: dict[str, tuple[float, ...]] = {}
    for tok in args[1:]:
        key, sep, text = tok.decode("latin-1").partition("=")
        if not sep or key not in layout:
            want = ", ".join(layout) or "none"
            raise SceneError(path, lineno, f"expected key=value for proc:{name} (keys: {want}), got {key!r}")
        try:
            vals = tuple(plain_float(v) for v in text.split(","))      # "1_0", "inf": not numbers here
        except ValueError:
            vals = ()
        size = layout[key][1]
        if len(vals) != size or not all(math.isfinite(v) for v in vals):
            raise SceneError(path, lineno, f"expected {size} finite number(s) for {key} of proc:{name}, got {text!r}")
        problem = tex.check(key, vals) or (size == 3 and colour_problem(tag, colour_high, key, name, vals))
        if problem:
            raise SceneError(path, lineno, problem)
        values[key] = vals
    return ProcRef(name, tex.pack(values), path, lineno, colours=tex.colours())


def colour_problem(tag: str, high: float, key: str, name: str, vals) -> str | None:
    """Why colour ``vals`` cannot fill ``tag``'s slots, whose values lie in [0, ``high``], or None."""
    if all(0.0 <= v <= high for v in vals):
        return None
    return f"{key} of proc:{name} fills '{tag}': each value in [0, {high:g}], got {tuple(vals)}"


def instance_arrays(refs: list[ProcRef], key: tuple[tuple[str, str], ...]) -> tuple[np.ndarray, np.ndarray]:
    """Per-instance kind (index into ``key``, device.proctex.features_key) and (K, MAX_PARAMS) float32
    parameters."""
    order = {name: i for i, (name, _) in enumerate(key)}
    kinds = np.array([order.get(r.name, -1) for r in refs], dtype=np.int32)
    params = np.array([r.params for r in refs], dtype=np.float32).reshape(-1, MAX_PARAMS)
    return kinds, params
