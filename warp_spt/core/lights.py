"""Lights: the sky's radiance, and the light table that next-event estimation samples.

The table is built from what the scene really emits:

* every emissive triangle of every mesh (textured emitters included),
* every emissive sphere, sampled over the cone it subtends from the shading point,
* the sky (constant or gradient), sampled with a density proportional to its radiance.

One discrete distribution chooses among all of them, with probability proportional to
**emitting area x mean emitted radiance** (mean over the RGB channels; for a textured emitter, over
the texture on that triangle, estimated at a few points). For the seed's diffuse emitters that is
proportional to the emitted power: a two-sided triangle of area A radiates 2*pi*A*L, a sphere
pi*4*pi*r^2*L, and the sky is weighed as a sphere of the scene's radius seen from inside. Power,
rather than area alone, sends few samples to dim emitters; the estimate is unbiased whatever the
weights, because MIS evaluates ``pdf`` with the same table that ``sample`` draws from (an emitter
the table misses is simply found by BSDF sampling).

Triangles are two-sided, as in the seed. A triangle that subtends a fair solid angle from the
shading point is sampled uniformly in solid angle (Arvo's spherical-triangle map), so that a point
close to an emitter (the ceiling just above the Cornell box's light, lit by its back face) does not
pay area sampling's 1/r^2; a tiny or distant one is sampled uniformly by area, its solid-angle
density using ``|cos|`` on either face. ``pdf_hit`` makes the same choice from the same numbers.
"""

from __future__ import annotations

from dataclasses import dataclass
from types import SimpleNamespace

import numpy as np
import warp as wp

from warp_spt.core.device_scene import Features, Geometry, Materials, Textures
from warp_spt.core.geometry import (
    KIND_MISS,
    KIND_SPHERE,
    KIND_TRIANGLE,
    NO_HIT,
    Hit,
    sphere_hit,
)
from warp_spt.core.sampling import (
    TWO_PI,
    orthonormal_basis,
    spherical_triangle_sample,
    triangle_solid_angle,
)
from warp_spt.core.surface import offset_eps
from warp_spt.core.textures import checker_np, sample_texture_np
from warp_spt.scene.model import SLOT_EMISSION, TEX_CHECKER, TEX_PROC_BASE, Scene
from warp_spt.scene.sky import SKY_GRADIENT, Z_UP, Sky

INV_FOUR_PI = wp.constant(0.07957747154594767)
# Solid-angle range (steradians) in which a triangle is sampled by solid angle (see use_solid_angle).
# Below 0.1 sr the distance and cosine vary little over the triangle, so area sampling is nearly as
# good and about 4x cheaper (Arvo's map costs ~115 ns here); on the Cornell box of
# benchmarks/bench_light.py thresholds of 3e-4 (pbrt-v4's), 0.02 and 0.1 gave the same MSE
# (nee: 0.0261, area sampling alone 0.0325), 0.5 a little more (0.0269). Above 6.22 (pbrt-v4's
# bound) the triangle nearly encloses the point and the map loses precision.
MIN_SPHERICAL = wp.constant(0.1)
MAX_SPHERICAL = wp.constant(6.22)
# Barycentric points at which a textured emitter's mean radiance is estimated for its weight
_BARY = np.array([(1 / 3, 1 / 3)] + [(a, b) for a in (0.1, 0.45, 0.8) for b in (0.1, 0.45) if a + b < 1])


@wp.struct
class Lights:
    """The light table (entries: triangles, then spheres, then the sky) and the sky itself."""

    cdf: wp.array(dtype=wp.float32)            # cumulative choice probabilities, last = 1
    num_entries: int
    num_triangles: int
    num_spheres: int
    entry_prob: wp.array(dtype=wp.float32)     # choice probability per entry
    tri_mesh: wp.array(dtype=wp.int32)         # per triangle entry: mesh and face within it
    tri_face: wp.array(dtype=wp.int32)
    face_prob: wp.array(dtype=wp.float32)      # per global face: choice probability (0: not in table)
    sph_index: wp.array(dtype=wp.int32)        # per sphere entry: the sphere
    sphere_prob: wp.array(dtype=wp.float32)    # per sphere: choice probability (0: not in table)
    sky_prob: float                            # choice probability of the sky (0: it does not emit)
    sky_kind: int
    sky_color: wp.vec3                         # constant sky: its colour; gradient sky: its mean
    sky_slope: wp.vec3                         # gradient sky: radiance = sky_color + sky_slope * z
    sky_a: float                               # sky sampling density is (a + b z) / (4 pi a)
    sky_b: float
    sky_up: wp.vec3                            # z above is the direction's component along sky_up;
    sky_t: wp.vec3                             # (sky_t, sky_b_axis, sky_up) is a right-handed frame,
    sky_b_axis: wp.vec3                        # (1,0,0), (0,1,0), (0,0,1) for the seed's Z up


