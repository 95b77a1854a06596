"""Integrators, chosen by name: a registry of :class:`Integrator` records and their built functions.

``INTEGRATORS`` maps a name to its record (``common.Integrator``: step and vertex builders, sample
stride, capabilities, parameters); a new integrator is one module defining ``INTEGRATOR`` plus one
line here (or ``register(record)`` from outside the package). The line names the module, which is
imported when its record is first asked for: a render imports the integrator it uses, not the others
(their Warp functions are defined at import; ``ears`` with the guiding trees alone cost about 15 ms
of every start, docs/performance.md, Start-up). Its parameters (``Integrator.params``, :class:`Param`
records: name, default, doc, type, range) are set by name in ``RenderSettings.integrator_options``
and checked before any upload; no integrator keeps state in its module. Built functions and kernels
live in the one
kernel cache (:mod:`warp_spt.runtime.kernel_cache`), per (integrator, sampler, features); Warp's
disk cache keeps the compiled code across processes.
"""

from __future__ import annotations

import importlib
from collections.abc import MutableMapping

import warp as wp

from warp_spt.device.camera_rays import CameraParams, camera_params, camera_ray
from warp_spt.device.structs import Features
from warp_spt.device.proctex import explain_compile_failure
from warp_spt.integrators.common import (
    Integrator,
    Param,
    PathState,
    RenderParams,
    fast_inputs,
    make_kernel,
    make_start_path,
)
from warp_spt.runtime import kernel_cache, kernel_index
from warp_spt.samplers import DEFAULT_SAMPLER, get_sampler


class Registry(MutableMapping):
    """Name -> :class:`Integrator`; an entry is a record, or the name of the module (in this
    package) whose ``INTEGRATOR`` it is, imported on first look-up. Listing the names imports
    nothing; values and items import every module."""

    def __init__(self, entries: dict[str, "Integrator | str"]):
        self._entries = dict(entries)

    def __getitem__(self, name: str) -> Integrator:
        entry = self._entries[name]
        if isinstance(entry, str):
            entry = self._entries[name] = importlib.import_module(f"{__name__}.{entry}").INTEGRATOR
        return entry

    def __setitem__(self, name: str, record: Integrator) -> None:
        self._entries[name] = record

    def __delitem__(self, name: str) -> None:
        del self._entries[name]

    def __iter__(self):
        return iter(self._entries)

    def __len__(self) -> int:
        return len(self._entries)

    def __contains__(self, name) -> bool:      # without importing the module
        return name in self._entries

    def __repr__(self) -> str:
        return f"Registry({sorted(self._entries)})"


INTEGRATORS = Registry({
    "seed": "seed",
    "nee": "nee",
    "guided": "guided",
    "ears": "ears",
    "volpath": "volpath",
})
DEFAULT_INTEGRATOR = "nee"      # see docs/performance.md, Light transport: several times the seed's efficiency


def register(integrator: Integrator) -> Integrator:
    """Add ``integrator`` to ``INTEGRATORS`` under its name (a plugin's one line); returns it."""
    INTEGRATORS[integrator.name] = integrator
    return integrator


def get_integrator(name: str) -> Integrator:
    """The record registered as ``name`` (ValueError naming the choices otherwise)."""
    if name not in INTEGRATORS:
        raise ValueError(f"unknown integrator {name!r}; choose from {', '.join(sorted(INTEGRATORS))}")
    return INTEGRATORS[name]


def check_integrator(name: str) -> None:
    """Raise ValueError unless ``name`` is a registered integrator."""
    get_integrator(name)


def describe_options(name: str) -> str:
    """The parameters of integrator ``name``, one line each (name, allowed values, default, doc),
    or a line saying it has none: for help texts and the docs."""
    rec = get_integrator(name)
    if not rec.params:
        return f"{name}: no options"
    return "\n".join([f"{name}:"] + [f"  {p.describe()}" for p in rec.params])


def check_sliceable(name: str, renderer: str) -> None:
    """ValueError if integrator ``name`` schedules its own passes (``Integrator.render_passes``, as
    ``guided``): it renders whole images through the tile renderer only, not in ``renderer``'s
    batches, windows or sample slices."""
    if get_integrator(name).render_passes is not None:
        raise ValueError(f"integrator {name!r} trains over its own passes of the whole image: {renderer} cannot "
                         "render it (use render_scene, or the command line without budgets, --workers or --cluster)")


