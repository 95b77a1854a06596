"""Emitting triangles: every triangle of every mesh whose material emits (textured emitters included).

Triangles are two-sided, as in the seed. A triangle that subtends a fair solid angle from the
shading point is sampled uniformly in solid angle (Arvo's spherical-triangle map), so that a point
close to an emitter (the ceiling just above the Cornell box's light, lit by its back face) does not
pay area sampling's 1/r^2; a tiny or distant one is sampled uniformly by area, its solid-angle
density using ``|cos|`` on either face. ``pdf_li`` makes the same choice from the same numbers.

Choice weight: area x mean emitted radiance x 2 (two-sided), the mean taken over the texture on the
triangle at a few points for a textured emitter. A scene with many emitting triangles (at least
``light_tree.MIN_TREE_LIGHTS``) puts them all in one table entry of their total weight and chooses
among them with a light tree (``light_tree``): in proportion to power over distance squared from the
shading point.

(No ``from __future__ import annotations`` here: ``make``'s functions are annotated with the
``Lights`` struct it is given, which Warp must see as an object, not as a string.)
"""

from types import SimpleNamespace

import numpy as np
import warp as wp

from warp_spt.device.structs import Features, Geometry
from warp_spt.accel.ray_queries import KIND_TRIANGLE, Hit
from warp_spt.emitters.base import (
    emitting_rows,
    LightKind,
    LightSample,
    Weighed,
    device_array,
    mean_emission,
    sample_at,
)
from warp_spt.emitters import emissive_texels
from warp_spt.emitters.emissive_texels import TexelLights
from warp_spt.emitters.light_tree import MIN_TREE_LIGHTS, LightTree, build_tree, leaf_prob, pick_leaf, upload_tree
from warp_spt.device.sampling import solid_angle_terms, spherical_triangle_sample
from warp_spt.scene.model import SLOT_EMISSION, Scene
from warp_spt.scene.sky import Sky

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
class TriangleLights:
    """Per triangle entry: its mesh and face; per global face: its choice probability (0: not in the
    table). With a light tree (``use_tree``): the kind is one table entry, ``face_prob`` that entry's
    probability, and the tree chooses the triangle (``face_entry``: a face's triangle entry)."""

    mesh: wp.array(dtype=wp.int32)
    face: wp.array(dtype=wp.int32)
    face_prob: wp.array(dtype=wp.float32)
    use_tree: int
    face_entry: wp.array(dtype=wp.int32)
    tree: LightTree
    texel: TexelLights     # textured emitters' cells (``emissive_texels``)


@wp.func
def use_solid_angle(omega: float) -> bool:
    """Sample a triangle by solid angle, not by area, when it subtends omega steradians from the
    shading point: area sampling's 1/r^2 then varies wildly over it, while a small triangle gains
    little for the cost (and beyond MAX_SPHERICAL, nearly enclosing, Arvo's map loses precision).
    ``sample_li`` and ``pdf_li`` decide with the same function of the same numbers, so their
    densities agree."""
    return omega >= MIN_SPHERICAL and omega <= MAX_SPHERICAL


# tan(MIN_SPHERICAL / 2) lowered by 0.1%: where |num| / den (``solid_angle_terms``, den > 0) is below
# it, the triangle subtends less than MIN_SPHERICAL by a margin far above atan2f's and the product's
# rounding (a few 1e-7), so the solid angle, which only that comparison would read, is not taken.
_SMALL_RATIO = wp.constant(float(np.tan(0.5 * float(MIN_SPHERICAL)) * (1.0 - 1.0e-3)))


@wp.func
def sampled_solid_angle(p0: wp.vec3, p1: wp.vec3, p2: wp.vec3, x: wp.vec3) -> float:
    """``triangle_solid_angle(p0, p1, p2, x)`` wherever ``use_solid_angle`` could hold for it, else 0
    (a triangle that surely subtends less than MIN_SPHERICAL: sampled by area, its solid angle
    unused). Skipping the arctangent there (most light samples of a room lit by a small lamp: libm's
    atan2f was about 6% of the Cornell box's path kernel) changes no decision and no bit."""
    num, den = solid_angle_terms(p0, p1, p2, x)
    if den > 0.0 and wp.abs(num) < den * _SMALL_RATIO:
        return 0.0
    return wp.abs(2.0 * wp.atan2(num, den))


