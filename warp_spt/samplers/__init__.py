"""Samplers: the uniform numbers of a path, addressed by explicit dimension, chosen by name.

Every sampler is a pure function of (seed, pixel, global sample index, dimension), so an image is
the same whatever the threads and tiles, and renders of disjoint ``sample_offset`` ranges merge
exactly. A kernel asks ``value, state = next_1d(state, dim)`` (or ``next_2d`` for dims dim, dim+1)
with the dimensions in increasing order; the integrators assign them (``integrators.common``).

* ``independent`` (:mod:`warp_spt.samplers.independent`): dimension d is the d-th draw of a PCG chain.
* ``sobol`` (:mod:`warp_spt.samplers.sobol`): Owen-scrambled Sobol' points per pixel.

A new sampler is one module with a ``make() -> Sampler`` function plus one line in ``SAMPLERS``.
"""

from __future__ import annotations

from dataclasses import dataclass

import warp as wp

from warp_spt.runtime import kernel_cache


@wp.struct
class SamplerState:
    """Where a path is in its sample: which sample, and (independent sampler) its PCG chain."""

    seed: wp.uint32
    pixel: int
    index: int          # global sample index
    rng: wp.uint32      # independent: the chain's state after draw ``next_dim - 1``; sobol: the pixel key
    next_dim: int


@dataclass(frozen=True)
class Sampler:
    """A sampler's three Warp functions: ``start(seed, pixel, index) -> state``,
    ``next_1d(state, dim) -> (float, state)``, ``next_2d(state, dim) -> (vec2, state)``."""

    name: str
    start: object
    next_1d: object
    next_2d: object
    random_access: bool = False    # any dimension costs the same, so unused ones are simply not drawn


@wp.func
def sampler_state(seed: wp.uint32, pixel: int, index: int, rng: wp.uint32) -> SamplerState:
    """A sampler's state at the start of a sample (dimension 0), with its own ``rng`` word."""
    st = SamplerState()
    st.seed = seed
    st.pixel = pixel
    st.index = index
    st.rng = rng
    st.next_dim = 0
    return st


def detach_requests(next_1d, next_2d) -> None:
    """Give a sampler's requests zero adjoints: their numbers depend on integers only (seed, pixel,
    sample, dimension), so no derivative flows through them. Without this, Warp's adjoint of a
    request re-runs its forward and then its callees' adjoints, each re-running their own forwards
    (a Sobol' request's hashes several times per differentiated vertex)."""
    from warp_spt.core.adjoint import zero_adjoint

    zero_adjoint(next_1d, (float, SamplerState))
    zero_adjoint(next_2d, (wp.vec2, SamplerState))


# The samplers' modules use the types above: imported after them.
from warp_spt.samplers import independent, sobol  # noqa: E402

SAMPLERS = {
    "independent": independent.make,
    "sobol": sobol.make,
}
# sobol: on bench_light's Cornell box, nee + sobol reaches a given whole-image error sooner than
# nee + independent at 256^2 and 512^2 (README, "Speed and accuracy").
DEFAULT_SAMPLER = "sobol"


def check_sampler(name: str) -> None:
    """Raise ValueError unless ``name`` is a registered sampler."""
    if name not in SAMPLERS:
        raise ValueError(f"unknown sampler {name!r}; choose from {', '.join(sorted(SAMPLERS))}")


def get_sampler(name: str) -> Sampler:
    """The sampler registered as ``name`` (built once per process, in the kernel cache)."""
    check_sampler(name)
    return kernel_cache.cached("sampler", name, SAMPLERS[name])