def get_step(integrator: str, sampler: str, features: Features, differentiable: bool = False):
    """``(step, start_path)`` Warp functions of ``integrator`` with ``sampler`` for ``features``;
    ``differentiable`` for the differentiable kernel (hits carry derivatives in the camera ray)."""
    rec = get_integrator(integrator)
    return kernel_cache.cached("step", (integrator, sampler, features, differentiable),
                               lambda: _with_start(rec.make_step, sampler, features, differentiable))


def get_vertex(integrator: str, sampler: str, features: Features, inline: bool | None = None,
               pathwise: bool = False):
    """``(vertex, start_path)`` Warp functions of ``integrator`` with ``sampler`` for ``features``
    (ValueError when the integrator has no vertex function: no path replay for it); ``inline``: the
    vertex's wp.func inline hint; ``pathwise``: the vertex with the tape's derivatives
    (``Integrator.pathwise``)."""
    rec = get_integrator(integrator)
    if not rec.replayable or (pathwise and not rec.pathwise):
        what = "pathwise vertex" if rec.replayable else "vertex function"
        raise ValueError(f"integrator {integrator!r} has no {what} for path replay")
    if pathwise:
        return kernel_cache.cached("pathwise vertex", (integrator, sampler, features, inline), lambda: _with_start(
            lambda f, s, i: rec.make_vertex(f, s, i, pathwise=True), sampler, features, inline))
    return kernel_cache.cached("vertex", (integrator, sampler, features, inline),
                               lambda: _with_start(rec.make_vertex, sampler, features, inline))


def _with_start(make, sampler: str, features: Features, flag) -> tuple:
    """``(make(features, sampler, flag), start_path)``; each pair gets its own ``start_path``, so
    that the adjoint-code flags path replay sets on its functions reach no other kernel's."""
    s = get_sampler(sampler)
    return make(features, s, flag), make_start_path(s)


def get_kernel(features: Features, device: str = "cpu", integrator: str | None = None,
               sampler: str | None = None) -> wp.Kernel:
    """The fast kernel for (integrator, sampler, features), compiled and loaded on ``device``
    (defaults: DEFAULT_INTEGRATOR, DEFAULT_SAMPLER)."""
    integrator = integrator or DEFAULT_INTEGRATOR
    sampler = sampler or DEFAULT_SAMPLER
    spec = (integrator, sampler, features)
    own = kernel_index.enabled() and _own_code(integrator, sampler, features)
    key = kernel_index.own_key("fast", spec) if own else None
    if key is not None and device == "cpu" and ("fast", spec) not in kernel_cache.entries("fast"):
        found = kernel_cache.cached("fast, by own key", spec,
                                    lambda: kernel_index.load(key, make_kernel(None, None, decorate=False), device))
        if found is not None:
            return found
    step, start = get_step(integrator, sampler, features)
    build = get_integrator(integrator).make_kernel or make_kernel
    k = kernel_cache.cached("fast", spec, lambda: build(step, start))
    try:
        kernel_cache.load(k, device)
    except Exception as err:       # a user's procedural texture is the likely culprit: name it
        if not features.procedural:
            raise
        raise explain_compile_failure(features.procedural, err, device) from None
    if key is not None:
        kernel_index.remember(key, k, device)
    return k


def _own_code(integrator: str, sampler: str, features: Features) -> bool:
    """Whether the fast kernel of (integrator, sampler, features) is this package's code alone, the
    common kernel around an integrator and a sampler of its own and no procedural texture: what
    ``kernel_index``'s key covers (a plugin's source is not in its digest)."""
    from warp_spt.emitters.registry import KINDS as LIGHT_KINDS
    from warp_spt.media.registry import KINDS as MEDIA_KINDS
    from warp_spt.samplers import SAMPLERS

    rec = get_integrator(integrator)
    make = SAMPLERS.get(sampler)
    ours = [rec.make_step, make, *MEDIA_KINDS.values(), *(k.make for k in LIGHT_KINDS)]
    return (rec.make_kernel is None and not features.procedural and make is not None
            and all(getattr(x, "__module__", getattr(x, "__name__", "")).startswith("warp_spt.") for x in ours))


__all__ = ["INTEGRATORS", "DEFAULT_INTEGRATOR", "Integrator", "CameraParams", "Param", "PathState", "RenderParams",
           "camera_params", "camera_ray", "check_sliceable", "describe_options", "fast_inputs", "get_integrator", "get_kernel", "get_step",
           "get_vertex", "check_integrator", "register"]
