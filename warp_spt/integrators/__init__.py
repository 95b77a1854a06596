"""Integrators, chosen by name, and the cache of their compiled kernels.

``INTEGRATORS`` maps a name to a module-level ``make(features, sampler) -> step`` (see
``common``); a new integrator is one module plus one line here. Kernels are cached per
(integrator, sampler, features) and process; Warp's disk cache keeps the compiled code across
processes.
"""

from __future__ import annotations

import threading

import warp as wp

from warp_spt.core.device_scene import Features
from warp_spt.core.proctex import explain_compile_failure
from warp_spt.integrators import nee, seed
from warp_spt.integrators.common import (
    CameraParams,
    PathState,
    RenderParams,
    camera_params,
    camera_ray,
    make_kernel,
    make_start_path,
)
from warp_spt.samplers import DEFAULT_SAMPLER, get_sampler

INTEGRATORS = {"seed": seed.make, "nee": nee.make}
# Optional: ``make_vertex(features, sampler) -> vertex``, the bounce after its ray was traced
# (``step`` = closest hit + vertex). Path-replay gradients (warp_spt.diff.prb) need it; an integrator
# without one gets gradients through the tape only.
VERTICES = {"seed": seed.make_vertex, "nee": nee.make_vertex}
DEFAULT_INTEGRATOR = "nee"      # see README, "Speed and accuracy": several times the seed's efficiency

_kernels: dict[tuple[str, str, Features], wp.Kernel] = {}
_steps: dict[tuple, tuple] = {}      # (registry, integrator, sampler, features, differentiable) -> functions
_lock = threading.Lock()


def check_integrator(name: str) -> None:
    if name not in INTEGRATORS:
        raise ValueError(f"unknown integrator {name!r}; choose from {', '.join(sorted(INTEGRATORS))}")


def get_step(integrator: str, sampler: str, features: Features, differentiable: bool = False):
    """``(step, start_path)`` Warp functions of ``integrator`` with ``sampler`` for ``features``;
    ``differentiable`` for the differentiable kernel (hits carry derivatives in the camera ray)."""
    check_integrator(integrator)
    return _functions(INTEGRATORS, integrator, sampler, features, differentiable)


def get_vertex(integrator: str, sampler: str, features: Features, inline: bool | None = None):
    """``(vertex, start_path)`` Warp functions of ``integrator`` with ``sampler`` for ``features``
    (ValueError when the integrator has no vertex function: no path replay for it); ``inline``: the
    vertex's wp.func inline hint."""
    check_integrator(integrator)
    if integrator not in VERTICES:
        raise ValueError(f"integrator {integrator!r} has no vertex function for path replay")
    return _functions(VERTICES, integrator, sampler, features, inline)


def _functions(registry: dict, integrator: str, sampler: str, features: Features, *flags) -> tuple:
    """``(registry[integrator](features, sampler, *flags), start_path)``, built once per process."""
    key = (id(registry), integrator, sampler, features, flags)
    with _lock:
        if key not in _steps:
            s = get_sampler(sampler)
            _steps[key] = (registry[integrator](features, s, *flags), make_start_path(s))
        return _steps[key]


def get_kernel(features: Features, device: str = "cpu", integrator: str | None = None,
               sampler: str | None = None) -> wp.Kernel:
    """The fast kernel for (integrator, sampler, features), compiled and loaded on ``device``
    (defaults: DEFAULT_INTEGRATOR, samplers.DEFAULT_SAMPLER)."""
    integrator = integrator or DEFAULT_INTEGRATOR
    sampler = sampler or DEFAULT_SAMPLER
    key = (integrator, sampler, features)
    step, start = get_step(integrator, sampler, features)
    with _lock:
        k = _kernels.get(key)
        if k is None:
            k = _kernels[key] = make_kernel(step, start)
    try:
        wp.load_module(k.module, device=device)
    except Exception as err:       # a user's procedural texture is the likely culprit: name it
        if not features.procedural:
            raise
        raise explain_compile_failure(features.procedural, err, device) from None
    return k


__all__ = ["INTEGRATORS", "VERTICES", "CameraParams", "PathState", "RenderParams", "camera_params", "camera_ray",
           "get_kernel", "get_step", "get_vertex", "check_integrator"]
