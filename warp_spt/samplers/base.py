"""The sampler record and the state a sampler carries through a path (see :mod:`warp_spt.samplers`)."""

from __future__ import annotations

from dataclasses import dataclass

import warp as wp


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
    ``next_1d(state, dim) -> (float, state)``, ``next_2d(state, dim) -> (vec2, state)``.

    ``make_batch`` (optional, random-access samplers whose ``next_1d(d)`` is ``next_2d(d)``'s x):
    ``make_batch(offsets) -> batch``, ``batch(state, base) -> vector`` of ``2 * lanes`` floats
    (``lanes = batch_lanes(len(offsets))``): entry k and entry ``lanes + k`` are ``next_2d(state, base +
    offsets[k])``'s x and y, bit for bit, all computed in one call (a vertex's requests as the lanes
    of one batch). Forward kernels only: it has no adjoint."""

    name: str
    start: object
    next_1d: object
    next_2d: object
    random_access: bool = False    # any dimension costs the same, so unused ones are simply not drawn
    summary: str = ""              # one line for --help and the docs
    make_batch: object = None


def batch_lanes(n: int) -> int:
    """The lanes of a batch of ``n`` requests: a power of two (at least 2), which clang's vectoriser
    packs whole into vector registers."""
    return 1 << max(1, (n - 1).bit_length())


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
    from warp_spt.device.adjoint import zero_adjoint

    zero_adjoint(next_1d, (float, SamplerState))
    zero_adjoint(next_2d, (wp.vec2, SamplerState))
