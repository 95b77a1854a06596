"""The environment map: an infinite light whose radiance is an equirectangular float32 image
(``scene.environment``), times a strength, turned about the sky's up axis.

Sampling is importance sampling of the map: a piecewise-constant 2-D distribution over the
image's (u, v) square, a row from the marginal CDF and then a column from that row's conditional
CDF, uniformly within the texel, with weights luminance x sin(theta) (``scene.environment
.sampling_weights``). Its density in solid angle is p(u, v) / (2 pi^2 sin theta), looked up at the
nearest texel. MIS with BSDF sampling is the integrators' (``pdf_li`` is what a BSDF-sampled ray
that escapes is weighed with). Its choice weight in the light table is the sky's: a sphere of the
scene's radius seen from inside, radiating the map's mean radiance.

Its differentiable parameters are ``EnvLight.params``, (strength, rotation in degrees), named
``environment.strength`` and ``environment.rotate`` by ``diff.params``.

The functions take the whole light table (generic, ``Any``), reading ``lights.environment`` in
place, for the reason ``sky`` gives.

(No ``from __future__ import annotations`` here: ``make``'s functions are annotated with the
``Lights`` struct it is given, which Warp must see as an object, not as a string.)
"""

from types import SimpleNamespace
from typing import Any

import numpy as np
import warp as wp

from warp_spt.device.structs import Features, Geometry
from warp_spt.accel.ray_queries import KIND_MISS, NO_HIT
from warp_spt.emitters.base import LightKind, LightSample, Weighed, device_array
from warp_spt.emitters.sky import sky_frame
from warp_spt.device.sampling import TWO_PI
from warp_spt.scene.environment import distribution, mean_radiance, sampling_weights
from warp_spt.scene.model import Scene
from warp_spt.scene.sky import SKY_ENVIRONMENT, Sky

PI = wp.constant(3.141592653589793)
INV_TWO_PI_SQ = wp.constant(0.05066059182116889)     # 1 / (2 pi^2)
MIN_SIN_THETA = wp.constant(1e-7)    # env_pdf's floor: 2e-5 degrees; the density stays below 1e8 x a texel's


@wp.struct
class EnvLight:
    """The environment on the device: its texels (radiance, row 0 the zenith), its sampling
    distribution, its frame and rotation, and the background camera rays see."""

    prob: float                                 # choice probability (0: not in the table)
    width: int
    height: int
    texels: wp.array(dtype=wp.vec3)             # H x W, row by row
    params: wp.array(dtype=float)               # (strength, rotation in degrees): differentiable
    marginal: wp.array(dtype=float)             # H: cumulative row probabilities, last = 1
    conditional: wp.array(dtype=float)          # H x W: cumulative column probabilities per row
    density: wp.array(dtype=float)              # H x W: p(u, v) of each texel (mean 1)
    t: wp.vec3                                  # (t, b_axis, up): the sky's frame (sky.sky_frame)
    b_axis: wp.vec3
    up: wp.vec3
    background: wp.vec3
    has_background: int


@wp.func
def env_texel(lights: Any, d: wp.vec3) -> int:
    """The index of the texel that direction ``d`` (unit) falls in (nearest: no filtering)."""
    e = lights.environment
    z = wp.clamp(wp.dot(d, e.up), -1.0, 1.0)
    psi = wp.atan2(-wp.dot(d, e.t), -wp.dot(d, e.b_axis))      # azimuth as the map's u counts it
    u = psi / TWO_PI + e.params[1] / 360.0
    u = u - wp.floor(u)
    v = wp.acos(z) / PI
    col = wp.min(int(u * float(e.width)), e.width - 1)
    row = wp.min(int(v * float(e.height)), e.height - 1)
    return row * e.width + col