@wp.func
def triangle_pdf(mesh: wp.uint64, face: int, x: wp.vec3, r2_over_cos: float) -> float:
    """Density (per steradian, before the choice probability) of sampling the triangle from x for a
    direction that meets it at distance r with cosine cos there."""
    p0 = wp.mesh_get_point(mesh, 3 * face)
    p1 = wp.mesh_get_point(mesh, 3 * face + 1)
    p2 = wp.mesh_get_point(mesh, 3 * face + 2)
    omega = sampled_solid_angle(p0, p1, p2, x)
    if use_solid_angle(omega):
        return 1.0 / omega
    return r2_over_cos / (0.5 * wp.length(wp.cross(p1 - p0, p2 - p0)))


def make(Lights, features: Features):
    """``sample_li`` and ``pdf_li`` over ``lights.triangle``."""

    @wp.func
    def sample_triangle(geo: Geometry, lights: Lights, entry: int, prob: float, x: wp.vec3, u: wp.vec2) -> LightSample:
        ls = LightSample()
        ls.pdf = 0.0
        mesh = lights.triangle.mesh[entry]
        face = lights.triangle.face[entry]
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
        omega = sampled_solid_angle(p0, p1, p2, x)
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
        return sample_at(h, pl, x, spherical, prob, omega, prob, area2, geo.extent)

    @wp.func(inline=True)     # into the dispatch's pdf_li, one function as before: no call level of its own
    def pdf_li(geo: Geometry, lights: Lights, h: Hit, o: wp.vec3, d: wp.vec3) -> float:
        prob = lights.triangle.face_prob[geo.face_offset[h.index] + h.face]
        cos_l = wp.abs(wp.dot(h.normal, d))
        if prob > 0.0 and cos_l >= 1.0e-7:
            return prob * triangle_pdf(geo.mesh_ids[h.index], h.face, o, h.t * h.t / cos_l)
        return 0.0

    if features.lit("triangle.texels"):       # image-textured emitters drawn by their texels' light
        by_texels = emissive_texels.make(Lights, use_solid_angle, sample_triangle, pdf_li)
        sample_triangle, pdf_li = by_texels.sample_li, by_texels.pdf_li

    if not features.lit("triangle.tree"):
        return SimpleNamespace(sample_li=sample_triangle, pdf_li=pdf_li)

    @wp.func(inline=True)     # into the dispatch's chain: one call level, as without the tree
    def sample_li(geo: Geometry, lights: Lights, entry: int, prob: float, x: wp.vec3, u: wp.vec2) -> LightSample:
        e = entry
        p = float(1.0)
        uu = u[0]
        if lights.triangle.use_tree != 0:
            e, p, uu = pick_leaf(lights.triangle.tree, x, u[0])
        return sample_triangle(geo, lights, e, prob * p, x, wp.vec2(uu, u[1]))

    @wp.func(inline=True)
    def pdf_tree(geo: Geometry, lights: Lights, h: Hit, o: wp.vec3, d: wp.vec3) -> float:
        pdf = pdf_li(geo, lights, h, o, d)
        if lights.triangle.use_tree != 0 and pdf > 0.0:
            e = lights.triangle.face_entry[geo.face_offset[h.index] + h.face]
            pdf = pdf * leaf_prob(lights.triangle.tree, e, o)
        return pdf

    return SimpleNamespace(sample_li=sample_li, pdf_li=pdf_tree)


