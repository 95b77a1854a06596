"""Emissive textures sampled by their texels: a light triangle whose emission is an image texture
(``map_Ke``) covering several texels is split into cells, and a point on it is drawn in proportion
to the light of each cell rather than uniformly over its area.

The cells are the triangle's regular midpoint subdivision of order ``n``: in barycentric coordinates
(u, v) (the weights of corners 0 and 1, as ``Hit.u``/``Hit.v``) the grid of step 1/n cuts it into n^2
congruent triangles, cell ``(i, j)`` holding a "lower" triangle (i, j), (i+1, j), (i, j+1) and, for
i + j < n - 1, an "upper" one (i+1, j+1), (i, j+1), (i+1, j) (all over n). The cell of a point
is found from its barycentrics alone (``cell_of``), so MIS evaluates the same density that sampling
drew from. ``n`` is chosen so that a cell covers about one texel of the triangle's uv footprint
(at most ``MAX_N``); a triangle covering under two texels keeps uniform sampling.

A cell's weight is its mean emitted luminance (mean over RGB, nearest texels at s x s points per
cell) plus 1% of the triangle's mean, so that no cell that might emit (a bilinear filter bleeds
across a black texel's edge) has density 0. Within the chosen cell a point is drawn as the
triangle sampler draws one on a whole triangle: uniformly in solid angle where the cell subtends a
fair solid angle (``use_solid_angle``), else uniformly by area. The triangle's own choice weight
becomes 2 x area x the cells' mean, a better estimate than a few points.

Unbiased whatever the weights: the density of a point is the cell's probability over the cell's
area (or solid angle), evaluated by ``pdf_li`` from the hit's barycentrics, and MIS with BSDF
sampling covers any cell of weight zero.

(No ``from __future__ import annotations`` here: ``make``'s functions are annotated with the
``Lights`` struct it is given, which Warp must see as an object, not as a string.)
"""

from types import SimpleNamespace

import numpy as np
import warp as wp

from warp_spt.core.geometry import KIND_TRIANGLE, Hit
from warp_spt.core.lights.base import LightSample, device_array
from warp_spt.core.sampling import spherical_triangle_sample, triangle_solid_angle
from warp_spt.core.structs import Geometry
from warp_spt.core.surface import offset_eps
from warp_spt.core.textures import sample_texture_np
from warp_spt.scene.model import SLOT_EMISSION, Scene

MAX_N = 32                 # cells per edge at most (2 n^2 table slots per triangle)
MAX_SLOTS = 1 << 22        # table slots for the whole scene; triangles past it keep uniform sampling
FLOOR = 0.01               # each cell's weight gets this fraction of the triangle's mean
ONE_MINUS_EPS = wp.constant(0.99999994)


@wp.struct
class TexelLights:
    """Per global face: the first slot of its cells in ``cdf``/``prob`` (-1: sampled uniformly) and
    its order ``n``; per slot (2 n^2 a triangle, slot 2 (i n + j) + upper): the cumulative and own
    probabilities of the cells within their triangle (0 for slots that are not a cell)."""

    first: wp.array(dtype=wp.int32)
    n: wp.array(dtype=wp.int32)
    cdf: wp.array(dtype=wp.float32)
    prob: wp.array(dtype=wp.float32)


@wp.func
def cell_of(n: int, bu: float, bv: float) -> int:
    """The slot of the cell holding barycentrics (bu, bv) in the order-n subdivision."""
    a = bu * float(n)
    b = bv * float(n)
    i = wp.clamp(int(wp.floor(a)), 0, n - 1)
    j = wp.clamp(int(wp.floor(b)), 0, n - 1 - i)
    up = int(0)
    if i + j < n - 1 and (a - float(i)) + (b - float(j)) > 1.0:
        up = 1
    return 2 * (i * n + j) + up


