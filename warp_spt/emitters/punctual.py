"""Punctual lights: the sun (directional), point and spot lights (host records: ``scene.lights``).

None of them is ever hit by a ray, so they are *delta* lights in the sense of MIS: only light
sampling reaches them, its estimate gets the weight 1, and a BSDF sample adds nothing for them
(``LightKind.delta``; the integrators test the sample's hit kind, ``KIND_PUNCTUAL``). A sun with an
angular radius above 0 is sampled uniformly over its cone of directions with the radiance that gives
the stated irradiance; it too is left out of what a missing ray sees (as the delta sun), which keeps
its whole contribution on the one technique that finds it.

* ``sample_li``: the direction to the light; density the choice probability (a delta light), or
  that over the cone's solid angle (the sun with a radius); the shadow ray stops just short of a
  point light and runs a long way towards the sun.
* ``radiance`` (the differentiable half, ``le`` of the dispatch): what arrives at ``x``:
  ``intensity / r^2`` (times the spot's falloff), the sun's irradiance (delta) or its radiance.

Per light (``light`` maps table entries to lights; a black light is in no entry): its type, two rows
of ``vecs`` (position or the direction towards the sun; intensity or irradiance), the differentiable
parameters, whose rows ``diff.params`` names; ``axis`` (a spot's) and ``cone`` (the sun: cos r,
1 - cos r, sin^2 r; a spot: cos outer, the falloff's scale).

Choice weight: the power, mean over RGB: 4 pi I for a point light, 2 pi ((1 - cos inner) +
(cos inner - cos outer) / 3) I for a spot (the integral of its falloff), and for the sun, as pbrt,
its irradiance times the area of the disc of the scene's bounding sphere.

(No ``from __future__ import annotations`` here: ``make``'s functions are annotated with the
``Lights`` struct it is given, which Warp must see as an object, not as a string.)
"""

import math
from types import SimpleNamespace

import numpy as np
import warp as wp

from warp_spt.device.structs import Features, Geometry
from warp_spt.emitters.base import KIND_PUNCTUAL, LightKind, LightSample, Weighed
from warp_spt.accel.ray_queries import Hit
from warp_spt.device.sampling import TWO_PI, orthonormal_basis
from warp_spt.accel.surface import offset_eps
from warp_spt.scene.lights import KIND_SPOT, KIND_SUN, punctual_lights
from warp_spt.scene.model import Scene
from warp_spt.scene.sky import Sky

INV_PI = wp.constant(0.3183098861837907)
# the shadow ray towards the sun: far beyond any scene the limits admit, and finite, so that a ray
# redrawn from the other side of a surface (nee.shadow_ray) stays finite
SUN_DISTANCE = wp.constant(1.0e30)


@wp.struct
class PunctualLights:
    light: wp.array(dtype=wp.int32)       # per table entry: the light
    kind: wp.array(dtype=wp.int32)        # per light: scene.lights.KIND_SUN / KIND_POINT / KIND_SPOT
    vecs: wp.array(dtype=wp.vec3)         # per light, two rows: position (sun: direction towards it), colour
    axis: wp.array(dtype=wp.vec3)         # per light: a spot's unit axis (where it shines)
    cone: wp.array(dtype=wp.vec4)         # per light: the sun's (cos r, 1 - cos r, sin^2 r, 0), a spot's (cos outer, scale, 0, 0)


@wp.func
def spot_scale(lights_cone: wp.vec4, cos_a: float) -> float:
    """glTF's falloff: clamp((cos a - cos outer) * scale, 0, 1)^2."""
    s = wp.clamp((cos_a - lights_cone[0]) * lights_cone[1], 0.0, 1.0)
    return s * s