def weigh(scene: Scene, sky: Sky) -> Weighed:
    """The emitting faces: weights 2 x area x mean emission; payload (mesh, face, global face, number
    of faces in the scene)."""
    tm, tf, tg, tw = [], [], [], []
    start = 0
    # Only faces whose material can emit (a positive constant or an emission texture) are weighed:
    # weighing every face was the whole process's memory peak on large meshes (about 250 bytes of
    # temporaries per triangle; at 1M triangles peak 650 -> 425 MB and 1.06 -> 0.16 CPU s without it).
    mt = scene.materials
    may_emit = (mt.emission.astype(np.float64).mean(axis=1) > 0) | (mt.tex[:, SLOT_EMISSION] != -1)
    for k, m in enumerate(scene.meshes):
        (cand,) = np.nonzero(may_emit[m.face_material])
        p = m.positions[m.indices[cand]].astype(np.float64)
        area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
        w0, w1 = _BARY[:, 0], _BARY[:, 1]
        cuv = m.corner_uv[cand]
        uv = (cuv[:, None, 0] * w0[:, None] + cuv[:, None, 1] * w1[:, None]
              + cuv[:, None, 2] * (1 - w0 - w1)[:, None])
        weight = 2.0 * area * mean_emission(scene, m.face_material[cand], uv)
        faces = cand[weight > 0]
        weight = weight[weight > 0]
        tm.append(np.full(len(faces), k))
        tf.append(faces)
        tg.append(faces + start)
        tw.append(weight)
        start += len(m.indices)
    cat = (lambda parts, dt: np.concatenate(parts).astype(dt) if parts else np.zeros(0, dt))
    weights, mesh, face = cat(tw, np.float64), cat(tm, np.int32), cat(tf, np.int32)
    weights, cells = emissive_texels.cells(scene, mesh, face, weights)
    tree = None
    if len(weights) >= MIN_TREE_LIGHTS:      # one table entry; the tree chooses among the triangles
        corners = np.stack([scene.meshes[k].positions[scene.meshes[k].indices[f]] for k, f in zip(mesh, face)])
        tree = build_tree(corners.astype(np.float64), weights)
        return Weighed(np.array([weights.sum()]), (mesh, face, cat(tg, np.int64), start, tree, cells))
    return Weighed(weights, (mesh, face, cat(tg, np.int64), start, tree, cells))


def upload(payload, prob: np.ndarray, scene: Scene, sky: Sky, up, device: str) -> TriangleLights:
    mesh, face, global_face, num_faces, tree, cells = payload
    face_prob = np.zeros(max(num_faces, 1), np.float32)
    face_prob[global_face] = prob if tree is None else prob[0]
    face_entry = np.zeros(max(num_faces, 1) if tree is not None else 1, np.int32)
    if tree is not None:
        face_entry[global_face] = np.arange(len(global_face))
    t = TriangleLights()
    t.mesh, t.face = device_array(mesh, wp.int32, np.int32, device), device_array(face, wp.int32, np.int32, device)
    t.face_prob = device_array(face_prob, wp.float32, np.float32, device)
    t.use_tree = int(tree is not None)
    t.face_entry = device_array(face_entry, wp.int32, np.int32, device)
    t.tree = upload_tree(tree, device)
    t.texel = emissive_texels.upload(cells, global_face, num_faces, device)
    return t


def declare(scene: Scene, used: np.ndarray, base: Features) -> frozenset:
    """"triangle" where some used material emits and the scene has triangles; "triangle.tree" for
    many emitting faces (at least as many as the table's triangle entries, so that a scene whose
    table builds a light tree compiles its code); "triangle.texels" for image-textured emitters."""
    out = set()
    if base.emitters and base.meshes:
        out.add("triangle")
    row_emits = emitting_rows(scene)
    if sum(np.count_nonzero(row_emits[m.face_material]) for m in scene.meshes) >= MIN_TREE_LIGHTS:
        out.add("triangle.tree")
    if (scene.materials.tex[used, SLOT_EMISSION] >= 0).any():
        out.add("triangle.texels")
    return frozenset(out)


KIND = LightKind("triangle", TriangleLights, KIND_TRIANGLE, area=True, weigh=weigh, upload=upload, make=make,
                 declare=declare, sampled=lambda f: f.emitters and f.meshes and f.lit("triangle"))
