"""The integrator x sampler pairs of the tests that check every pair.

Each pair compiles a kernel of its own (15 today), which made these tests a fifth of the default
tier's time. The default tier runs a covering set, every integrator and every sampler at least once
and the default pair among them (as the CUDA compile test chooses its representative set); the
other pairs are marked ``slow``, so CI still runs every pair (tests/conftest.py's tiers).
"""

from __future__ import annotations

import pytest

from warp_spt.integrators import DEFAULT_INTEGRATOR, INTEGRATORS
from warp_spt.samplers import DEFAULT_SAMPLER, SAMPLERS


def covering() -> set[tuple[str, str]]:
    """Every integrator with a sampler taken in turn, the default integrator with the default sampler
    and with any sampler left over."""
    integrators = [DEFAULT_INTEGRATOR] + sorted(i for i in INTEGRATORS if i != DEFAULT_INTEGRATOR)
    samplers = [DEFAULT_SAMPLER] + sorted(s for s in SAMPLERS if s != DEFAULT_SAMPLER)
    chosen = {(i, samplers[k % len(samplers)]) for k, i in enumerate(integrators)}
    return chosen | {(DEFAULT_INTEGRATOR, s) for s in samplers[len(integrators):]}


def every_pair(*extra) -> list:
    """``pytest.param(integrator, sampler, *extra)`` for every pair, sorted; those outside
    :func:`covering` in the slow tier."""
    cover = covering()
    return [pytest.param(i, s, *extra, marks=() if (i, s) in cover else pytest.mark.slow)
            for i in sorted(INTEGRATORS) for s in sorted(SAMPLERS)]
