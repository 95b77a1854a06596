"""The seed's estimator: pure path tracing. A light is found only by bouncing into it.

Emission counts in full wherever a path meets it; the sky counts on a miss. Four dimensions per
bounce (lobe, direction, Fresnel), exactly the draws of the renderer before the restructure, so
with the independent sampler its images are bit-identical to it (tests/integrators/test_seed_baseline.py).
It is the NEE step with light sampling (and roulette) compiled out: MIS weights are then exactly 1.
"""

from __future__ import annotations

from warp_spt.device.structs import Features
from warp_spt.integrators.common import SEED_STRIDE, Integrator
from warp_spt.integrators.nee import make_path_step, make_path_vertex
from warp_spt.samplers import Sampler


def make(features: Features, sampler: Sampler, differentiable: bool = False):
    """The bounce step of pure path tracing for scenes with these features."""
    return make_path_step(features, sampler, light_sampling=False, differentiable=differentiable)


def make_vertex(features: Features, sampler: Sampler, inline: bool | None = None, pathwise: bool = False):
    """The vertex of pure path tracing (``nee.make_path_vertex``): what path replay differentiates
    (``pathwise``: with every derivative the tape's has, for ``diff.replay_pathwise``)."""
    return make_path_vertex(features, sampler, light_sampling=False, inline=inline, replay=not pathwise,
                            differentiable=pathwise)


INTEGRATOR = Integrator("seed", make, make_vertex, SEED_STRIDE, pathwise=True,
                        summary="the seed's pure path tracing: lights are found only by bouncing into them")