@wp.func
def env_radiance(lights: Any, d: wp.vec3) -> wp.vec3:
    """The map's radiance along ``d`` (unit), times its strength: linear between texel centres in
    azimuth, nearest in elevation. Linear in azimuth gives the rotation a derivative (a nearest
    lookup is a step function of it) and keeps each texel's integral over the sphere what it is
    with a nearest lookup (a tent spanning two columns holds as much as a box one column wide; cos
    theta depends on the row alone), so the sampling density's texels still match the radiance's."""
    e = lights.environment
    z = wp.clamp(wp.dot(d, e.up), -1.0, 1.0)
    psi = wp.atan2(-wp.dot(d, e.t), -wp.dot(d, e.b_axis))      # azimuth as the map's u counts it
    u = psi / TWO_PI + e.params[1] / 360.0
    u = u - wp.floor(u)
    x = u * float(e.width) - 0.5                # in column-centre units: column c's centre at c
    c0f = wp.floor(x)
    f = x - c0f
    c0 = int(c0f)
    c1 = c0 + 1
    if c0 < 0:
        c0 = e.width - 1
    if c1 >= e.width:
        c1 = 0
    row = wp.min(int(wp.acos(z) / PI * float(e.height)), e.height - 1)
    base = row * e.width
    return (e.texels[base + c0] * (1.0 - f) + e.texels[base + c1] * f) * e.params[0]


@wp.func
def env_pdf(lights: Any, d: wp.vec3) -> float:
    """Density in solid angle of ``sample_env`` (before the choice probability)."""
    e = lights.environment
    # sin theta from the direction's part across the up axis, not sqrt(1 - z^2): within about 0.02
    # degrees of a pole 1 - z^2 rounds to 0 in float32, the density read 0 there, and a BSDF-sampled
    # ray escaping to a bright pole took the whole MIS weight (one pixel of 622 among neighbours of 6)
    across = wp.vec2(wp.dot(d, e.t), wp.dot(d, e.b_axis))
    # At the pole itself (a cosine-sampled BSDF direction along the normal, u = 0 exactly: the first
    # sample of a Sobol' sequence) sin theta is 0 and the density, which grows as 1 / sin theta, read
    # 0: the ray took the whole MIS weight, the sun's radiance in one sample (one pixel of 47 among
    # neighbours of 3.9 at 2048 spp). Within MIN_SIN_THETA of a pole it is taken as that far: finite,
    # and far above any BSDF's density, so MIS leaves that point to light sampling, as around it.
    sin_theta = wp.max(wp.length(across), MIN_SIN_THETA)
    return e.density[env_texel(lights, d)] * INV_TWO_PI_SQ / sin_theta


@wp.func
def _search(cdf: wp.array(dtype=float), first: int, count: int, u: float) -> int:
    """The first index k in [0, count) with cdf[first + k] > u (the last if none)."""
    lo = int(0)
    hi = count - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if cdf[first + mid] > u:
            hi = mid
        else:
            lo = mid + 1
    return lo


@wp.func
def _within(cdf: wp.array(dtype=float), first: int, k: int, u: float) -> float:
    """Where ``u`` lies within bin ``k`` of the CDF at ``first``, in [0, 1)."""
    lo = float(0.0)
    if k > 0:
        lo = cdf[first + k - 1]
    width = cdf[first + k] - lo
    if width <= 0.0:
        return 0.5
    return wp.clamp((u - lo) / width, 0.0, 0.99999994)


@wp.func
def sample_env(lights: Any, u: wp.vec2) -> wp.vec4:
    """A direction (xyz) drawn from the map's distribution with ``u``, and its density in solid
    angle (w, before the choice probability): the density ``env_pdf`` gives that direction, as MIS
    weighs a BSDF-sampled ray with."""
    e = lights.environment
    row = _search(e.marginal, 0, e.height, u[0])
    fv = _within(e.marginal, 0, row, u[0])
    col = _search(e.conditional, row * e.width, e.width, u[1])
    fu = _within(e.conditional, row * e.width, col, u[1])
    theta = PI * (float(row) + fv) / float(e.height)
    psi = TWO_PI * ((float(col) + fu) / float(e.width) - e.params[1] / 360.0)
    st = wp.sin(theta)
    d = e.t * (-st * wp.sin(psi)) - e.b_axis * (st * wp.cos(psi)) + e.up * wp.cos(theta)
    # The density of the texel the direction is looked up in (env_texel), which gives its radiance
    # too, not of the texel drawn: a draw at a texel's edge (u exactly a CDF value, fv = 0, about one
    # in 2^24; or one the float32 trigonometry moves across) was looked up in its bright neighbour
    # and divided by its own dim density: a sun's row over the sky's gave one sample 19,000 times the
    # mean (one pixel of 47 among neighbours of 3.9 at 2048 spp)
    return wp.vec4(d[0], d[1], d[2], env_pdf(lights, d))