@wp.struct
class LightSample:
    """A sampled light direction: incident radiance, density (solid angle, choice included), and
    how far a shadow ray must stay clear (just short of the emitter)."""

    dir: wp.vec3
    li: wp.vec3
    pdf: float
    t_max: float
    h: Hit            # the point on the emitter (kind KIND_MISS: the sky), where ``radiance`` looks


@wp.func
def sky_radiance(lights: Lights, d: wp.vec3) -> wp.vec3:
    """The seed's skies: SKY_GRADIENT linear in the component along the up axis, anything else a
    constant colour."""
    if lights.sky_kind == 1:
        z = wp.dot(d, lights.sky_up)             # exactly d[2] for Z up: the seed's images do not change
        return lights.sky_color + lights.sky_slope * z
    return lights.sky_color


@wp.func
def sky_pdf(lights: Lights, d: wp.vec3) -> float:
    """Density of ``sample_sky`` (before the choice probability): proportional to the RGB sum."""
    return (lights.sky_a + lights.sky_b * wp.dot(d, lights.sky_up)) * INV_FOUR_PI / lights.sky_a


@wp.func
def sample_sky(lights: Lights, u: wp.vec2) -> wp.vec3:
    """Invert the CDF of z for the density (a + b z) on [-1, 1]; uniform in azimuth around the up axis."""
    a = lights.sky_a
    b = lights.sky_b
    z = 2.0 * u[0] - 1.0
    if wp.abs(b) > 1.0e-6 * a:
        disc = a * a - 2.0 * b * (a - 0.5 * b - 2.0 * a * u[0])
        z = wp.clamp((wp.sqrt(wp.max(disc, 0.0)) - a) / b, -1.0, 1.0)
    r = wp.sqrt(wp.max(0.0, 1.0 - z * z))
    phi = TWO_PI * u[1]
    return lights.sky_t * (r * wp.cos(phi)) + lights.sky_b_axis * (r * wp.sin(phi)) + lights.sky_up * z


@wp.func
def cone_one_minus_cos(c: wp.vec3, r: float, x: wp.vec3) -> float:
    """1 - cos(half-angle) of the cone a sphere subtends from x (0 when x is inside it); written
    as sin^2 / (1 + cos) so that a tiny or far sphere does not round to an empty cone."""
    d2 = wp.length_sq(c - x)
    if d2 <= r * r:
        return 0.0
    sin2 = r * r / d2
    return sin2 / (1.0 + wp.sqrt(wp.max(0.0, 1.0 - sin2)))


@wp.func
def use_solid_angle(omega: float) -> bool:
    """Sample a triangle by solid angle, not by area, when it subtends omega steradians from the
    shading point: area sampling's 1/r^2 then varies wildly over it, while a small triangle gains
    little for the cost (and beyond MAX_SPHERICAL, nearly enclosing, Arvo's map loses precision).
    ``sample`` and ``pdf_hit`` decide with the same function of the same numbers, so their densities
    agree."""
    return omega >= MIN_SPHERICAL and omega <= MAX_SPHERICAL


