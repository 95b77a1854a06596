"""Emitting spheres, sampled uniformly over the cone they subtend from the shading point.

Choice weight: 4 pi r^2 x mean emitted radiance (over a 4x4 grid of uv points for a textured one).

(No ``from __future__ import annotations`` here: ``make``'s functions are annotated with the
``Lights`` struct it is given, which Warp must see as an object, not as a string.)
"""

from types import SimpleNamespace

import numpy as np
import warp as wp

from warp_spt.device.structs import Features, Geometry
from warp_spt.accel.ray_queries import KIND_SPHERE, NO_HIT, Hit, sphere_hit
from warp_spt.emitters.base import (
    LightKind,
    LightSample,
    Weighed,
    device_array,
    mean_emission,
)
from warp_spt.device.sampling import TWO_PI, orthonormal_basis
from warp_spt.accel.surface import offset_eps
from warp_spt.scene.model import Scene
from warp_spt.scene.sky import Sky


@wp.struct
class SphereLights:
    """Per sphere entry: the sphere; per sphere: its choice probability (0: not in the table)."""

    index: wp.array(dtype=wp.int32)
    sphere_prob: wp.array(dtype=wp.float32)


@wp.func
def cone_one_minus_cos(c: wp.vec3, r: float, x: wp.vec3) -> float:
    """1 - cos(half-angle) of the cone a sphere subtends from x (0 when x is inside it); written
    as sin^2 / (1 + cos) so that a tiny or far sphere does not round to an empty cone."""
    d2 = wp.length_sq(c - x)
    if d2 <= r * r:
        return 0.0
    sin2 = r * r / d2
    return sin2 / (1.0 + wp.sqrt(wp.max(0.0, 1.0 - sin2)))


def make(Lights, features: Features):
    """``sample_li`` and ``pdf_li`` over ``lights.sphere``."""

    @wp.func
    def sample_li(geo: Geometry, lights: Lights, entry: int, prob: float, x: wp.vec3, u: wp.vec2) -> LightSample:
        ls = LightSample()
        ls.pdf = 0.0
        j = lights.sphere.index[entry]
        sph = geo.spheres[j]
        c = wp.vec3(sph[0], sph[1], sph[2])
        omc = cone_one_minus_cos(c, sph[3], x)
        if omc <= 0.0:
            return ls                       # inside the sphere: left to BSDF sampling
        w = wp.normalize(c - x)
        e1, e2 = orthonormal_basis(w)
        one_minus = u[0] * omc              # 1 - cos(theta), uniform in the cone
        cos_t = 1.0 - one_minus
        sin_t = wp.sqrt(wp.max(0.0, one_minus * (2.0 - one_minus)))
        phi = TWO_PI * u[1]
        ls.dir = wp.normalize(e1 * (sin_t * wp.cos(phi)) + e2 * (sin_t * wp.sin(phi)) + w * cos_t)
        th = sphere_hit(sph, x, ls.dir, NO_HIT)
        if th >= NO_HIT:
            return ls                       # grazed past the rim in float32
        h = Hit()
        h.kind = KIND_SPHERE
        h.index = j
        h.t = th
        ls.h = h
        ls.pdf = prob / (TWO_PI * omc)
        on = c + wp.normalize(x + ls.dir * th - c) * sph[3]     # surface_at's point: back onto the sphere
        ls.t_max = th - offset_eps(on, geo.extent) * 2.0
        return ls

    @wp.func(inline=True)     # into the dispatch's pdf_li, one function as before: no call level of its own
    def pdf_li(geo: Geometry, lights: Lights, h: Hit, o: wp.vec3, d: wp.vec3) -> float:
        prob = lights.sphere.sphere_prob[h.index]
        sph = geo.spheres[h.index]
        omc = cone_one_minus_cos(wp.vec3(sph[0], sph[1], sph[2]), sph[3], o)
        if prob > 0.0 and omc > 0.0:
            return prob / (TWO_PI * omc)
        return 0.0

    return SimpleNamespace(sample_li=sample_li, pdf_li=pdf_li)


def weigh(scene: Scene, sky: Sky) -> Weighed:
    """The emitting spheres: weights 4 pi r^2 x mean emission; payload their indices."""
    sph = scene.spheres.astype(np.float64).reshape(-1, 4)
    g = np.linspace(0.05, 0.95, 4)
    uv = np.broadcast_to(np.stack(np.meshgrid(g, g), -1).reshape(1, -1, 2), (len(sph), 16, 2))
    sw = 4 * np.pi * sph[:, 3] ** 2 * mean_emission(scene, scene.sphere_material, uv)
    (si,) = np.nonzero(sw > 0)
    return Weighed(sw[si], si.astype(np.int32))


def upload(payload, prob: np.ndarray, scene: Scene, sky: Sky, up, device: str) -> SphereLights:
    sphere_prob = np.zeros(max(len(scene.spheres), 1), np.float32)
    sphere_prob[payload] = prob
    s = SphereLights()
    s.index = device_array(payload, wp.int32, np.int32, device)
    s.sphere_prob = device_array(sphere_prob, wp.float32, np.float32, device)
    return s


def declare(scene: Scene, used: np.ndarray, base: Features) -> frozenset:
    """"sphere" where some used material emits and the scene has spheres."""
    return frozenset({"sphere"} if base.emitters and base.spheres else ())


KIND = LightKind("sphere", SphereLights, KIND_SPHERE, area=True, weigh=weigh, upload=upload, make=make,
                 declare=declare, sampled=lambda f: f.emitters and f.spheres and f.lit("sphere"))
