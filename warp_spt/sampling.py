"""Random numbers and direction sampling as Warp functions (no state hidden in functions).

Random draws happen in the kernel body, where ``wp.randf(state)`` advances a local state; the
functions here take the uniform numbers they need as arguments, so they are pure and differentiable.
"""

from __future__ import annotations

import warp as wp

TWO_PI = wp.constant(6.283185307179586)
# Unsigned constants above 2**31 must be typed as such, or the generated C++ narrows them.
_PCG_MUL = wp.constant(wp.uint32(747796405))
_PCG_INC = wp.constant(wp.uint32(2891336453))
_PCG_OUT = wp.constant(wp.uint32(277803737))
_GOLDEN = wp.constant(wp.uint32(2654435769))
_SALT = wp.constant(wp.uint32(1663821227))


@wp.func
def hash_u32(v: wp.uint32) -> wp.uint32:
    """A PCG-style integer hash (permuted congruential step, then an xorshift-multiply output)."""
    s = v * _PCG_MUL + _PCG_INC
    w = ((s >> ((s >> wp.uint32(28)) + wp.uint32(4))) ^ s) * _PCG_OUT
    return (w >> wp.uint32(22)) ^ w


@wp.func
def stream_state(seed: wp.uint32, pixel: int, sample: int) -> wp.uint32:
    """The start state of the random stream for one (pixel, sample): a pure function of the three,
    so an image is the same whatever the tiling, thread count or split of samples across runs."""
    h = hash_u32(seed ^ _GOLDEN)
    h = hash_u32(h + wp.uint32(pixel))
    return hash_u32(h ^ hash_u32(wp.uint32(sample) + _SALT))


@wp.func
def orthonormal_basis(n: wp.vec3):
    """Two unit tangents completing n to a right-handed frame, continuous except at n.z = -1."""
    sign = wp.where(n[2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    t = wp.vec3(1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0])
    bt = wp.vec3(b, sign + n[1] * n[1] * a, -n[1])
    return t, bt


@wp.func
def cosine_hemisphere(n: wp.vec3, u1: float, u2: float) -> wp.vec3:
    """A direction about n with density cos(theta)/pi (Malley's method: a disk point lifted up)."""
    r = wp.sqrt(u1)
    phi = TWO_PI * u2
    t, b = orthonormal_basis(n)
    z = wp.sqrt(wp.max(0.0, 1.0 - u1))
    return wp.normalize(t * (r * wp.cos(phi)) + b * (r * wp.sin(phi)) + n * z)


@wp.func
def uniform_sphere(u1: float, u2: float) -> wp.vec3:
    """A uniformly distributed unit vector (the seed's cube-projected vector was not uniform)."""
    z = 1.0 - 2.0 * u1
    r = wp.sqrt(wp.max(0.0, 1.0 - z * z))
    phi = TWO_PI * u2
    return wp.vec3(r * wp.cos(phi), r * wp.sin(phi), z)


@wp.func
def concentric_disk(u1: float, u2: float) -> wp.vec2:
    """Square to unit disk preserving area and adjacency (Shirley-Chiu concentric map)."""
    a = 2.0 * u1 - 1.0
    b = 2.0 * u2 - 1.0
    if a == 0.0 and b == 0.0:
        return wp.vec2(0.0, 0.0)
    r = float(0.0)
    phi = float(0.0)
    if wp.abs(a) > wp.abs(b):
        r = a
        phi = 0.7853981633974483 * (b / a)
    else:
        r = b
        phi = 1.5707963267948966 - 0.7853981633974483 * (a / b)
    return wp.vec2(r * wp.cos(phi), r * wp.sin(phi))