@wp.func
def cell_corner(n: int, slot: int, k: int) -> wp.vec2:
    """Barycentrics (u, v) of corner k (0, 1, 2) of cell ``slot``."""
    up = slot % 2
    ij = slot // 2
    i = ij // n
    j = ij - i * n
    di = int(0)
    dj = int(0)
    if up == 0:
        if k == 1:
            di = 1
        if k == 2:
            dj = 1
    else:
        if k == 0:
            di = 1
            dj = 1
        if k == 1:
            dj = 1
        if k == 2:
            di = 1
    inv = 1.0 / float(n)
    return wp.vec2(float(i + di) * inv, float(j + dj) * inv)


@wp.func
def at_bary(p0: wp.vec3, p1: wp.vec3, p2: wp.vec3, b: wp.vec2) -> wp.vec3:
    return p2 + (p0 - p2) * b[0] + (p1 - p2) * b[1]


@wp.func
def pick_cell(cells: TexelLights, first: int, count: int, u: float):
    """(slot within the triangle, its probability, u rescaled for reuse): the first slot whose
    cumulative probability exceeds u."""
    lo = int(0)
    hi = count - 1
    while lo < hi:
        mid = (lo + hi) // 2
        if cells.cdf[first + mid] > u:
            hi = mid
        else:
            lo = mid + 1
    p = cells.prob[first + lo]
    below = float(0.0)
    if lo > 0:
        below = cells.cdf[first + lo - 1]
    uu = float(0.0)
    if p > 0.0:
        uu = wp.clamp((u - below) / p, 0.0, ONE_MINUS_EPS)
    return lo, p, uu