@wp.func
def triangle_pdf(mesh: wp.uint64, face: int, x: wp.vec3, r2_over_cos: float) -> float:
    """Density (per steradian, before the choice probability) of ``sample_triangle`` from x for a
    direction that meets the triangle at distance r with cosine cos there."""
    p0 = wp.mesh_get_point(mesh, 3 * face)
    p1 = wp.mesh_get_point(mesh, 3 * face + 1)
    p2 = wp.mesh_get_point(mesh, 3 * face + 2)
    omega = triangle_solid_angle(p0, p1, p2, x)
    if use_solid_angle(omega):
        return 1.0 / omega
    return r2_over_cos / (0.5 * wp.length(wp.cross(p1 - p0, p2 - p0)))


@wp.func
def pick_entry(lights: Lights, u: float) -> int:
    """The first table entry whose cumulative probability exceeds u (zero-weight entries never)."""
    lo = int(0)
    hi = lights.num_entries - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if lights.cdf[mid] > u:
            hi = mid
        else:
            lo = mid + 1
    return lo


@wp.func
def reuse_pick(lights: Lights, u: float) -> float:
    """The uniform number left in ``u`` once ``pick_entry`` has used it: (u - cdf before) / prob, again
    uniform on [0, 1) for the chosen entry (pbrt-v4's "remapped" sample), or -1 where the entry's
    probability is under 2**-12 and too few of u's 24 bits would be left."""
    e = pick_entry(lights, u)
    prob = lights.entry_prob[e]
    if prob < 2.44140625e-4:
        return -1.0
    lo = float(0.0)
    if e > 0:
        lo = lights.cdf[e - 1]
    return wp.clamp((u - lo) / prob, 0.0, 0.99999994)


