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

A cell's weight is its mean emitted luminance (mean over RGB, nearest texels at s x s jittered
points per cell, about half a texel apart) plus 1% of the triangle's mean, so that no cell that
might emit (a bilinear filter bleeds across a black texel's edge) has density 0. Within the chosen
cell a point is drawn as the triangle sampler draws one on a whole triangle: uniformly in solid angle where the cell subtends a
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

from warp_spt.accel.ray_queries import KIND_TRIANGLE, Hit
from warp_spt.emitters.base import LightSample, device_array, sample_at
from warp_spt.device.sampling import spherical_triangle_sample, triangle_solid_angle
from warp_spt.device.structs import Geometry
from warp_spt.device.textures import sample_texture_np
from warp_spt.scene.model import SLOT_EMISSION, Scene

MAX_N = 32                 # cells per edge at most (2 n^2 table slots per triangle)
MAX_SLOTS = 1 << 18        # table slots for the whole scene; triangles past it keep uniform sampling
                           # (it also bounds the weights' texture lookups: 4.5 a slot, 18 for cells of
                           # MAX_N, a second or three of numpy at most; a screen of 32 x 32 cells a
                           # triangle fits 128 triangles, one of 2 x 2 cells 32,768)
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
        return sample_at(h, pl, x, spherical, prob * pc, omega, prob * pc * float(n * n), area2, geo.extent)

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


def fine_points(m: int, jitter: bool = False) -> np.ndarray:
    """One point (k, 2) in each cell of the order-m subdivision, barycentrics (u, v): its centroid, or
    with ``jitter`` a point drawn uniformly in its inner 90% (a fixed seed: the same points every
    time), which turns the regular grid's aliasing against the texel grid (a texel caught by 4 points
    or by 9) into a small unbiased noise."""
    i, j = np.meshgrid(np.arange(m), np.arange(m), indexing="ij")
    low = (i + j <= m - 1)
    upp = (i + j <= m - 2)
    pts = np.concatenate([np.stack([(i[low] + 1 / 3) / m, (j[low] + 1 / 3) / m], 1),
                          np.stack([(i[upp] + 2 / 3) / m, (j[upp] + 2 / 3) / m], 1)])
    if not jitter:
        return pts
    k = low.sum()
    r = np.random.default_rng(12345).random((len(pts), 2))
    fold = r.sum(axis=1) > 1
    r[fold] = 1 - r[fold]
    edge = np.full((len(pts), 2, 2), 1.0 / m)           # the cell's two edge vectors from its first corner
    edge[:, 0, 1] = edge[:, 1, 0] = 0.0
    edge[k:] *= -1.0                                    # upper cells point the other way
    first = pts - (edge[:, 0] + edge[:, 1]) / 3         # centroid = first corner + (e1 + e2) / 3
    p = first + r[:, :1] * edge[:, 0] + r[:, 1:] * edge[:, 1]
    return pts + 0.9 * (p - pts)


def footprint(uv: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The texels covered by triangles of corner uv ``uv`` (..., 3, 2) on a texture of ``shape``."""
    uv = np.asarray(uv, dtype=np.float64)
    e1, e2 = uv[..., 1, :] - uv[..., 0, :], uv[..., 2, :] - uv[..., 0, :]
    texels = 0.5 * np.abs(e1[..., 0] * e2[..., 1] - e1[..., 1] * e2[..., 0]) * shape[0] * shape[1]
    return np.where(np.isfinite(texels), texels, 0.0)


def order(uv: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The order n of triangles of corner uv ``uv`` (..., 3, 2) on a texture of ``shape`` (H, W):
    about one texel a cell, at most MAX_N; 1 below two texels."""
    texels = footprint(uv, shape)
    return np.where(texels < 2.0, 1, np.minimum(MAX_N, np.ceil(np.sqrt(np.maximum(texels, 1.0))))).astype(np.int64)


def _cell_means(image: np.ndarray, cuv: np.ndarray, n: int) -> np.ndarray:
    """(E, 2 n^2): the mean luminance of each cell of E triangles of order n (corner uv ``cuv`` (E, 3,
    2)), nearest texels at s x s points a cell, spaced at most about half a texel (s = 3 for a cell of a
    texel or less; up to 6 for the larger cells of MAX_N), so that a cell partly over a bright texel is
    not weighed as if it missed it (its samples would then be rare and bright: a firefly); 0 for slots
    that are not a cell."""
    per_cell = float(footprint(cuv, image.shape[:2]).max()) / (n * n)
    s = int(np.clip(np.ceil(3.0 * np.sqrt(per_cell)), 3, 6))
    b = fine_points(n * s, jitter=True)
    slot = cell_of_np(n, b[:, 0], b[:, 1])
    by_cell = np.argsort(slot, kind="stable")       # s^2 points to a cell (fine_points' subdivision)
    cells_ = np.unique(slot)
    out = np.zeros((len(cuv), 2 * n * n))
    chunk = max(1, (1 << 20) // len(b))          # at most about a million lookups at a time
    for lo in range(0, len(cuv), chunk):
        c = cuv[lo:lo + chunk]
        uv = (c[:, None, 0] * b[None, :, :1] + c[:, None, 1] * b[None, :, 1:]
              + c[:, None, 2] * (1 - b[None, :, :1] - b[None, :, 1:]))
        lum = sample_texture_np(image, uv.reshape(-1, 2)).astype(np.float64).mean(axis=1).reshape(len(c), -1)
        out[lo:lo + chunk, cells_] = lum[:, by_cell].reshape(len(c), len(cells_), s * s).mean(axis=2)
    return out


def cells(scene: Scene, mesh: np.ndarray, face: np.ndarray, weights: np.ndarray):
    """For the light triangles (``mesh``, ``face``, choice ``weights``) whose emission is an image
    texture: their cells. Returns (weights with those triangles' replaced by 2 x area x the cells'
    mean luminance, {entry index: (n, per-slot weights)})."""
    out = weights.copy()
    table: dict[int, tuple[int, np.ndarray]] = {}
    if not len(face):
        return out, table
    tex = np.full(len(face), -1, np.int64)
    cuv = np.zeros((len(face), 3, 2))
    area = np.zeros(len(face))
    for k in np.unique(mesh):       # gathered mesh by mesh (few), vectorised within
        sel = mesh == k
        m = scene.meshes[k]
        tex[sel] = scene.materials.tex[m.face_material[face[sel]], SLOT_EMISSION]
        cuv[sel] = m.corner_uv[face[sel]]
        p = m.positions[m.indices[face[sel]]].astype(np.float64)
        area[sel] = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    n = np.ones(len(face), np.int64)
    for k in np.unique(tex[tex >= 0]):
        sel = tex == k
        n[sel] = order(cuv[sel], scene.textures[k].shape[:2])
    n[tex < 0] = 1
    slots = np.where(n > 1, 2 * n * n, 0)
    n[np.cumsum(slots) > MAX_SLOTS] = 1          # past the budget: uniform sampling, as before
    for k in np.unique(tex[n > 1]):
        for order_n in np.unique(n[(tex == k) & (n > 1)]):
            (idx,) = np.nonzero((tex == k) & (n == order_n))
            means = _cell_means(scene.textures[k], cuv[idx], int(order_n))
            valid = means.sum(axis=1) > 0
            m_all = np.zeros(2 * order_n * order_n, bool)        # the slots that are cells
            m_all[np.unique(cell_of_np(int(order_n), *fine_points(int(order_n)).T))] = True
            tri_mean = means[:, m_all].mean(axis=1)
            for j in np.nonzero(valid)[0]:
                e = int(idx[j])
                out[e] = 2.0 * area[e] * tri_mean[j]
                table[e] = (int(order_n), np.where(m_all, means[j] + FLOOR * tri_mean[j], 0.0))
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
