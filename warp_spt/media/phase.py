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
    # 1 + g^2 - 2 g cos written as a sum of two terms >= 0: in float32 the plain form cancels to 0 or
    # below near the peak once |g| > 0.999 (g = 0.999999 gave NaN samples)
    # and the cosine clamped to [-1, 1]: a dot product of two unit vectors an ulp above 1 made the
    # second term negative and larger than the first near |g| = 1 (the square root of a negative)
    a = wp.abs(g)
    c = wp.clamp(cos_theta, -1.0, 1.0)
    if g < 0.0:
        c = -c
    den = (1.0 - a) * (1.0 - a) + 2.0 * a * (1.0 - c)
    return INV_FOUR_PI * (1.0 - a) * (1.0 + a) / (den * wp.sqrt(den))


@wp.func
def hg_eval(d: wp.vec3, d_new: wp.vec3, g: float) -> float:
    """Density (= value) of turning a ray travelling along ``d`` into ``d_new`` (both unit)."""
    return hg(wp.dot(d, d_new), g)


@wp.func
def hg_cos(g: float, u: float) -> float:
    """The cosine between the old and new propagation directions, by inverting HG's CDF."""
    if wp.abs(g) < 1.0e-3:
        return 1.0 - 2.0 * u
    # 1 + g - 2 g u as (1 - g) + 2 g (1 - u): no cancellation as g nears 1 and u nears 1 (nor, for g
    # near -1, as u nears 0: (1 + g) - 2 g u with both terms >= 0)
    den = (1.0 - g) + 2.0 * g * (1.0 - u)
    if g < 0.0:
        den = (1.0 + g) - 2.0 * g * u
    s = (1.0 - g) * (1.0 + g) / den
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