def make(Lights, features: Features):
    """``sample_li`` and ``radiance`` over ``lights.punctual`` (``pdf_li``/``le`` of a ray that misses
    are 0: no ray meets these lights)."""

    @wp.func
    def sample_li(geo: Geometry, lights: Lights, entry: int, prob: float, x: wp.vec3, u: wp.vec2) -> LightSample:
        ls = LightSample()
        ls.pdf = 0.0
        j = lights.punctual.light[entry]
        a = lights.punctual.vecs[2 * j]
        h = Hit()
        h.kind = KIND_PUNCTUAL
        h.index = j
        if lights.punctual.kind[j] == KIND_SUN:
            w = wp.normalize(a)
            c = lights.punctual.cone[j]
            if c[1] > 0.0:           # uniform over the cone: 1 - cos theta uniform in [0, 1 - cos r]
                omc = u[0] * c[1]
                sin_t = wp.sqrt(wp.max(0.0, omc * (2.0 - omc)))
                t, b = orthonormal_basis(w)
                phi = TWO_PI * u[1]
                ls.dir = wp.normalize(t * (sin_t * wp.cos(phi)) + b * (sin_t * wp.sin(phi)) + w * (1.0 - omc))
                ls.pdf = prob / (TWO_PI * c[1])
            else:
                ls.dir = w
                ls.pdf = prob
            h.t = SUN_DISTANCE
            ls.t_max = SUN_DISTANCE
        else:
            dv = a - x
            dist = wp.length(dv)
            if dist <= 0.0:
                return ls
            ls.dir = dv / dist
            h.t = dist
            ls.t_max = dist - offset_eps(a, geo.extent)
            if ls.t_max <= 0.0:
                return ls
            ls.pdf = prob
        ls.h = h
        return ls

    @wp.func
    def radiance(lights: Lights, ls: LightSample, x: wp.vec3) -> wp.vec3:
        """What arrives at ``x`` from the sampled light (unoccluded): the estimate is f * this / pdf
        with MIS weight 1. Computed from the parameters again, so that their derivatives flow."""
        j = ls.h.index
        col = lights.punctual.vecs[2 * j + 1]
        c = lights.punctual.cone[j]
        kind = lights.punctual.kind[j]
        if kind == KIND_SUN:
            if c[1] > 0.0:
                return col * (INV_PI / c[2])
            return col
        dv = lights.punctual.vecs[2 * j] - x
        r2 = wp.dot(dv, dv)
        if r2 <= 0.0:
            return wp.vec3(0.0, 0.0, 0.0)
        li = col / r2
        if kind == KIND_SPOT:
            li = li * spot_scale(c, -wp.dot(lights.punctual.axis[j], dv) / wp.sqrt(r2))
        return li

    @wp.func
    def pdf_li(lights: Lights, d: wp.vec3) -> float:
        return 0.0

    @wp.func
    def le(lights: Lights, d: wp.vec3) -> wp.vec3:
        return wp.vec3(0.0, 0.0, 0.0)

    return SimpleNamespace(sample_li=sample_li, pdf_li=pdf_li, le=le, radiance=radiance)


# ---------------------------------------------------------------------------------------------
# Host side


def scene_radius(scene: Scene) -> float:
    """Half the diagonal of the scene's bounds (1 without geometry)."""
    b = scene.bounds
    r = 0.5 * float(np.linalg.norm(b[1] - b[0])) if np.all(np.isfinite(b)) else 1.0
    return max(r, 1e-6)


def power(light, radius: float) -> float:
    """The choice weight of one light (mean over RGB), see the module docstring."""
    if light.kind == KIND_SUN:
        return float(np.mean(light.color)) * math.pi * radius * radius
    i = float(np.mean(light.intensity))
    if light.kind == KIND_SPOT:
        ci, co = math.cos(math.radians(light.inner_deg)), math.cos(math.radians(light.outer_deg))
        return i * 2.0 * math.pi * ((1.0 - ci) + (ci - co) / 3.0)
    return i * 4.0 * math.pi


def weigh(scene: Scene, sky: Sky) -> Weighed:
    lights = punctual_lights(scene.lights)
    radius = scene_radius(scene)
    w = np.array([power(x, radius) for x in lights], dtype=np.float64)
    (keep,) = np.nonzero(w > 0)
    return Weighed(w[keep], (keep.astype(np.int32), lights))


def light_rows(light) -> tuple:
    """(kind, position or direction, colour, axis, cone) of one light, as uploaded."""
    if light.kind == KIND_SUN:
        r = math.radians(light.radius_deg)
        sin2 = math.sin(r) ** 2
        omc = sin2 / (1.0 + math.cos(r))
        return light.kind, light.direction, light.color, (0.0, 0.0, 1.0), (math.cos(r), omc, sin2, 0.0)
    if light.kind == KIND_SPOT:
        ci, co = math.cos(math.radians(light.inner_deg)), math.cos(math.radians(light.outer_deg))
        axis = np.asarray(light.direction, np.float64)
        axis = tuple(axis / np.linalg.norm(axis))
        return light.kind, light.position, light.intensity, axis, (co, 1.0 / max(1e-3, ci - co), 0.0, 0.0)
    return light.kind, light.position, light.intensity, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0, 0.0)


def upload(payload, prob: np.ndarray, scene: Scene, sky: Sky, up, device: str) -> PunctualLights:
    keep, lights = payload if payload is not None else (np.zeros(0, np.int32), [])
    rows = [light_rows(x) for x in lights] or [(0, (0.0, 0.0, 1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0,) * 4)]
    s = PunctualLights()
    s.light = wp.array(keep if len(keep) else np.zeros(1, np.int32), dtype=wp.int32, device=device)
    s.kind = wp.array(np.array([r[0] for r in rows], np.int32), dtype=wp.int32, device=device)
    vecs = np.array([v for r in rows for v in (r[1], r[2])], np.float32).reshape(-1, 3)
    s.vecs = wp.array(vecs, dtype=wp.vec3, device=device)
    s.axis = wp.array(np.array([r[3] for r in rows], np.float32), dtype=wp.vec3, device=device)
    s.cone = wp.array(np.array([r[4] for r in rows], np.float32), dtype=wp.vec4, device=device)
    return s


def declare(scene: Scene, used: np.ndarray, base: Features) -> frozenset:
    """"punctual" where the scene has a sun, point or spot light."""
    return frozenset({"punctual"} if punctual_lights(scene.lights) else ())


KIND = LightKind("punctual", PunctualLights, KIND_PUNCTUAL, area=False, declare=declare,
                 weigh=weigh, upload=upload, make=make, params="vecs", delta=True,
                 pathwise=frozenset({"position", "direction"}))