def make_lights(features: Features, surface_at, emission) -> SimpleNamespace:
    """``sample``, ``pdf_hit`` and ``pdf_sky`` (choice included) for the light kinds these features have."""
    tris = features.emitters and features.meshes
    spheres = features.emitters and features.spheres

    @wp.func
    def sample_triangle(geo: Geometry, lights: Lights, entry: int, prob: float, x: wp.vec3,
                        u: wp.vec2) -> LightSample:
        ls = LightSample()
        ls.pdf = 0.0
        mesh = lights.tri_mesh[entry]
        face = lights.tri_face[entry]
        mid = geo.mesh_ids[mesh]
        p0 = wp.mesh_get_point(mid, 3 * face)
        p1 = wp.mesh_get_point(mid, 3 * face + 1)
        p2 = wp.mesh_get_point(mid, 3 * face + 2)
        cr = wp.cross(p1 - p0, p2 - p0)
        area2 = wp.length(cr)
        if area2 <= 0.0:
            return ls
        n = cr / area2
        h = Hit()
        h.kind = KIND_TRIANGLE
        h.index = mesh
        h.face = face
        h.normal = n
        omega = triangle_solid_angle(p0, p1, p2, x)
        spherical = use_solid_angle(omega)
        if spherical:
            d = spherical_triangle_sample(wp.normalize(p0 - x), wp.normalize(p1 - x), wp.normalize(p2 - x), omega, u)
            dn = wp.dot(n, d)
            if dn == 0.0:
                return ls
            q = x + d * (wp.dot(n, p0 - x) / dn)        # where d meets the triangle's plane
            h.u = wp.clamp(wp.dot(wp.cross(p1 - q, p2 - q), n) / area2, 0.0, 1.0)
            h.v = wp.clamp(wp.dot(wp.cross(p2 - q, p0 - q), n) / area2, 0.0, 1.0 - h.u)
        else:
            su = wp.sqrt(u[0])
            h.u = 1.0 - su                     # uniform on the triangle
            h.v = u[1] * su
        pl = p2 + (p0 - p2) * h.u + (p1 - p2) * h.v
        dist = wp.length(pl - x)
        if dist <= 0.0:
            return ls
        ls.dir = (pl - x) / dist
        h.t = dist
        cos_l = wp.abs(wp.dot(n, ls.dir))
        if cos_l < 1.0e-7:
            return ls
        ls.h = h
        if spherical:
            ls.pdf = prob / omega
        else:
            ls.pdf = prob / (0.5 * area2) * dist * dist / cos_l
        ls.t_max = dist - offset_eps(pl, geo.extent) / wp.max(cos_l, 0.05)
        return ls

    @wp.func
    def sample_sphere(geo: Geometry, lights: Lights, entry: int, prob: float, x: wp.vec3,
                      u: wp.vec2) -> LightSample:
        ls = LightSample()
        ls.pdf = 0.0
        j = lights.sph_index[entry]
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

    @wp.func
    def sample_point(geo: Geometry, lights: Lights, x: wp.vec3, u_pick: float, u: wp.vec2) -> LightSample:
        """``sample`` without the radiance: the direction, density, shadow-ray length and point."""
        ls = LightSample()
        ls.pdf = 0.0
        if lights.num_entries == 0:
            return ls
        e = pick_entry(lights, u_pick)
        prob = lights.entry_prob[e]
        if wp.static(tris):
            if e < lights.num_triangles:
                return sample_triangle(geo, lights, e, prob, x, u)
        if wp.static(spheres):
            s = e - lights.num_triangles
            if s >= 0 and s < lights.num_spheres:
                return sample_sphere(geo, lights, s, prob, x, u)
        if wp.static(features.sky):
            if lights.sky_prob > 0.0 and e == lights.num_entries - 1:
                ls.dir = sample_sky(lights, u)
                ls.pdf = prob * sky_pdf(lights, ls.dir)
                ls.t_max = NO_HIT
                ls.h.kind = KIND_MISS
        return ls

    @wp.func(inline=True)
    def radiance(geo: Geometry, m: Materials, t: Textures, lights: Lights, ls: LightSample, x: wp.vec3) -> wp.vec3:
        """The radiance arriving at ``x`` from the sampled point ``ls`` (unoccluded). Inlined: called out
        of line, it copied the four scene structs it takes by value (the fast kernel 5% slower)."""
        if ls.h.kind == KIND_MISS:
            return sky_radiance(lights, ls.dir)
        return emission(m, t, surface_at(geo, ls.h, x, ls.dir))

    @wp.func
    def sample(geo: Geometry, m: Materials, t: Textures, lights: Lights, x: wp.vec3, u_pick: float,
               u: wp.vec2) -> LightSample:
        """Choose a light with ``u_pick`` and a point on it with ``u``, as seen from ``x``: the
        direction, incident radiance ``li`` (0 where ``pdf`` is 0), density and shadow-ray length."""
        ls = sample_point(geo, lights, x, u_pick, u)
        if ls.pdf > 0.0:
            ls.li = radiance(geo, m, t, lights, ls, x)
        return ls

    @wp.func
    def pdf_hit(geo: Geometry, lights: Lights, h: Hit, o: wp.vec3, d: wp.vec3) -> float:
        """Density with which ``sample`` from ``o`` would have produced the hit ``h`` along ``d``."""
        if wp.static(tris):
            if h.kind == KIND_TRIANGLE:
                prob = lights.face_prob[geo.face_offset[h.index] + h.face]
                cos_l = wp.abs(wp.dot(h.normal, d))
                if prob > 0.0 and cos_l >= 1.0e-7:
                    return prob * triangle_pdf(geo.mesh_ids[h.index], h.face, o, h.t * h.t / cos_l)
        if wp.static(spheres):
            if h.kind == KIND_SPHERE:
                prob = lights.sphere_prob[h.index]
                sph = geo.spheres[h.index]
                omc = cone_one_minus_cos(wp.vec3(sph[0], sph[1], sph[2]), sph[3], o)
                if prob > 0.0 and omc > 0.0:
                    return prob / (TWO_PI * omc)
        return 0.0

    @wp.func
    def pdf_sky(lights: Lights, d: wp.vec3) -> float:
        """Density with which ``sample`` would have chosen the sky in direction ``d``."""
        if wp.static(features.sky):
            if lights.sky_prob > 0.0:
                return lights.sky_prob * sky_pdf(lights, d)
        return 0.0

    return SimpleNamespace(sample=sample, sample_point=sample_point, radiance=radiance, pdf_hit=pdf_hit,
                           pdf_sky=pdf_sky)