def make(Lights, use_solid_angle, sample_plain, pdf_plain):
    """``sample_li`` and ``pdf_li`` over ``lights.triangle`` drawing textured triangles by their cells
    (``use_solid_angle``, ``sample_plain`` and ``pdf_plain``: the triangle kind's, used as they are
    for every triangle without cells)."""

    @wp.func(inline=True)
    def sample_li(geo: Geometry, lights: Lights, entry: int, prob: float, x: wp.vec3, u: wp.vec2) -> LightSample:
        mesh = lights.triangle.mesh[entry]
        face = lights.triangle.face[entry]
        g = geo.face_offset[mesh] + face
        first = int(-1)
        if g < lights.triangle.texel.first.shape[0]:     # one slot only where no triangle has cells
            first = lights.triangle.texel.first[g]
        if first < 0:
            return sample_plain(geo, lights, entry, prob, x, u)
        ls = LightSample()
        ls.pdf = 0.0
        n = lights.triangle.texel.n[g]
        slot, pc, uu = pick_cell(lights.triangle.texel, first, 2 * n * n, u[0])
        if pc <= 0.0:
            return ls
        mid = geo.mesh_ids[mesh]
        p0 = wp.mesh_get_point(mid, 3 * face)
        p1 = wp.mesh_get_point(mid, 3 * face + 1)
        p2 = wp.mesh_get_point(mid, 3 * face + 2)
        cr = wp.cross(p1 - p0, p2 - p0)
        area2 = wp.length(cr)
        if area2 <= 0.0:
            return ls
        nrm = cr / area2
        q0 = at_bary(p0, p1, p2, cell_corner(n, slot, 0))
        q1 = at_bary(p0, p1, p2, cell_corner(n, slot, 1))
        q2 = at_bary(p0, p1, p2, cell_corner(n, slot, 2))
        omega = triangle_solid_angle(q0, q1, q2, x)
        spherical = use_solid_angle(omega)
        pl = wp.vec3()
        if spherical:
            d = spherical_triangle_sample(wp.normalize(q0 - x), wp.normalize(q1 - x), wp.normalize(q2 - x), omega,
                                          wp.vec2(uu, u[1]))
            dn = wp.dot(nrm, d)
            if dn == 0.0:
                return ls
            pl = x + d * (wp.dot(nrm, p0 - x) / dn)
        else:
            su = wp.sqrt(uu)
            pl = at_bary(q0, q1, q2, wp.vec2(1.0 - su, u[1] * su))
        h = Hit()
        h.kind = KIND_TRIANGLE
        h.index = mesh
        h.face = face
        h.normal = nrm
        h.u = wp.clamp(wp.dot(wp.cross(p1 - pl, p2 - pl), nrm) / area2, 0.0, 1.0)
        h.v = wp.clamp(wp.dot(wp.cross(p2 - pl, p0 - pl), nrm) / area2, 0.0, 1.0 - h.u)
        dist = wp.length(pl - x)
        if dist <= 0.0:
            return ls
        ls.dir = (pl - x) / dist
        h.t = dist
        cos_l = wp.abs(wp.dot(nrm, ls.dir))
        if cos_l < 1.0e-7:
            return ls
        ls.h = h
        if spherical:
            ls.pdf = prob * pc / omega
        else:
            ls.pdf = prob * pc * float(n * n) / (0.5 * area2) * dist * dist / cos_l
        ls.t_max = dist - offset_eps(pl, geo.extent) / wp.max(cos_l, 0.05)
        return ls

    @wp.func(inline=True)
    def pdf_li(geo: Geometry, lights: Lights, h: Hit, o: wp.vec3, d: wp.vec3) -> float:
        g = geo.face_offset[h.index] + h.face
        first = int(-1)
        if g < lights.triangle.texel.first.shape[0]:
            first = lights.triangle.texel.first[g]
        if first < 0:
            return pdf_plain(geo, lights, h, o, d)
        prob = lights.triangle.face_prob[g]
        cos_l = wp.abs(wp.dot(h.normal, d))
        if prob <= 0.0 or cos_l < 1.0e-7:
            return 0.0
        n = lights.triangle.texel.n[g]
        slot = cell_of(n, h.u, h.v)
        pc = lights.triangle.texel.prob[first + slot]
        if pc <= 0.0:
            return 0.0
        mid = geo.mesh_ids[h.index]
        p0 = wp.mesh_get_point(mid, 3 * h.face)
        p1 = wp.mesh_get_point(mid, 3 * h.face + 1)
        p2 = wp.mesh_get_point(mid, 3 * h.face + 2)
        q0 = at_bary(p0, p1, p2, cell_corner(n, slot, 0))
        q1 = at_bary(p0, p1, p2, cell_corner(n, slot, 1))
        q2 = at_bary(p0, p1, p2, cell_corner(n, slot, 2))
        omega = triangle_solid_angle(q0, q1, q2, o)
        if use_solid_angle(omega):
            return prob * pc / omega
        area = 0.5 * wp.length(wp.cross(p1 - p0, p2 - p0)) / float(n * n)
        return prob * pc * (h.t * h.t / cos_l) / area

    return SimpleNamespace(sample_li=sample_li, pdf_li=pdf_li)


# ---------------------------------------------------------------------------------------------
# Host side


def cell_of_np(n: int, bu: np.ndarray, bv: np.ndarray) -> np.ndarray:
    """:func:`cell_of` for arrays (float64)."""
    a, b = bu * n, bv * n
    i = np.clip(np.floor(a).astype(np.int64), 0, n - 1)
    j = np.clip(np.floor(b).astype(np.int64), 0, n - 1 - i)
    up = (i + j < n - 1) & ((a - i) + (b - j) > 1.0)
    return 2 * (i * n + j) + up


def fine_points(m: int) -> np.ndarray:
    """The centroids (k, 2) of the order-m subdivision's cells: barycentrics (u, v)."""
    i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
    low = (i + j <= m - 1)
    upp = (i + j <= m - 2)
    pts = [np.stack([(i[low] + 1 / 3) / m, (j[low] + 1 / 3) / m], 1),
           np.stack([(i[upp] + 2 / 3) / m, (j[upp] + 2 / 3) / m], 1)]
    return np.concatenate(pts)


