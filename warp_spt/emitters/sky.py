"""The sky: an infinite light, constant or linear in the height of a direction along an up axis.

It is seen by every ray that misses the scene (``le``), and sampled with a density proportional to
its RGB sum, (a + b z) / (4 pi a) (uniform for a constant sky); its choice weight is that of a
sphere of the scene's radius seen from inside, radiating the mean radiance.

Its colours (``scene.sky.Sky.colour_fields``: the constant sky's ``color``; the gradient sky's
``zenith`` and ``nadir``) are the rows of ``SkyLight.colors``, float64 as the host holds them: they
are the sky's differentiable parameters, whose gradient a backward pass reads from that array's
``.grad`` (``table.alias_parameters``), as for a material colour. The radiance is computed from them
in float64 and rounded once to float32, exactly as the host rounded the gradient's mean and slope
before they were device arrays: images are bit-identical to that.

``sky_radiance``, ``sky_pdf`` and ``sample_sky`` take the whole light table (generic, ``Any``: this
module cannot name ``table.Lights``, which is built from the registry that lists it) and read
``lights.sky.<field>`` in place. Passed ``lights.sky`` by value instead, each call copied the struct
and its adjoint added a whole SkyLight adjoint back into the table's, field by field: path replay's
backward was 3-4% slower than with the seed's flat struct.

(No ``from __future__ import annotations`` here: ``make``'s functions are annotated with the
``Lights`` struct it is given, which Warp must see as an object, not as a string.)
"""

from types import SimpleNamespace
from typing import Any

import numpy as np
import warp as wp

from warp_spt.device.structs import Features, Geometry
from warp_spt.accel.ray_queries import KIND_MISS, NO_HIT
from warp_spt.emitters.base import LightKind, LightSample, Weighed
from warp_spt.device.sampling import TWO_PI
from warp_spt.scene.model import Scene
from warp_spt.scene.sky import SKY_GRADIENT, Sky

INV_FOUR_PI = wp.constant(0.07957747154594767)


@wp.struct
class SkyLight:
    """The sky on the device: its colours, its sampling density and its frame."""

    prob: float                                # choice probability (0: it does not emit)
    kind: int                                  # SKY_CONSTANT or SKY_GRADIENT
    colors: wp.array(dtype=wp.vec3d)           # rows: Sky.colour_fields() (constant: color; gradient: zenith, nadir)
    a: float                                   # sampling density is (a + b z) / (4 pi a)
    b: float
    up: wp.vec3                                # z above is the direction's component along up;
    t: wp.vec3                                 # (t, b_axis, up) is a right-handed frame,
    b_axis: wp.vec3                            # (1,0,0), (0,1,0), (0,0,1) for the seed's Z up


@wp.func
def sky_radiance(lights: Any, d: wp.vec3) -> wp.vec3:
    """The seed's skies: SKY_GRADIENT linear in the component along the up axis, from the nadir
    (z = -1) to the zenith (z = 1), as mean + slope * z with mean and slope rounded once from float64
    (the host's arithmetic, bit for bit); anything else a constant colour."""
    if lights.sky.kind == 1:
        zenith = lights.sky.colors[0]
        nadir = lights.sky.colors[1]
        mean = wp.vec3((zenith + nadir) * wp.float64(0.5))
        slope = wp.vec3((zenith - nadir) * wp.float64(0.5))
        z = wp.dot(d, lights.sky.up)           # exactly d[2] for Z up: the seed's images do not change
        return mean + slope * z
    return wp.vec3(lights.sky.colors[0])


@wp.func
def sky_pdf(lights: Any, d: wp.vec3) -> float:
    """Density of ``sample_sky`` (before the choice probability): proportional to the RGB sum."""
    return (lights.sky.a + lights.sky.b * wp.dot(d, lights.sky.up)) * INV_FOUR_PI / lights.sky.a


@wp.func
def sample_sky(lights: Any, u: wp.vec2) -> wp.vec3:
    """Invert the CDF of z for the density (a + b z) on [-1, 1]; uniform in azimuth around the up axis."""
    a = lights.sky.a
    b = lights.sky.b
    z = 2.0 * u[0] - 1.0
    if wp.abs(b) > 1.0e-6 * a:
        disc = a * a - 2.0 * b * (a - 0.5 * b - 2.0 * a * u[0])
        z = wp.clamp((wp.sqrt(wp.max(disc, 0.0)) - a) / b, -1.0, 1.0)
    r = wp.sqrt(wp.max(0.0, 1.0 - z * z))
    phi = TWO_PI * u[1]
    return lights.sky.t * (r * wp.cos(phi)) + lights.sky.b_axis * (r * wp.sin(phi)) + lights.sky.up * z


