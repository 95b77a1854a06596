"""Samplers: the uniform numbers of a path, addressed by explicit dimension, chosen by name.

Every sampler is a pure function of (seed, pixel, global sample index, dimension), so an image is
the same whatever the threads and tiles, and renders of disjoint ``sample_offset`` ranges merge
exactly. A kernel asks ``value, state = next_1d(state, dim)`` (or ``next_2d`` for dims dim, dim+1)
with the dimensions in increasing order; the integrators assign them (``integrators.common``).

* ``independent``: dimension d is the d-th draw of the PCG chain started by
  ``sampling.stream_state(seed, pixel, index)``. Skipping dimensions advances the chain, so with the
  seed integrator's dimensions (2 pixel, 2 lens, then 4 per bounce, consecutive) the numbers are the
  very draws of the renderer before the restructure: its images are bit-identical.
* ``sobol``: Owen-scrambled Sobol' points per pixel (``warp_spt.samplers.sobol``), registered when present.

A new sampler is a ``make_*`` function returning :class:`Sampler` plus one registry line.
"""

from __future__ import annotations

from dataclasses import dataclass

import warp as wp

from warp_spt.core.sampling import stream_state


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
def _state(seed: wp.uint32, pixel: int, index: int, rng: wp.uint32) -> SamplerState:
    st = SamplerState()
    st.seed = seed
    st.pixel = pixel
    st.index = index
    st.rng = rng
    st.next_dim = 0
    return st


@wp.func
def _start(seed: wp.uint32, pixel: int, index: int) -> SamplerState:
    return _state(seed, pixel, index, stream_state(seed, pixel, index))


def _detach(next_1d, next_2d) -> None:
    """Give a sampler's requests zero adjoints: their numbers depend on integers only (seed, pixel,
    sample, dimension), so no derivative flows through them. Without this, Warp's adjoint of a
    request re-runs its forward and then its callees' adjoints, each re-running their own forwards
    (a Sobol' request's hashes several times per differentiated vertex); only the differentiable
    kernels (tape, path replay) have adjoint code, so the fast kernels do not change."""

    @wp.func_grad(next_1d)
    def adj_next_1d(state: SamplerState, dim: int, adj_ret_0: float, adj_ret_1: SamplerState):
        pass

    @wp.func_grad(next_2d)
    def adj_next_2d(state: SamplerState, dim: int, adj_ret_0: wp.vec2, adj_ret_1: SamplerState):
        pass


def make_independent() -> Sampler:
    @wp.func
    def next_1d(state: SamplerState, dim: int):
        """The ``dim``-th draw of the chain (dims below ``next_dim`` are gone: callers go in order)."""
        st = state
        rng = st.rng
        n = st.next_dim
        while n < dim:            # skipped dimensions still advance the chain
            wp.randf(rng)
            n += 1
        v = wp.randf(rng)
        st.rng = rng
        st.next_dim = n + 1
        return v, st

    @wp.func
    def next_2d(state: SamplerState, dim: int):
        a, s1 = next_1d(state, dim)
        b, s2 = next_1d(s1, dim + 1)
        return wp.vec2(a, b), s2

    _detach(next_1d, next_2d)
    return Sampler("independent", _start, next_1d, next_2d)


def _make_sobol() -> Sampler:
    from warp_spt.samplers.sobol import pixel_key, sobol_1d_keyed, sobol_2d_keyed

    @wp.func
    def start(seed: wp.uint32, pixel: int, index: int) -> SamplerState:
        return _state(seed, pixel, index, pixel_key(seed, pixel))   # the requests' shared key part, no PCG chain

    @wp.func
    def next_1d(state: SamplerState, dim: int):
        return sobol_1d_keyed(state.rng, state.index, dim), state

    @wp.func
    def next_2d(state: SamplerState, dim: int):
        return sobol_2d_keyed(state.rng, state.index, dim), state

    _detach(next_1d, next_2d)
    return Sampler("sobol", start, next_1d, next_2d, random_access=True)


def _sobol_available() -> bool:
    from importlib.util import find_spec
    return find_spec(__package__ + ".sobol") is not None


SAMPLERS = {"independent": make_independent}
if _sobol_available():
    SAMPLERS["sobol"] = _make_sobol

# sobol: on bench_light's Cornell box, nee + sobol reaches a given whole-image error sooner than
# nee + independent at 256^2 and 512^2 (README, "Speed and accuracy"); independent is the fallback
# when the sobol module is absent.
DEFAULT_SAMPLER = "sobol" if "sobol" in SAMPLERS else "independent"
_built: dict[str, Sampler] = {}


def get_sampler(name: str) -> Sampler:
    """The sampler registered as ``name`` (built once per process)."""
    if name not in SAMPLERS:
        raise ValueError(f"unknown sampler {name!r}; choose from {', '.join(sorted(SAMPLERS))}")
    if name not in _built:
        _built[name] = SAMPLERS[name]()
    return _built[name]
