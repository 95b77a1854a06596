"""The boundary term of secondary visibility at the paths' vertices: shadows' edges, and the outlines
a surface sees, by edge sampling on the sphere of directions.

The light a path's vertex x sends back, ``L_o(x) = integral f(x, w) cos L_in(x, w) dw``, jumps
where ``w`` crosses a curve of the sphere of directions at x: an object's outline as seen from x (an
occluder in front of a light, of the sky, of another surface), its border, a crease, or a sphere's
silhouette cone. When a parameter moves such a curve, ``L_o`` gains (Reynolds' theorem on the sphere)

    integral over the curves of f(x, w) cos (L_in_minus - L_in_plus) (n . dw/dtheta) dl

with ``n`` the curve's unit normal on the sphere. A straight edge seen from x is a great-circle arc
(the angle between its ends' directions is its length), and the direction to its point X moves as
``dw = (I - w w^T)(dX - dx) / |X - x|``: the curve moves when the occluder moves (X) and when the
receiver does (x slides along its incoming ray as its surface, or the camera, moves). So, per
pixel, ``secondary_spp`` paths are traced: each gives its camera ray's hit and, where ``max_depth``
leaves room, one later vertex of a depth drawn uniformly in 2..``secondary_depth`` (weighted by the
number of depths; the path's throughput up to it multiplies its f cos). A kernel returns the
receivers' points, normals, throughputs and primitives;
for each the host lists the candidate curves for that x (the edges whose faces face opposite ways from
x, borders, creases, sphere cones, as ``diff.boundary`` does for the eye) with their arc lengths, and
draws one point by length (density 1 / total length, exact); the kernel then evaluates the surface's
``f cos`` towards it and traces two paths from x, 1e-4 radian to either side of the curve, with the
integrator's own step and the same random numbers. The sample becomes two forces
(``diff.forces``): ``w n / |X - x|`` on the curve's point X (an edge's blend of two vertices, or a
sphere's tangency point) and its opposite on x, taken to x's own surface point by the ray-space rule
``dx = d (n_x . v) / (n_x . d)``; the camera's own term moves x directly.

A deeper receiver moves with its own surface along its incoming ray, the vertex before it held
(the camera's motion reaches the camera rays' hits alone): exact where what moves is an occluder,
a lamp or the receiver's own surface, not where an earlier vertex's motion swings the ray that
reaches it (docs/gradients.md, Limits).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_spt.device.lobes import LOBE_TRANSMISSION
from warp_spt.diff.boundary import Projection, camera_derivative, mesh_edges
from warp_spt.diff.boundary_paths import BOUNDARY, STAGE_LIGHTING, STAGE_RECEIVERS
from warp_spt.diff.forces import Forces
from warp_spt.rendering.setup import Bound

ANGLE_OFFSET = 1e-4        # radians either side of the curve for the two paths
SEED_SALT = 0x5EC0_0D      # the receivers' random numbers are not the image's
CHUNK = 1 << 16            # (receivers x edges) entries per block of the host's arrays


# ------------------------------------------------------------------------------------------------
# The host: receivers, their curves, one sample each


def _launch(bound: Bound, stage: int, pix, sample, steps, dirs, rp, seed2):
    dev = bound.dev
    n = len(pix)
    first = stage == STAGE_RECEIVERS
    rec = wp.zeros(5 * n if first else 1, dtype=wp.vec3, device=dev.device)
    info = wp.zeros(n if first else 1, dtype=wp.vec4i, device=dev.device)
    bary = wp.zeros(n if first else 1, dtype=wp.vec2, device=dev.device)
    out = wp.zeros(3 * n if not first else 1, dtype=wp.vec3, device=dev.device)
    apex = wp.zeros(n if first else 1, dtype=wp.vec3, device=dev.device)
    d = wp.array(dirs.astype(np.float32), dtype=wp.vec3, device=dev.device) if dirs is not None else \
        wp.zeros(1, dtype=wp.vec3, device=dev.device)
    wp.launch(BOUNDARY.build(bound), dim=n, device=dev.device, inputs=[
        *bound.scene_args(rp), stage, wp.uint32(seed2), wp.array(pix.astype(np.int32), dtype=wp.int32, device=dev.device),
        wp.array(sample.astype(np.int32), dtype=wp.int32, device=dev.device),
        wp.array(steps.astype(np.int32), dtype=wp.int32, device=dev.device), d, rec, info, bary, apex, out])
    return rec, info, bary, apex, out


EXACT_EDGES = 256          # a block of at most this many edges is weighed by its exact arc lengths


@dataclass
class Block:
    """One placement of a mesh (world vertex positions, faces and their normals, edges) or one sphere
    (``centre``, ``radius``): what the receivers' curves are drawn from, block by block."""

    sphere: bool
    index: int
    placement: int = 0
    edges: object = None
    tri: np.ndarray | None = None
    nrm: np.ndarray | None = None
    a: np.ndarray | None = None
    b: np.ndarray | None = None
    centre: np.ndarray | None = None
    radius: float = 0.0
    length: float = 0.0


