"""The independent sampler: dimension d of a sample is the d-th draw of one PCG chain.

The chain starts at ``sampling.stream_state(seed, pixel, index)``. Skipping dimensions advances the
chain, so with the seed integrator's dimensions (2 pixel, 2 lens, then 4 per bounce, consecutive)
the numbers are the very draws of the renderer before the restructure: its images are bit-identical.
"""

from __future__ import annotations

import warp as wp

from warp_spt.device.sampling import stream_state
from warp_spt.samplers.base import Sampler, SamplerState, detach_requests, sampler_state


@wp.func
def start(seed: wp.uint32, pixel: int, index: int) -> SamplerState:
    return sampler_state(seed, pixel, index, stream_state(seed, pixel, index))


def make() -> Sampler:
    """The independent sampler's record."""

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

    detach_requests(next_1d, next_2d)
    return Sampler("independent", start, next_1d, next_2d, summary="independent PCG streams per pixel and sample")
