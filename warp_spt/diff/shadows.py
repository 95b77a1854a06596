"""The boundary term of hard shadows: the curves of the image where a sun's, a point light's or a
spot light's visibility jumps, by edge sampling of the occluders' outlines as the light sees them.

A punctual light is a single direction at each receiver, so its shadow's edge is no curve of the
sphere of directions (``diff.secondary`` samples those) but a curve of the image: the receiver point
y seen through a pixel is lit on one side and shadowed on the other. Reynolds' theorem in the image,
as for the silhouettes (``diff.boundary``), adds

    dI/dθ  +=  integral over the shadow curves of (L_minus - L_plus) (n . du/dθ) dl

where the curve's point u is the camera's image of y, and y the point where the ray from the light
through a point X of an occluder's outline (an edge whose faces face opposite ways from the light, or
a border) meets the surface behind it. So, per light, ``boundary_spp`` x pixels points X are drawn
by length along the outlines (density 1 / total length), the ray through each is traced (the
``boundary`` kernel kind, stage 3) to its receiver y, y is kept where the camera sees it (its camera
ray's first hit is y), and its image u, the curve's image tangent (y moves over its receiver's plane
as X slides along the edge) and normal give the two rays of the pair, a thousandth of a pixel to
either side, traced with the integrator's own step (``diff.boundary._trace_pairs``). The sample's
weight ``adjoint . (L_minus - L_plus) x total length x |du/dl|`` then gives

* the light's own parameter (a point or spot light's ``position``, a sun's ``direction``): the weight
  times ``n . J dy/dθ``, y's motion over its receiver's plane by central differences of the smooth
  map (the receiver held where it is);
* the occluder: a force ``weight (J dy/dX)^T n`` on X (a blend of its edge's two vertices), which
  ``diff.forces`` takes to the occluder's positions and pose.

Not estimated (docs/gradients.md, Limits): spheres as occluders, the receiver's own motion (a floor
moved under a fixed shadow), and a sun of non-zero radius (its penumbra is a smooth ramp, no jump).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_spt.accel.surface import OFFSET_ABS, OFFSET_REL
from warp_spt.diff.boundary import Projection, _trace_pairs
from warp_spt.diff.boundary_paths import BOUNDARY, STAGE_RAYS
from warp_spt.diff.forces import Forces
from warp_spt.diff.secondary import blocks_of
from warp_spt.rendering.setup import Bound
from warp_spt.scene.lights import KIND_SUN, punctual_lights

SEED_SALT = 0x5AD0_3D      # the shadows' random numbers are not the image's nor the other terms'
STEP = 1e-6                # central differences of the receiver-plane map, relative to the scene's extent
SEEN = 1e-4                # a camera ray's hit within this x the extent of y: the camera sees y


def _hits(bound: Bound, origins: np.ndarray, dirs: np.ndarray):
    """(points (N, 3), geometric normals (N, 3), hit (N,) bool): the first hits of the rays."""
    dev = bound.dev
    n = len(origins)
    if not n:
        return np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, bool)
    v3 = lambda a: wp.array(np.asarray(a, np.float32), dtype=wp.vec3, device=dev.device)    # noqa: E731
    info = wp.zeros(n, dtype=wp.vec4i, device=dev.device)
    point = wp.zeros(n, dtype=wp.vec3, device=dev.device)
    normal = wp.zeros(n, dtype=wp.vec3, device=dev.device)
    one_i = wp.zeros(1, dtype=wp.int32, device=dev.device)
    rp = bound.params(0, count=1, seed=0)
    wp.launch(BOUNDARY.build(bound), dim=n, device=dev.device, inputs=[
        *bound.scene_args(rp), STAGE_RAYS, wp.uint32(0), one_i, one_i, one_i, v3(dirs), v3(origins),
        info, wp.zeros(1, dtype=wp.vec2, device=dev.device), point, normal])
    return (point.numpy().astype(np.float64), normal.numpy().astype(np.float64), info.numpy()[:, 0] >= 0)


def _receiver_point(light: np.ndarray, sun: bool, x: np.ndarray, y0: np.ndarray, ng: np.ndarray,
                    eps: np.ndarray) -> np.ndarray:
    """The receiver's point (on its plane through y0, normal ng) whose shadow ray grazes X: the
    renderer's shadow rays leave from ``eps`` off the surface along ng (``offset_origin``, up to a
    pixel's thousandth here, as much as the pair's offset), so the ray from the light through X
    meets that offset plane, and the point is the one below it. From a position the ray runs along
    X - light, from a sun (``light``: towards it, any length) along -light."""
    d = -light / np.linalg.norm(light, axis=-1, keepdims=True) if sun else x - light
    start = x if sun else light
    off = ng * eps[:, None]
    s = np.sum(ng * (y0 + off - start), axis=-1, keepdims=True) / np.sum(ng * d, axis=-1, keepdims=True)
    return start + s * d - off


def _outlines(blocks, light: np.ndarray, sun: bool):
    """(a (E, 3), b (E, 3), mesh, placement, vertex pairs (E, 2)): the edges of every mesh placement
    that outline it as the light sees it (faces facing opposite ways, or a border)."""
    out = []
    for blk in blocks:
        if blk.sphere:
            continue
        e = blk.edges
        toward = np.broadcast_to(light, blk.tri[:, 0].shape) if sun else light - blk.tri[:, 0]
        facing = np.sign(np.sum(toward * blk.nrm, axis=1))
        f0, f1 = e.faces[:, 0], np.maximum(e.faces[:, 1], 0)
        cand = (e.faces[:, 1] < 0) | e.many | (facing[f0] * facing[f1] <= 0)
        r = np.flatnonzero(cand)
        out.append((blk.a[r], blk.b[r], np.full(len(r), blk.index), np.full(len(r), blk.placement), e.verts[r]))
    if not out:
        return None
    return tuple(np.concatenate(parts) for parts in zip(*out))


def shadow_term(bound: Bound, adjoint: np.ndarray, wanted: list, spp: int, seed: int,
                topology: dict | None = None):
    """(Forces on the occluders' points, {light parameter name: gradient}): the boundary term of the
    punctual lights' shadows (the module docstring) for the parameters ``wanted``."""
    rs = bound.settings
    scene = bound.dev.scene
    lights = punctual_lights(scene.lights)
    grads = {p.name: np.zeros(3) for p in wanted if p.kind == "punctual" and p.field in ("position", "direction")}
    wants_geometry = any(p.kind not in ("punctual", "camera") for p in wanted)
    if spp <= 0 or not lights or not (grads or wants_geometry):
        return Forces.empty(), grads
    w, h = rs.width, rs.height
    proj = Projection.of(bound.camera, w, h)
    extent = float(bound.dev.geometry.extent)
    blocks = blocks_of(scene, bound.dev.geometry.has_corner_normals != 0, {} if topology is None else topology)
    owner = {p.index // 2: p for p in wanted if p.name in grads}
    parts = []
    rng = np.random.default_rng([seed, SEED_SALT])
    for j, light in enumerate(lights):
        sun = light.kind == KIND_SUN
        if sun and getattr(light, "radius_deg", 0.0) > 0.0:
            continue                       # a disc of directions: its penumbra has no jump
        pos = np.asarray(light.direction if sun else light.position, np.float64)
        lines = _outlines(blocks, pos, sun)
        if lines is None or not len(lines[0]):
            continue
        a, b, mesh, place, verts = lines
        length = np.linalg.norm(b - a, axis=1)
        total = float(length.sum())
        n = spp * w * h
        u = (np.arange(n) + rng.random(n)) / n * total                  # stratified along the outlines
        cum = np.cumsum(length)
        k = np.minimum(np.searchsorted(cum, u, side="right"), len(length) - 1)
        s = np.clip((u - (cum[k] - length[k])) / np.maximum(length[k], 1e-300), 0.0, 1.0)
        x = a[k] + s[:, None] * (b[k] - a[k])
        d = -pos / np.linalg.norm(pos) if sun else x - pos
        d = d / np.linalg.norm(d, axis=-1, keepdims=True)
        d = np.broadcast_to(d, x.shape)
        y0, ng, hit = _hits(bound, x + d * (1e-4 * extent), d)
        px, lam = proj.project(y0)
        inside = hit & (lam > 0) & np.all(np.isfinite(px), axis=1) & (px[:, 0] >= 0) & (px[:, 0] < w) & \
            (px[:, 1] >= 0) & (px[:, 1] < h)
        r = np.flatnonzero(inside)
        if not len(r):
            continue
        seen_at, _, seen_hit = _hits(bound, np.broadcast_to(proj.origin, (len(r), 3)), proj.direction(px[r]))
        r = r[seen_hit & (np.linalg.norm(seen_at - y0[r], axis=1) <= SEEN * extent)]
        pix = np.floor(px[r]).astype(np.int64)
        adj = adjoint[pix[:, 1], pix[:, 0]].astype(np.float64)
        wanted = np.any(adj != 0, axis=1)
        r, adj = r[wanted], adj[wanted]
        if not len(r):
            continue
        xr, nr = x[r], ng[r]
        eps = OFFSET_REL * np.abs(y0[r]).max(axis=1) + OFFSET_ABS * extent      # accel.surface.offset_eps
        y = _receiver_point(pos, sun, xr, y0[r], nr, eps)     # where the renderer's shadow edge lies
        px_r = proj.project(y)[0]
        jac = proj.jacobian(y)
        step = STEP * extent
        # the curve's tangent: y as X slides along its edge
        e = (b[k[r]] - a[k[r]]) / np.maximum(length[k[r], None], 1e-300)
        dy_dl = (_receiver_point(pos, sun, xr + step * e, y, nr, eps) - _receiver_point(pos, sun, xr - step * e, y, nr, eps)) / (2 * step)
        tangent = np.einsum("nij,nj->ni", jac, dy_dl)
        t_len = np.linalg.norm(tangent, axis=1)
        ok = t_len > 0
        normal = np.zeros((len(r), 2))
        normal[ok] = np.stack([-tangent[ok, 1], tangent[ok, 0]], axis=1) / t_len[ok, None]
        rad = _trace_pairs(bound, proj, px_r, normal, seed + 7919 * (j + 1))
        dl = rad[0::2] - rad[1::2]                                   # L_minus - L_plus
        wgt = np.where(ok, np.sum(adj * dl, axis=1) * total * t_len / n, 0.0)

        def rate(fn) -> np.ndarray:
            """(N, 3): n . J dy/dq for each component q of what ``fn(q_offset)`` moves."""
            out = np.zeros((len(r), 3))
            for c in range(3):
                dq = np.zeros(3)
                dq[c] = step
                dy = (fn(dq) - fn(-dq)) / (2 * step)
                out[:, c] = np.einsum("ni,nij,nj->n", normal, jac, dy)
            return out

        p = owner.get(j)
        if p is not None:
            grads[p.name] = grads[p.name] + wgt @ rate(lambda dq: _receiver_point(pos + dq, sun, xr, y, nr, eps))
        if wants_geometry:
            force = wgt[:, None] * rate(lambda dq: _receiver_point(pos, sun, xr + dq, y, nr, eps))
            sr = s[r]
            parts.append(Forces(xr, force, np.zeros(len(r), bool), mesh[k[r]], place[k[r]],
                                np.stack([verts[k[r], 0], verts[k[r], 1], verts[k[r], 0]], axis=1),
                                np.stack([1.0 - sr, sr, np.zeros_like(sr)], axis=1)))
    return Forces.join(parts), grads