def detach_lights(light: SimpleNamespace) -> None:
    """Give the geometric half of ``light`` (from :func:`make_lights`: ``sample_point``, ``pdf_hit``,
    ``pdf_sky``) zero adjoints. Path replay's own lights only (``warp_spt.diff.prb``): its light samples
    stay put (detached sampling) and its MIS weights carry no derivative, so these adjoints were
    computed and dropped, each after re-running its function's forward code (the spherical triangle
    sampler's several times per vertex, once per nesting level); ``radiance``, which carries the
    emission and sky gradients, keeps its adjoint. The tape, whose camera gradients move the
    shading points, keeps them all."""

    @wp.func_grad(light.sample_point)
    def adj_sample_point(geo: Geometry, lights: Lights, x: wp.vec3, u_pick: float, u: wp.vec2,
                         adj_ret: LightSample):
        pass

    @wp.func_grad(light.pdf_hit)
    def adj_pdf_hit(geo: Geometry, lights: Lights, h: Hit, o: wp.vec3, d: wp.vec3, adj_ret: float):
        pass

    @wp.func_grad(light.pdf_sky)
    def adj_pdf_sky(lights: Lights, d: wp.vec3, adj_ret: float):
        pass


# ---------------------------------------------------------------------------------------------
# Host side: the table


@dataclass
class _Weights:
    tri_mesh: np.ndarray
    tri_face: np.ndarray
    tri_global: np.ndarray
    tri_weight: np.ndarray
    sph_index: np.ndarray
    sph_weight: np.ndarray
    num_faces: int


def sky_emits(sky: Sky) -> bool:
    if sky.kind == SKY_GRADIENT:
        return any(c > 0 for c in sky.zenith + sky.nadir)
    return any(c > 0 for c in sky.color)


def sky_terms(sky: Sky) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """(colour or mean, slope) of the sky's radiance colour + slope * z."""
    if sky.kind == SKY_GRADIENT:
        return sky.gradient_terms()
    return tuple(sky.color), (0.0, 0.0, 0.0)


def sky_density(sky: Sky) -> tuple[float, float]:
    """(a, b) with the RGB sum of the sky's radiance = a + b z (the sampling density's shape); the
    seed's gradient sky gives exactly (2.6, -0.4)."""
    mean, slope = sky_terms(sky)
    return float(sum(mean)), float(sum(slope))


def table_key(sky: Sky, camera_up=Z_UP) -> tuple:
    """The key under which a DeviceScene caches its light table for this sky and camera up."""
    return sky.kind, tuple(sky.color), tuple(sky.zenith), tuple(sky.nadir), sky.up_axis(camera_up)


def light_table(dev, sky: Sky, camera_up=Z_UP) -> Lights:
    """The device light table of a DeviceScene under ``sky`` (built once per scene and sky); the
    gradient sky follows ``sky.up``, else ``camera_up`` (pass the camera's ``up``)."""
    key = table_key(sky, camera_up)
    weights = dev.light_cache("weights", lambda: _emitter_weights(dev.scene))
    return dev.light_cache(key, lambda: _upload(weights, dev.scene, sky, key[-1], dev.device))