def make(Lights, features: Features):
    """``sample_li``, ``pdf_li``, ``le`` and ``seen`` (what a camera ray that misses sees: the
    background if one is set) of ``lights.environment``, inlined into the dispatch."""

    @wp.func(inline=True)
    def sample_li(geo: Geometry, lights: Lights, entry: int, prob: float, x: wp.vec3, u: wp.vec2) -> LightSample:
        ls = LightSample()
        s = sample_env(lights, u)
        ls.dir = wp.vec3(s[0], s[1], s[2])
        ls.pdf = prob * s[3]
        ls.t_max = NO_HIT
        ls.h.kind = KIND_MISS
        return ls

    @wp.func(inline=True)
    def pdf_li(lights: Lights, d: wp.vec3) -> float:
        if lights.environment.prob > 0.0:
            return lights.environment.prob * env_pdf(lights, d)
        return 0.0

    @wp.func(inline=True)
    def le(lights: Lights, d: wp.vec3) -> wp.vec3:
        return env_radiance(lights, d)

    @wp.func(inline=True)
    def seen(lights: Lights, d: wp.vec3, le_all: wp.vec3) -> wp.vec3:
        if lights.environment.has_background != 0:
            return lights.environment.background
        return le_all

    return SimpleNamespace(sample_li=sample_li, pdf_li=pdf_li, le=le, seen=seen)


# ---------------------------------------------------------------------------------------------
# Host side


def environment_emits(sky: Sky) -> bool:
    """The sky is an environment map with some light in it."""
    return (sky.kind == SKY_ENVIRONMENT and sky.strength > 0.0
            and float(sky.env.image.max(initial=0.0)) > 0.0)


def weigh(scene: Scene, sky: Sky) -> Weighed:
    """One entry if the map emits, weighed as the sky is (a sphere of the scene's radius seen from
    inside, radiating the map's mean radiance); the payload is its sampling distribution."""
    if not environment_emits(sky):
        return Weighed(np.zeros(0))
    b = scene.bounds
    radius = 0.5 * float(np.linalg.norm(b[1] - b[0])) if np.all(np.isfinite(b)) else 1.0
    a = float(mean_radiance(sky.env.image).sum()) * sky.strength
    img = sky.env.image
    return Weighed(np.array([4 * np.pi * max(radius, 1e-6) ** 2 * a / 3.0]),
                   distribution(sampling_weights(img, sky.env.sampling)))


def upload(payload, prob: np.ndarray, scene: Scene, sky: Sky, up, device: str) -> EnvLight:
    e = EnvLight()
    e.prob = float(prob[0]) if len(prob) else 0.0
    env = sky.env if sky.kind == SKY_ENVIRONMENT else None
    if env is None:
        e.width = e.height = 1
        texels = np.zeros((1, 3), np.float32)
        marginal = cond = density = np.ones(1)
    else:
        e.width, e.height = env.width, env.height
        texels = env.image.reshape(-1, 3)
        if payload is None:     # a black map: never sampled, still seen
            payload = (np.ones(env.height), np.ones((env.height, env.width)), np.zeros((env.height, env.width)))
        marginal, cond, density = payload
    e.texels = device_array(texels, wp.vec3, np.float32, device)
    e.marginal = device_array(np.ravel(marginal), float, np.float32, device)
    e.conditional = device_array(np.ravel(cond), float, np.float32, device)
    e.density = device_array(np.ravel(density), float, np.float32, device)
    strength = float(sky.strength) if env is not None else 0.0
    e.params = wp.array(np.array([strength, sky.rotate % 360.0], dtype=np.float32), dtype=float, device=device)
    e.t, e.b_axis, e.up = (wp.vec3(*v.astype(np.float32).tolist()) for v in sky_frame(up))
    bg = sky.background
    e.has_background = int(bg is not None)
    e.background = wp.vec3(*(bg if bg is not None else (0.0, 0.0, 0.0)))
    return e


def declare_sky(sky: Sky) -> frozenset:
    """"environment.seen" where the sky is a map (its code is compiled in: rays that miss see it),
    "environment" where the map emits (it is in the light table)."""
    if sky.kind != SKY_ENVIRONMENT:
        return frozenset()
    return frozenset({"environment.seen", "environment"} if environment_emits(sky) else {"environment.seen"})


KIND = LightKind("environment", EnvLight, KIND_MISS, area=False, declare_sky=declare_sky,
                 sampled=lambda f: f.lit("environment") and f.lit("environment.seen"),
                 weigh=weigh, upload=upload, make=make, cache=False, params="params",
                 present=lambda f: f.lit("environment.seen"))