def order(uv: np.ndarray, shape: tuple[int, int]) -> int:
    """The order n for a triangle of corner uv ``uv`` (3, 2) on a texture of ``shape`` (H, W): about
    one texel a cell, at most MAX_N; 1 below two texels."""
    e1, e2 = uv[1] - uv[0], uv[2] - uv[0]
    texels = 0.5 * abs(e1[0] * e2[1] - e1[1] * e2[0]) * shape[0] * shape[1]
    if not np.isfinite(texels) or texels < 2.0:
        return 1
    return int(min(MAX_N, np.ceil(np.sqrt(texels))))


def cells(scene: Scene, mesh: np.ndarray, face: np.ndarray, weights: np.ndarray):
    """For the light triangles (``mesh``, ``face``, choice ``weights``) whose emission is an image
    texture: their cells. Returns (weights with those triangles' replaced by 2 x area x the cells'
    mean luminance, {entry index: (n, per-slot weights)})."""
    mt = scene.materials
    out = weights.copy()
    table: dict[int, tuple[int, np.ndarray]] = {}
    slots = 0
    for e in range(len(face)):
        m = scene.meshes[mesh[e]]
        mat = m.face_material[face[e]]
        k = int(mt.tex[mat, SLOT_EMISSION])
        if k < 0:
            continue
        image = scene.textures[k]
        cuv = m.corner_uv[face[e]].astype(np.float64)
        n = order(cuv, image.shape[:2])
        if n <= 1 or slots + 2 * n * n > MAX_SLOTS:
            continue
        s = max(1, 64 // n)           # points per cell edge: at most a 64 x 64 grid per triangle
        b = fine_points(n * s)
        uv = cuv[0] * b[:, :1] + cuv[1] * b[:, 1:] + cuv[2] * (1 - b[:, :1] - b[:, 1:])
        lum = sample_texture_np(image, uv).astype(np.float64).mean(axis=1)
        slot = cell_of_np(n, b[:, 0], b[:, 1])
        total = np.bincount(slot, lum, minlength=2 * n * n)
        count = np.bincount(slot, minlength=2 * n * n)
        mean = np.where(count > 0, total / np.maximum(count, 1), 0.0)
        tri_mean = lum.mean()
        if not tri_mean > 0:
            continue
        p = m.positions[m.indices[face[e]]].astype(np.float64)
        area = 0.5 * np.linalg.norm(np.cross(p[1] - p[0], p[2] - p[0]))
        out[e] = 2.0 * area * tri_mean
        table[e] = (n, np.where(count > 0, mean + FLOOR * tri_mean, 0.0))
        slots += 2 * n * n
    return out, table


def upload(table: dict, global_face: np.ndarray, num_faces: int, device: str) -> TexelLights:
    """The device cells (``table`` from :func:`cells`; ``global_face``: each entry's global face)."""
    first = np.full(max(num_faces, 1) if table else 1, -1, np.int32)    # the kernels check the length
    n_of = np.zeros(len(first), np.int32)
    cdf, prob = [], []
    at = 0
    for e, (n, w) in sorted(table.items()):
        c = np.cumsum(w) / w.sum()
        c = c.astype(np.float32)
        c[-1] = 1.0
        last = np.nonzero(w > 0)[0][-1]
        c[last:] = 1.0
        cdf.append(c)
        prob.append(np.diff(np.concatenate([[0.0], c.astype(np.float64)])))     # what pick_cell gives
        first[global_face[e]] = at
        n_of[global_face[e]] = n
        at += len(w)
    t = TexelLights()
    t.first = device_array(first, wp.int32, np.int32, device)
    t.n = device_array(n_of, wp.int32, np.int32, device)
    t.cdf = device_array(np.concatenate(cdf) if cdf else np.zeros(0), wp.float32, np.float32, device)
    t.prob = device_array(np.concatenate(prob) if prob else np.zeros(0), wp.float32, np.float32, device)
    return t