def make(Lights, features: Features):
    """``sample_li``, ``pdf_li`` and ``le`` of ``lights.sky``, inlined into the dispatch (``dispatch``):
    a call level of their own would copy the structs they take by value and, in an adjoint, re-run
    their forward once more (path replay's backward about 3% slower)."""

    @wp.func(inline=True)
    def sample_li(geo: Geometry, lights: Lights, entry: int, prob: float, x: wp.vec3, u: wp.vec2) -> LightSample:
        ls = LightSample()
        ls.dir = sample_sky(lights, u)
        ls.pdf = prob * sky_pdf(lights, ls.dir)
        ls.t_max = NO_HIT
        ls.h.kind = KIND_MISS
        return ls

    @wp.func(inline=True)
    def pdf_li(lights: Lights, d: wp.vec3) -> float:
        if lights.sky.prob > 0.0:
            return lights.sky.prob * sky_pdf(lights, d)
        return 0.0

    @wp.func(inline=True)
    def le(lights: Lights, d: wp.vec3) -> wp.vec3:
        return sky_radiance(lights, d)

    return SimpleNamespace(sample_li=sample_li, pdf_li=pdf_li, le=le)


# ---------------------------------------------------------------------------------------------
# Host side


def sky_emits(sky: Sky) -> bool:
    """Some colour of the sky (its constant or gradient part, ``Sky.colour_sky``) is above 0 (else it
    is not in the light table)."""
    part = sky.colour_sky()
    return part is not None and any(c > 0 for f in sky.colour_fields() for c in getattr(part, f))


def sky_terms(sky: Sky) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(colour or mean, slope) of the radiance colour + slope * z of the sky's constant or gradient part
    (black for an environment map alone)."""
    part = sky.colour_sky()
    if part is None:
        return (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)
    if part.kind == SKY_GRADIENT:
        return part.gradient_terms()
    return tuple(part.color), (0.0, 0.0, 0.0)


def sky_density(sky: Sky) -> tuple[float, float]:
    """(a, b) with the RGB sum of the sky's radiance = a + b z (the sampling density's shape); the
    seed's gradient sky gives exactly (2.6, -0.4)."""
    mean, slope = sky_terms(sky)
    return float(sum(mean)), float(sum(slope))


def sky_frame(up: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A right-handed orthonormal (t, b, up) around the unit ``up``: the identity for Z up."""
    u = np.asarray(up, dtype=np.float64)
    helper = np.array([0.0, 1.0, 0.0]) if abs(u[1]) < 0.9 else np.array([0.0, 0.0, 1.0])
    t = np.cross(helper, u)
    t /= np.linalg.norm(t)
    return t, np.cross(u, t), u


def weigh(scene: Scene, sky: Sky) -> Weighed:
    """One entry if the sky emits, weighed as a sphere of the scene's radius seen from inside (the
    subject's: a stage prop such as the studio's ground is left out)."""
    if not sky_emits(sky):
        return Weighed(np.zeros(0))
    b = scene.subject_bounds
    if not np.all(np.isfinite(b)):
        b = scene.bounds
    radius = 0.5 * float(np.linalg.norm(b[1] - b[0])) if np.all(np.isfinite(b)) else 1.0
    a, _ = sky_density(sky)
    return Weighed(np.array([4 * np.pi * max(radius, 1e-6) ** 2 * a / 3.0]))


def upload(payload, prob: np.ndarray, scene: Scene, sky: Sky, up, device: str) -> SkyLight:
    s = SkyLight()
    s.prob = float(prob[0]) if len(prob) else 0.0
    part = sky.colour_sky() or sky
    s.kind = int(part.kind)
    rows = [getattr(part, f) for f in sky.colour_fields()] or [(0.0, 0.0, 0.0)]   # a map alone: black here
    s.colors = wp.array(np.array(rows, dtype=np.float64), dtype=wp.vec3d, device=device)
    s.a, s.b = sky_density(sky) if len(prob) else (1.0, 0.0)
    if part is not sky and part.up is not None:     # a map's plus sky with an axis of its own
        up = part.up
    s.t, s.b_axis, s.up = (wp.vec3(*v.astype(np.float32).tolist()) for v in sky_frame(up))
    return s


def declare_sky(sky: Sky) -> frozenset:
    """"sky" where the sky emits (its ``le`` is compiled in whatever the features: a dark sky is black)."""
    return frozenset({"sky"} if sky_emits(sky) else ())


KIND = LightKind("sky", SkyLight, KIND_MISS, area=False, declare_sky=declare_sky, weigh=weigh,
                 upload=upload, make=make, cache=False, params="colors")
