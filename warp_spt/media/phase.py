"""The Henyey-Greenstein phase function: value, density and sampling (pure Warp functions).

Directions are propagation directions along the path (the camera's ray ``d`` turning into ``d_new``);
the density depends on their cosine alone and is the same for light running the other way. g > 0
scatters forward: the density peaks at d_new = d.
"""

from __future__ import annotations

import warp as wp

from warp_spt.device.sampling import orthonormal_basis

INV_FOUR_PI = wp.constant(0.07957747154594767)


@wp.func
def hg(cos_theta: float, g: float) -> float:
    """p(cos theta) of the angle between the propagation directions before and after scattering."""
    den = 1.0 + g * g - 2.0 * g * cos_theta
    return INV_FOUR_PI * (1.0 - g * g) / (den * wp.sqrt(wp.max(den, 1.0e-12)))


@wp.func
def hg_eval(d: wp.vec3, d_new: wp.vec3, g: float) -> float:
    """Density (= value) of turning a ray travelling along ``d`` into ``d_new`` (both unit)."""
    return hg(wp.dot(d, d_new), g)


@wp.func
def hg_cos(g: float, u: float) -> float:
    """The cosine between the old and new propagation directions, by inverting HG's CDF."""
    if wp.abs(g) < 1.0e-3:
        return 1.0 - 2.0 * u
    s = (1.0 - g * g) / (1.0 + g - 2.0 * g * u)
    return wp.clamp((1.0 + g * g - s * s) / (2.0 * g), -1.0, 1.0)


@wp.func
def hg_sample(d: wp.vec3, g: float, u: wp.vec2) -> wp.vec3:
    """A new propagation direction for a ray travelling along unit ``d``; its density is
    ``hg(dot(d, new), g)``."""
    c = hg_cos(g, u[0])
    s = wp.sqrt(wp.max(0.0, 1.0 - c * c))
    phi = 6.283185307179586 * u[1]
    t, b = orthonormal_basis(d)
    return wp.normalize(t * (s * wp.cos(phi)) + b * (s * wp.sin(phi)) + d * c)
