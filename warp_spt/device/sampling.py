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


@wp.func
def triangle_solid_angle(p0: wp.vec3, p1: wp.vec3, p2: wp.vec3, x: wp.vec3) -> float:
    """Solid angle of the triangle seen from x (Van Oosterom-Strackee: tan(omega/2) =
    |e0 . (e1 x e2)| / (l0 l1 l2 + (e0.e1) l2 + (e1.e2) l0 + (e2.e0) l1) with e_i = p_i - x, l_i = |e_i|).
    The triple product is taken as e0 . ((p1 - p0) x (p2 - p0)), from the triangle's own edges: well
    conditioned for a small or distant triangle, where the three e_i are nearly parallel."""
    num, den = solid_angle_terms(p0, p1, p2, x)
    return wp.abs(2.0 * wp.atan2(num, den))


@wp.func
def solid_angle_terms(p0: wp.vec3, p1: wp.vec3, p2: wp.vec3, x: wp.vec3):
    """(num, den) of :func:`triangle_solid_angle`: the triangle subtends ``|2 atan2(num, den)|``. A
    caller that only compares the angle with a threshold can often decide from the ratio of the two
    without the arctangent (``lights.triangle.sampled_solid_angle``)."""
    e0 = p0 - x
    e1 = p1 - x
    e2 = p2 - x
    l0 = wp.length(e0)
    l1 = wp.length(e1)
    l2 = wp.length(e2)
    num = wp.dot(e0, wp.cross(p1 - p0, p2 - p0))
    den = l0 * l1 * l2 + wp.dot(e0, e1) * l2 + wp.dot(e1, e2) * l0 + wp.dot(e2, e0) * l1
    return num, den


@wp.func
def _away_from(v: wp.vec3d, w: wp.vec3d) -> wp.vec3d:
    """The unit vector of v's part orthogonal to the unit vector w (one Gram-Schmidt step)."""
    return wp.normalize(v - w * wp.dot(v, w))


@wp.func
def spherical_triangle_sample(a32: wp.vec3, b32: wp.vec3, c32: wp.vec3, area: float, u: wp.vec2) -> wp.vec3:
    """A direction distributed uniformly over the spherical triangle of the unit vectors a, b, c,
    whose area (solid angle, ``triangle_solid_angle``) is ``area``.

    Arvo's area-preserving map (SIGGRAPH 1995), written from the paper's derivation: ``u[0]``
    chooses the area of the sub-triangle (a, b, c') with c' on the arc a-c, which fixes c';
    ``u[1]`` then chooses a point on the arc from b to c' with the density that makes the result
    uniform (cos theta linear in u). Only the angle alpha at a is needed, and it is taken from the
    arcs' plane normals without inverse trigonometry. Computed in float64: in float32 the sine of the
    arc a-c', taken from its cosine near 1, was off by up to 3e-4 rad and moved samples across a
    shared edge onto the neighbouring triangle. Returns the zero vector for a degenerate triangle.
    """
    one = wp.float64(1.0)
    zero = wp.float64(0.0)
    a = wp.vec3d(a32)
    b = wp.vec3d(b32)
    c = wp.vec3d(c32)
    n_ab = wp.cross(a, b)
    n_ca = wp.cross(c, a)
    if wp.length_sq(n_ab) <= zero or wp.length_sq(n_ca) <= zero:
        return wp.vec3(0.0, 0.0, 0.0)
    n_ab = wp.normalize(n_ab)
    n_ca = wp.normalize(n_ca)
    cos_alpha = -wp.dot(n_ab, n_ca)              # the triangle's angle at a, between the arcs a-b and a-c
    sin_alpha = wp.length(wp.cross(n_ab, n_ca))
    sub = wp.float64(u[0]) * wp.float64(area)    # the sub-triangle's area: its angle sum is pi + sub
    sin_s = wp.sin(sub)
    cos_s = wp.cos(sub)
    sin_phi = cos_s * sin_alpha - sin_s * cos_alpha      # phi = pi + sub - alpha
    cos_phi = -cos_s * cos_alpha - sin_s * sin_alpha
    k1 = cos_phi + cos_alpha
    k2 = sin_phi - sin_alpha * wp.dot(a, b)
    den = (k2 * sin_phi + k1 * cos_phi) * sin_alpha
    cos_b = one
    if den != zero:
        cos_b = wp.clamp((k2 + (k2 * cos_phi - k1 * sin_phi) * cos_alpha) / den, -one, one)
    sin_b = wp.sqrt(wp.max(zero, one - cos_b * cos_b))
    c_sub = a * cos_b + _away_from(c, a) * sin_b          # c' on the arc from a to c
    cb = wp.dot(c_sub, b)
    if cb >= one:
        return b32
    cos_t = one - wp.float64(u[1]) * (one - cb)
    sin_t = wp.sqrt(wp.max(zero, one - cos_t * cos_t))
    return wp.vec3(wp.normalize(b * cos_t + _away_from(c_sub, b) * sin_t))