def blocks_of(scene, reads_normals: bool, topology: dict) -> list[Block]:
    out = []
    for k, m in enumerate(scene.meshes):
        if not len(m.indices):
            continue
        if k not in topology:
            topology[k] = mesh_edges(m, reads_normals)
        e = topology[k]
        f = np.asarray(m.indices)
        for j in range(m.placements):
            pos = np.asarray(m.world_part(j)[0], dtype=np.float64)
            tri = pos[f]
            lo, hi = pos.min(axis=0), pos.max(axis=0)
            a, b = pos[e.verts[:, 0]], pos[e.verts[:, 1]]
            out.append(Block(False, k, j, e, tri, np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), a, b,
                             0.5 * (lo + hi), 0.5 * float(np.linalg.norm(hi - lo)),
                             float(np.linalg.norm(b - a, axis=1).sum())))
    for j, sph in enumerate(np.asarray(scene.spheres, dtype=np.float64).reshape(-1, 4)):
        out.append(Block(True, j, centre=sph[:3], radius=float(sph[3])))
    return out


def _arcs(blk: Block, x: np.ndarray, up: np.ndarray | None) -> np.ndarray:
    """(M, E) the arc length of each edge of ``blk`` seen from each receiver, 0 where the edge is not
    a candidate there (not a silhouette, border or crease for that x; or, with ``up``, wholly below
    the receiver's surface); (M, 1) a sphere's cone length 2 pi sin(alpha)."""
    if blk.sphere:
        dist = np.linalg.norm(blk.centre - x, axis=1)
        sin_a = np.where(dist > blk.radius * (1 + 1e-9), blk.radius / np.maximum(dist, 1e-300), 0.0)
        if up is not None:
            sin_a = np.where(np.sum((blk.centre - x) * up, axis=1) > -blk.radius, sin_a, 0.0)
        return (2.0 * np.pi * sin_a)[:, None]
    e = blk.edges
    fixed = (e.faces[:, 1] < 0) | e.crease | e.many
    f0, f1 = e.faces[:, 0], np.maximum(e.faces[:, 1], 0)
    phi = np.zeros((len(x), len(e.verts)))
    chunk = max(1, CHUNK // max(len(e.verts), len(blk.tri)))
    for lo in range(0, len(x), chunk):
        xs = x[lo:lo + chunk]
        facing = np.sign(np.einsum("mfk,fk->mf", xs[:, None, :] - blk.tri[None, :, 0], blk.nrm))
        cand = fixed[None] | (facing[:, f0] * facing[:, f1] <= 0)
        av, bv = blk.a[None] - xs[:, None], blk.b[None] - xs[:, None]
        ang = np.arctan2(np.linalg.norm(np.cross(av, bv), axis=2), np.sum(av * bv, axis=2))
        if up is not None:
            nu = up[lo:lo + chunk, None, :]
            cand &= (np.sum(av * nu, axis=2) > 0) | (np.sum(bv * nu, axis=2) > 0)
        phi[lo:lo + chunk] = np.where(cand & (ang < np.pi - 1e-6), ang, 0.0)
    return phi


def _weight_of(blk: Block, x: np.ndarray, up: np.ndarray | None):
    """((M,) what a block is chosen by, its arcs (M, E) where they were computed): its exact total arc
    length (small blocks, spheres), else a bound of it that is never 0 where the total is not: an edge
    seen from farther than d subtends at most its length / d (and at most pi); 0 where the block lies
    wholly below the receiver's surface."""
    if blk.sphere or len(blk.edges.verts) <= EXACT_EDGES:
        arcs = _arcs(blk, x, up)
        return arcs.sum(axis=1), arcs
    dist = np.linalg.norm(blk.centre - x, axis=1) - blk.radius
    bound = np.minimum(blk.length / np.maximum(dist, 1e-12), np.pi * len(blk.edges.verts))
    if up is not None:
        bound = np.where(np.sum((blk.centre - x) * up, axis=1) > -blk.radius, bound, 0.0)
    return bound, None


def _basis(axis: np.ndarray):
    """Two unit vectors orthogonal to ``axis`` (N, 3) and to each other."""
    helper = np.eye(3)[np.argmin(np.abs(axis), axis=1)]
    u = np.cross(axis, helper)
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    return u, np.cross(axis, u)


def receiver_depth(depth: int | None, max_depth: int) -> int:
    """The deepest receiver (``secondary_depth``): 1 the camera rays' hits alone; default, and at
    most, ``max_depth - 1`` (a receiver needs a bounce after it)."""
    top = max(1, max_depth - 1)
    if depth is None:
        return top
    if isinstance(depth, bool) or not isinstance(depth, (int, np.integer)) or depth < 1:
        raise ValueError(f"secondary_depth must be an integer >= 1, got {depth!r}")
    return min(int(depth), top)


def secondary_term(bound: Bound, adjoint: np.ndarray, wanted: list, spp: int, seed: int,
                   topology: dict | None = None, depth: int | None = None):
    """(Forces on the geometry's points, {camera parameter name: gradient}): the boundary term of
    secondary visibility at the paths' vertices up to ``depth`` (``receiver_depth``; the module
    docstring)."""
    rs = bound.settings
    cams = {p.name: np.zeros(3) for p in wanted if p.kind == "camera"}
    deepest = receiver_depth(depth, rs.max_depth)
    if spp <= 0 or rs.max_depth < 2:
        return Forces.empty(), cams
    w, h = rs.width, rs.height
    scene = bound.dev.scene
    pix = np.repeat(np.arange(w * h), spp)
    sample = np.tile(np.arange(spp), w * h)
    a_img = adjoint.reshape(-1, 3)[pix]
    keep = np.any(a_img != 0, axis=1)
    pix, sample, a_img = pix[keep], sample[keep], a_img[keep]
    if not len(pix):
        return Forces.empty(), cams
    # each sample's camera-ray hit, and (deeper receivers) the vertex at a depth drawn uniformly in
    # 2..deepest, weighted by the number of depths: one unbiased estimate of the sum over them
    steps = np.zeros(len(pix), np.int64)
    scale = np.ones(len(pix))
    if deepest >= 2:
        drawn = np.random.default_rng([seed, SEED_SALT, 2]).integers(1, deepest, len(pix))
        pix, sample, a_img = np.concatenate([pix, pix]), np.concatenate([sample, sample]), np.concatenate([a_img, a_img])
        steps = np.concatenate([steps, drawn])
        scale = np.concatenate([scale, np.full(len(drawn), float(deepest - 1))])
    rp = bound.params(0, count=1, seed=(seed ^ SEED_SALT) & 0x7FFFFFFF)
    rec, info, bary, apex, _ = _launch(bound, STAGE_RECEIVERS, pix, sample, steps, None, rp, 0)
    rec, info, bary = rec.numpy().astype(np.float64).reshape(-1, 5, 3), info.numpy(), bary.numpy().astype(np.float64)
    apex = apex.numpy().astype(np.float64)
    hit = info[:, 0] >= 0
    rows = np.flatnonzero(hit)
    if not len(rows):
        return Forces.empty(), cams
    o, d, surf, nx = (rec[rows, k] for k in range(4))
    x = apex[rows]        # the directions' apex (the curves are seen from there); surf: the surface point
    opaque = not (int(bound.features.lobes) & int(LOBE_TRANSMISSION))
    up = nx if opaque else None
    blocks = blocks_of(scene, bound.dev.geometry.has_corner_normals != 0, {} if topology is None else topology)
    if not blocks:
        return Forces.empty(), cams
    # two levels: a block by its weight (exact or a bound), then an edge of it by its exact arc length
    weighed = [_weight_of(b, x, up) for b in blocks]
    weights = np.stack([w_ for w_, _ in weighed], axis=1)
    total_w = weights.sum(axis=1)
    live = total_w > 0
    rows, o, d, x, surf, nx, weights, total_w = (rows[live], o[live], d[live], x[live], surf[live], nx[live],
                                                 weights[live], total_w[live])
    cached = [None if a is None else a[live] for _, a in weighed]
    up = nx if opaque else None
    if not len(rows):
        return Forces.empty(), cams
    rng = np.random.default_rng([seed, SEED_SALT])
    u_block, u_edge = rng.random(len(rows)), rng.random(len(rows))
    cum = np.cumsum(weights, axis=1)
    chosen = np.minimum((cum <= (u_block * total_w)[:, None]).sum(axis=1), len(blocks) - 1)
    n_r = len(rows)
    omega, pole, point = np.zeros((n_r, 3)), np.zeros((n_r, 3)), np.zeros((n_r, 3))
    inv_density = np.zeros(n_r)            # 1 / (the sample's density per radian of curve)
    is_sph = np.zeros(n_r, bool)
    index, place = np.zeros(n_r, np.int64), np.zeros(n_r, np.int64)
    vids, blend = np.zeros((n_r, 3), np.int64), np.zeros((n_r, 3))
    for bi, blk in enumerate(blocks):
        r = np.flatnonzero(chosen == bi)
        if not len(r):
            continue
        arcs = cached[bi][r] if cached[bi] is not None else _arcs(blk, x[r], None if up is None else up[r])
        tot = arcs.sum(axis=1)
        inv_density[r] = np.where(tot > 0, tot * total_w[r] / np.maximum(weights[r, bi], 1e-300), 0.0)
        is_sph[r], index[r], place[r] = blk.sphere, blk.index, blk.placement
        c = np.cumsum(arcs, axis=1)
        col = np.minimum((c <= (u_edge[r] * tot)[:, None]).sum(axis=1), arcs.shape[1] - 1)
        ang = arcs[np.arange(len(r)), col]
        frac = np.clip((u_edge[r] * tot - (c[np.arange(len(r)), col] - ang)) / np.maximum(ang, 1e-300), 0.0, 1.0)
        if blk.sphere:      # its silhouette cone, by angle
            v = blk.centre - x[r]
            dist = np.linalg.norm(v, axis=1, keepdims=True)
            axis = v / dist
            sin_a = blk.radius / dist
            cos_a = np.sqrt(np.maximum(0.0, 1.0 - sin_a * sin_a))
            u1, u2 = _basis(axis)
            ph = 2.0 * np.pi * frac[:, None]
            om = cos_a * axis + sin_a * (np.cos(ph) * u1 + np.sin(ph) * u2)
            pl = axis - np.sum(axis * om, axis=1, keepdims=True) * om          # towards the cone's axis
            pl /= np.linalg.norm(pl, axis=1, keepdims=True)
            omega[r], pole[r] = om, pl
            point[r] = x[r] + om * np.sqrt(np.maximum(0.0, dist ** 2 - blk.radius ** 2))
            continue
        # an edge: the arc between its ends' directions, slerped
        ca, cb = blk.a[col], blk.b[col]
        av, bv = ca - x[r], cb - x[r]
        ah = av / np.linalg.norm(av, axis=1, keepdims=True)
        bh = bv / np.linalg.norm(bv, axis=1, keepdims=True)
        t = frac[:, None]
        sa = np.maximum(np.sin(ang), 1e-300)[:, None]
        om = (np.sin((1 - t) * ang[:, None]) * ah + np.sin(t * ang[:, None]) * bh) / sa
        om /= np.maximum(np.linalg.norm(om, axis=1, keepdims=True), 1e-300)
        pl = np.cross(ah, bh)
        pl /= np.maximum(np.linalg.norm(pl, axis=1, keepdims=True), 1e-300)
        ed = cb - ca
        c1, c2 = np.cross(av, om), np.cross(ed, om)
        sb = np.clip(-np.sum(c1 * c2, axis=1) / np.maximum(np.sum(c2 * c2, axis=1), 1e-300), 0.0, 1.0)
        omega[r], pole[r], point[r] = om, pl, ca + sb[:, None] * ed
        vids[r] = np.stack([blk.edges.verts[col, 0], blk.edges.verts[col, 1], blk.edges.verts[col, 0]], axis=1)
        blend[r] = np.stack([1.0 - sb, sb, np.zeros_like(sb)], axis=1)
    valid = inv_density > 0
    omega[~valid] = d[~valid]             # nothing to sample there: a placeholder ray, weight 0
    pole[~valid] = 0.0
    dirs = np.empty((len(rows), 3, 3))
    dirs[:, 0] = omega
    for k, sgn in ((1, -1.0), (2, 1.0)):
        dd = omega + sgn * ANGLE_OFFSET * pole
        dirs[:, k] = dd / np.linalg.norm(dd, axis=1, keepdims=True)
    *_, out = _launch(bound, STAGE_LIGHTING, pix[rows], sample[rows], steps[rows], dirs.reshape(-1, 3), rp,
                      (seed * 2654435761 + 1) & 0x7FFFFFFF)
    out = out.numpy().astype(np.float64).reshape(-1, 3, 3)
    fcos, dl = out[:, 0], out[:, 1] - out[:, 2]                # throughput x f cos; L_minus - L_plus
    wgt = np.sum(a_img[rows] * fcos * dl, axis=1) * inv_density * scale[rows] / spp
    rho = np.linalg.norm(point - x, axis=1)
    force = (wgt / np.maximum(rho, 1e-300))[:, None] * pole   # on the curve's point X; its opposite on x
    parts = [Forces(point, force, is_sph, index, place, vids, blend)]
    # the receiver slides along its camera ray as its surface moves: dx = d (n_x . v) / (n_x . d)
    recv = -force
    nd = np.sum(nx * d, axis=1)
    ok = np.abs(nd) > 1e-12
    mat_force = np.where(ok[:, None], (np.sum(recv * d, axis=1) / np.where(ok, nd, 1.0))[:, None] * nx, 0.0)
    rinfo = info[rows]
    r_sph = rinfo[:, 0] == 1
    r_index = rinfo[:, 1].astype(np.int64)
    r_place, r_vids, r_w = _receiver_points(scene, rinfo, bary[rows])
    parts.append(Forces(surf, mat_force, r_sph, r_index, r_place, r_vids, r_w))
    first = steps[rows] == 0                  # the camera moves its rays' hits; deeper ones: Limits
    for p in wanted:
        if p.kind == "camera":
            cams[p.name] = _camera_receivers(p, bound, o[first], d[first], surf[first], nx[first], recv[first])
    return Forces.join(parts), cams


def _receiver_points(scene, info: np.ndarray, bary: np.ndarray):
    """(placement, vertex ids, weights) of the receivers' surface points (a sphere's: unused)."""
    n = len(info)
    place = np.zeros(n, np.int64)
    vids = np.zeros((n, 3), np.int64)
    weights = np.zeros((n, 3))
    firsts = np.cumsum([0] + [m.placements for m in scene.meshes])
    tri = info[:, 0] == 0
    for k, m in enumerate(scene.meshes):
        r = np.flatnonzero(tri & (info[:, 1] == k))
        if not len(r):
            continue
        placed = info[r, 3].astype(np.int64)
        place[r] = np.where(placed > 0, placed - 1 - firsts[k], 0)
        vids[r] = np.asarray(m.indices)[info[r, 2]]
        u, v = bary[r, 0], bary[r, 1]
        weights[r] = np.stack([u, v, 1.0 - u - v], axis=1)   # the point is u p0 + v p1 + (1 - u - v) p2
    return place, vids, weights


def _camera_receivers(p, bound: Bound, o, d, x, nx, recv) -> np.ndarray:
    """The camera parameter's part of the secondary term: its receivers move with its rays
    (x on its surface's plane along the ray through the same pixel point), by central differences."""
    rs = bound.settings
    px = Projection.of(bound.camera, rs.width, rs.height).project(o + d)[0]

    def moved(proj: Projection) -> float:
        dd = proj.direction(px)
        t = np.sum(nx * (x - proj.origin), axis=1) / np.sum(nx * dd, axis=1)
        return float(np.sum(recv * (proj.origin + t[:, None] * dd)))

    return camera_derivative(bound, p.field, moved)