def sky_frame(up: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A right-handed orthonormal (t, b, up) around the unit ``up``: the identity for Z up."""
    u = np.asarray(up, dtype=np.float64)
    helper = np.array([0.0, 1.0, 0.0]) if abs(u[1]) < 0.9 else np.array([0.0, 0.0, 1.0])
    t = np.cross(helper, u)
    t /= np.linalg.norm(t)
    return t, np.cross(u, t), u


def _mean_emission(scene: Scene, mat: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Mean over the RGB channels of each item's emission, at uv points (items, points, 2)."""
    mt = scene.materials
    out = mt.emission[mat].astype(np.float64).mean(axis=1)
    tex = mt.tex[mat, SLOT_EMISSION]
    for k in np.unique(tex[tex != -1]):
        sel = tex == k
        if k <= TEX_PROC_BASE:     # procedural: not known on the host; sampled by area (still unbiased)
            out[sel] = 1.0
            continue
        pts = uv[sel].reshape(-1, 2)
        vals = checker_np(pts) if k == TEX_CHECKER else sample_texture_np(scene.textures[k], pts)
        out[sel] = vals.reshape(sel.sum(), -1, 3).mean(axis=(1, 2))
    return out


def _emitter_weights(scene: Scene) -> _Weights:
    tm, tf, tg, tw = [], [], [], []
    start = 0
    for k, m in enumerate(scene.meshes):
        p = m.positions[m.indices].astype(np.float64)
        area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        w0, w1 = _BARY[:, 0], _BARY[:, 1]
        uv = (m.corner_uv[:, None, 0] * w0[:, None] + m.corner_uv[:, None, 1] * w1[:, None]
              + m.corner_uv[:, None, 2] * (1 - w0 - w1)[:, None])
        weight = 2.0 * area * _mean_emission(scene, m.face_material, uv)
        (faces,) = np.nonzero(weight > 0)
        tm.append(np.full(len(faces), k))
        tf.append(faces)
        tg.append(faces + start)
        tw.append(weight[faces])
        start += len(m.indices)
    sph = scene.spheres.astype(np.float64).reshape(-1, 4)
    g = np.linspace(0.05, 0.95, 4)
    uv = np.broadcast_to(np.stack(np.meshgrid(g, g), -1).reshape(1, -1, 2), (len(sph), 16, 2))
    sw = 4 * np.pi * sph[:, 3] ** 2 * _mean_emission(scene, scene.sphere_material, uv)
    (si,) = np.nonzero(sw > 0)
    cat = (lambda parts, dt: np.concatenate(parts).astype(dt) if parts else np.zeros(0, dt))
    return _Weights(cat(tm, np.int32), cat(tf, np.int32), cat(tg, np.int64), cat(tw, np.float64),
                    si.astype(np.int32), sw[si], start)


def _upload(w: _Weights, scene: Scene, sky: Sky, up: tuple[float, float, float], device: str) -> Lights:
    weights = [w.tri_weight, w.sph_weight]
    if sky_emits(sky):
        b = scene.bounds
        radius = 0.5 * float(np.linalg.norm(b[1] - b[0])) if np.all(np.isfinite(b)) else 1.0
        a, _ = sky_density(sky)
        weights.append(np.array([4 * np.pi * max(radius, 1e-6) ** 2 * a / 3.0]))
    wall = np.concatenate(weights)
    n = len(wall)
    if n:
        cdf = (np.cumsum(wall) / wall.sum()).astype(np.float32)
        cdf[-1] = 1.0
        prob = np.diff(np.concatenate([[0.0], cdf.astype(np.float64)]))   # exactly what pick_entry does
    else:
        cdf, prob = np.zeros(1, np.float32), np.zeros(0)
    nt, ns = len(w.tri_weight), len(w.sph_weight)
    face_prob = np.zeros(max(w.num_faces, 1), np.float32)
    face_prob[w.tri_global] = prob[:nt]
    sphere_prob = np.zeros(max(len(scene.spheres), 1), np.float32)
    sphere_prob[w.sph_index] = prob[nt:nt + ns]
    L = Lights()
    arr = (lambda x, dt, npdt: wp.array(np.ascontiguousarray(x if len(x) else np.zeros(1), dtype=npdt),
                                        dtype=dt, device=device))
    L.cdf = arr(cdf, wp.float32, np.float32)
    L.entry_prob = arr(prob, wp.float32, np.float32)
    L.num_entries, L.num_triangles, L.num_spheres = n, nt, ns
    L.tri_mesh, L.tri_face = arr(w.tri_mesh, wp.int32, np.int32), arr(w.tri_face, wp.int32, np.int32)
    L.face_prob, L.sphere_prob = arr(face_prob, wp.float32, np.float32), arr(sphere_prob, wp.float32, np.float32)
    L.sph_index = arr(w.sph_index, wp.int32, np.int32)
    L.sky_prob = float(prob[-1]) if sky_emits(sky) else 0.0
    mean, slope = sky_terms(sky)
    L.sky_kind, L.sky_color, L.sky_slope = int(sky.kind), wp.vec3(*mean), wp.vec3(*slope)
    L.sky_a, L.sky_b = sky_density(sky) if sky_emits(sky) else (1.0, 0.0)
    L.sky_t, L.sky_b_axis, L.sky_up = (wp.vec3(*v.astype(np.float32).tolist()) for v in sky_frame(up))
    return L
