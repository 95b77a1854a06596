"""Samplers: the uniform numbers of a path, addressed by explicit dimension, chosen by name.

Every sampler is a pure function of (seed, pixel, global sample index, dimension), so an image is
the same whatever the threads and tiles, and renders of disjoint ``sample_offset`` ranges merge
exactly. A kernel asks ``value, state = next_1d(state, dim)`` (or ``next_2d`` for dims dim, dim+1)
with the dimensions in increasing order; the integrators assign them (``integrators.common``).

* ``independent`` (:mod:`warp_spt.samplers.independent`): dimension d is the d-th draw of a PCG chain.
* ``sobol`` (:mod:`warp_spt.samplers.sobol`): Owen-scrambled Sobol' points per pixel.
* ``sobol-affine`` (:mod:`warp_spt.samplers.sobol_affine`): the same points with a cheaper nested scramble
  of the same error.

Both Sobol' samplers are one builder (:mod:`warp_spt.samplers.sobol_points`) given a scramble record.
A new sampler is one module with a ``make() -> Sampler`` function plus one line in ``SAMPLERS``; a new
scramble of the Sobol' points, a ``sobol_points.Scramble`` of four Warp functions and ``points(...).sampler``.
"""

from __future__ import annotations

from warp_spt.runtime import kernel_cache
from warp_spt.samplers import independent, sobol, sobol_affine
from warp_spt.scene.families import DEFAULT_SAMPLER
from warp_spt.samplers.base import Sampler, SamplerState, batch_lanes, detach_requests, sampler_state

__all__ = ["SAMPLERS", "DEFAULT_SAMPLER", "Sampler", "SamplerState", "batch_lanes", "check_sampler", "detach_requests",
           "get_sampler", "sampler_state"]


SAMPLERS = {
    "independent": independent.make,
    "sobol": sobol.make,
    "sobol-affine": sobol_affine.make,
}
# Sobol' points: on bench_light's Cornell box, nee + sobol reaches a given whole-image error sooner
# than nee + independent at 256^2 and 512^2 (docs/performance.md, Light transport). sobol-affine: the
# same points, a scramble with Owen's pair law (so Owen's variance) at 9 hashes a 2-D request instead
# of 15: RMSE over sobol's 0.94-1.02 on three scenes (within 1.6 standard errors, bench_scramble.py),
# whole renders 1.10-1.19x faster (bench_sampler.py --render). The name lives in scene/families.py,
# where the viewer reads it without Warp: one default for every front end.
assert DEFAULT_SAMPLER in SAMPLERS


def check_sampler(name: str) -> None:
    """Raise ValueError unless ``name`` is a registered sampler."""
    if name not in SAMPLERS:
        raise ValueError(f"unknown sampler {name!r}; choose from {', '.join(sorted(SAMPLERS))}")


def get_sampler(name: str) -> Sampler:
    """The sampler registered as ``name`` (built once per process, in the kernel cache)."""
    check_sampler(name)
    return kernel_cache.cached("sampler", name, SAMPLERS[name])
