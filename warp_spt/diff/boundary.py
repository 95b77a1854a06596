"""The boundary term of primary visibility: silhouettes and edges seen by the camera, by edge sampling.

The image is ``I_p = integral over pixel p of L(x) dx`` (pixel units: a pixel has area 1). Where ``L``
jumps across a curve of the image plane (an object's silhouette, an open mesh's border, a crease of a
flat-shaded mesh, a change of material) and a parameter moves that curve, Reynolds' transport theorem
adds to the interior derivative (the tape's, which moves hit points along fixed rays) the term

    dI_p/dθ  +=  integral over the curves inside p of (L_minus - L_plus) (n . dx/dθ) dl

with ``n`` the curve's unit normal in the image, ``L_minus`` / ``L_plus`` the radiance just behind /
ahead of it along ``n``, and ``dx/dθ`` the velocity of the curve's point in the image (Li et al. 2018,
redner; Mitsuba 3's projective integrators sample the primary term the same way, with the silhouette
table rebuilt per camera). This module:

1. lists the candidate curves on the host, in float64, for the camera's position: each mesh edge
   whose two faces face opposite ways from the eye (a silhouette), that borders one face only, or
   across which the shading is discontinuous (flat-shaded faces that are not coplanar, different
   materials, corner normals or uvs that differ); and each sphere's silhouette circle. Edges are
   clipped to the space in front of the eye and to the image;
2. draws ``boundary_spp`` samples per pixel along their total length in the image, stratified (one
   uniform number per stratum of the concatenated lengths: the density is 1 / total length on edges,
   and a 64-bin table of each circle's image length there);
3. traces two camera rays per sample, a thousandth of a pixel to either side (``EDGE_OFFSET``), with
   the integrator's own step and the same random numbers for both (the difference of two correlated
   estimates);
4. gives each sample its weight ``adjoint(p) . (L_minus - L_plus) / density`` and turns it into the
   parameters' gradients through the velocity of its point: analytic for vertex positions (the point
   is a fixed blend of the edge's two vertices), central differences of the smooth float64 maps for
   poses, spheres and the camera.

Where an edge is hidden, both rays meet the occluder and the difference is 0: occlusion needs no test.
The thin lens is treated as a pinhole at its centre (the silhouettes' blur across the lens is
ignored: below a pixel for the default aperture of 0.001). Not estimated here: the boundaries seen
by bounces and shadow rays (the shadow's edge moves, secondary visibility), curves where two objects
intersect, and cut-out edges inside triangles; docs/gradients.md, Limits.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import warp as wp

from warp_spt.device.camera_rays import camera_frame
from warp_spt.diff.boundary_paths import BOUNDARY, STAGE_PRIMARY
from warp_spt.diff.forces import Forces
from warp_spt.diff.geometry_params import MESH, SPHERE
from warp_spt.rendering.setup import Bound

EDGE_OFFSET = 1e-3          # pixels either side of the curve for the two rays
SPHERE_BINS = 64            # a silhouette circle's length table
NEAR = 1e-6                 # edges are clipped to depth >= NEAR x the scene's extent before the eye
SEED_SALT = 0x5EED_B0B      # the boundary's random numbers are not the image's


# ------------------------------------------------------------------------------------------------
# The camera's projection (pinhole at the lens centre), float64


@dataclass
class Projection:
    """Pixel coordinates of world points: ``X - origin = lam (corner + x_step px - y_step py)``."""

    origin: np.ndarray
    corner: np.ndarray
    x_step: np.ndarray
    y_step: np.ndarray

    @classmethod
    def of(cls, camera, width: int, height: int) -> "Projection":
        f = camera_frame(camera, width, height)
        return cls(f["origin"], f["to_upper_left"], f["x_step"], f["y_step"])

    def solve(self) -> np.ndarray:
        return np.linalg.inv(np.stack([self.corner, self.x_step, -self.y_step], axis=1))

    def project(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """((N, 2) pixel coordinates, (N,) depth factor lam; lam > 0 in front of the eye)."""
        a = (np.asarray(x, np.float64) - self.origin) @ self.solve().T
        lam = a[..., 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            return a[..., 1:] / lam[..., None], lam

    def jacobian(self, x: np.ndarray) -> np.ndarray:
        """(N, 2, 3): d pixel / d X at the points ``x``."""
        m = self.solve()
        a = (np.asarray(x, np.float64) - self.origin) @ m.T
        lam = a[:, 0:1]
        # px = a1 / a0 with a = M (X - o): d px = (M1 - px M0) / a0
        return (m[None, 1:, :] - (a[:, 1:] / lam)[:, :, None] * m[None, 0:1, :]) / lam[:, :, None]

    def direction(self, px: np.ndarray) -> np.ndarray:
        """(N, 3) unit directions of the rays through pixel coordinates ``px``."""
        d = self.corner + px[:, 0:1] * self.x_step - px[:, 1:2] * self.y_step
        return d / np.linalg.norm(d, axis=1, keepdims=True)


# ------------------------------------------------------------------------------------------------
# The curves


@dataclass
class Edges:
    """A mesh's undirected edges: vertex pairs (E, 2), their faces (E, 2; -1: none), and which are
    discontinuities of shading whatever the view (E,) bool."""

    verts: np.ndarray
    faces: np.ndarray
    crease: np.ndarray
    many: np.ndarray         # more than two faces on the edge: always a candidate


def mesh_edges(m, reads_corner_normals: bool) -> Edges:
    """The edges of ``m`` (own space), with the shading discontinuities across each: material, flat
    normals not parallel, corner normals (where the kernels read them) or uvs that differ."""
    f = np.asarray(m.indices, dtype=np.int64)
    nf = len(f)
    corner = np.stack([f, np.roll(f, -1, axis=1)], axis=2).reshape(-1, 2)      # (3F, 2): corner c -> c + 1
    key = np.sort(corner, axis=1)
    uniq, inv, counts = np.unique(key, axis=0, return_inverse=True, return_counts=True)
    inv = inv.reshape(-1)
    order = np.argsort(inv, kind="stable")
    first = np.zeros(len(uniq), dtype=np.int64)
    first[1:] = np.cumsum(counts)[:-1]
    faces = np.full((len(uniq), 2), -1, dtype=np.int64)
    slot_c = np.full((len(uniq), 2), -1, dtype=np.int64)          # the corner index 3 f + j of each side
    for s in range(2):
        ok = counts > s
        idx = order[first[ok] + s]
        faces[ok, s] = idx // 3
        slot_c[ok, s] = idx
    crease = np.zeros(len(uniq), dtype=bool)
    two = faces[:, 1] >= 0
    f0, f1 = faces[two, 0], faces[two, 1]
    mat = np.asarray(m.face_material)
    crease[two] |= mat[f0] != mat[f1]
    p = np.asarray(m.positions, dtype=np.float64)[f]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    flat = m.corner_normal is None
    if flat:
        crease[two] |= np.abs(np.sum(n[f0] * n[f1], axis=1)) < 1.0 - 1e-9
    # per-corner attributes at the edge's two vertices, as each face holds them
    a, b = uniq[two, 0], uniq[two, 1]

    def at(data, face, vertex):             # data (F, 3, k) at the corner of ``face`` holding ``vertex``
        j = np.argmax(f[face] == vertex[:, None], axis=1)
        return data[face, j]

    attrs = [np.asarray(m.corner_uv, dtype=np.float64)]
    if not flat and reads_corner_normals:
        attrs.append(np.asarray(m.corner_normal, dtype=np.float64))
    for data in attrs:
        for v in (a, b):
            crease[two] |= np.any(np.abs(at(data, f0, v) - at(data, f1, v)) > 1e-6, axis=1)
    del slot_c, nf
    return Edges(uniq, faces, crease, counts > 2)


@dataclass
class Samples:
    """Boundary samples: pixel coordinates (N, 2), unit normals (N, 2), weights 1 / density (N,),
    world points (N, 3) and what they lie on: ``owner`` (N,) the curve's index in ``curves``,
    ``s`` (N,) the blend of an edge's vertices (or the circle's angle)."""

    px: np.ndarray
    normal: np.ndarray
    weight: np.ndarray
    point: np.ndarray
    owner: np.ndarray
    s: np.ndarray


@dataclass
class Curve:
    """A candidate curve: an edge (``kind`` MESH: its mesh, placement, the two vertex rows, the world
    end points, the clipped blend range s0..s1) or a sphere's silhouette (``kind`` SPHERE: index)."""

    kind: str
    index: int
    placement: int = 0
    va: int = 0
    vb: int = 0
    a: np.ndarray | None = None
    b: np.ndarray | None = None
    s0: float = 0.0
    s1: float = 1.0
    length: float = 0.0


def image_to_edge(t, lam0: float, lam1: float):
    """The blend along a segment X0 -> X1 (depth factors lam0, lam1) whose image is at ``t`` of its
    image's length: the image point is ((1 - s) lam0 x0 + s lam1 x1) / ((1 - s) lam0 + s lam1)."""
    return t * lam0 / ((1.0 - t) * lam1 + t * lam0)


def _clip_to_image(pa: np.ndarray, pb: np.ndarray, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """Liang-Barsky: the parameter range (t0, t1) of segments pa -> pb (N, 2) inside the image (t0 > t1: outside)."""
    t0 = np.zeros(len(pa))
    t1 = np.ones(len(pa))
    d = pb - pa
    for axis, hi in ((0, width), (1, height)):
        for bound, sgn in ((0.0, -1.0), (float(hi), 1.0)):
            q = sgn * (bound - pa[:, axis])           # inside where sgn * d * t <= q
            pd = sgn * d[:, axis]
            with np.errstate(divide="ignore", invalid="ignore"):
                t = q / pd
            t0 = np.where(pd < 0, np.maximum(t0, t), t0)
            t1 = np.where(pd > 0, np.minimum(t1, t), t1)
            t1 = np.where((pd == 0) & (q < 0), -1.0, t1)
    return t0, t1


def sphere_circle(c: np.ndarray, r: float, eye: np.ndarray, phi: np.ndarray, basis=None):
    """Points (N, 3) of the circle where rays from ``eye`` graze sphere (c, r), at angles ``phi``, and
    the basis used (held fixed by callers that differentiate); None when the eye is inside."""
    w = eye - c
    dist = float(np.linalg.norm(w))
    if dist <= r * (1.0 + 1e-9):
        return None, None
    axis = w / dist
    if basis is None:
        helper = np.eye(3)[int(np.argmin(np.abs(axis)))]
        u = np.cross(axis, helper)
        basis = (u / np.linalg.norm(u), helper)
    u = np.cross(axis, basis[1])
    u /= np.linalg.norm(u)
    v = np.cross(axis, u)
    centre = c + axis * (r * r / dist)
    rho = r * np.sqrt(max(0.0, 1.0 - (r / dist) ** 2))
    return centre + rho * (np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * v), basis


def candidate_curves(scene, reads_corner_normals: bool, proj: Projection, width: int, height: int,
                     extent: float, topology: dict) -> list[Curve]:
    """Every curve of the image that may be a discontinuity for this eye (see the module docstring)."""
    eye = proj.origin
    m_inv = proj.solve()
    curves: list[Curve] = []
    near = NEAR * max(extent, 1e-30)
    for k, m in enumerate(scene.meshes):
        if not len(m.indices):
            continue
        if k not in topology:
            topology[k] = mesh_edges(m, reads_corner_normals)
        e = topology[k]
        for j in range(m.placements):
            pos, _ = m.world_part(j)
            pos = np.asarray(pos, dtype=np.float64)
            f = np.asarray(m.indices)
            tri = pos[f]
            n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
            facing = np.sign(np.sum(n * (eye - tri[:, 0]), axis=1))
            f0, f1 = e.faces[:, 0], e.faces[:, 1]
            border = f1 < 0
            sil = ~border & (facing[f0] * facing[np.maximum(f1, 0)] <= 0)
            keep = border | sil | e.crease | e.many
            idx = np.flatnonzero(keep)
            a, b = pos[e.verts[idx, 0]], pos[e.verts[idx, 1]]
            # clip to depth >= near: lam is affine in X (the depth along the view axis over the plane's)
            la = (a - eye) @ m_inv[0]
            lb = (b - eye) @ m_inv[0]
            lam_near = near / max(float(np.linalg.norm(proj.corner)), 1e-30)
            front = (la > lam_near) | (lb > lam_near)
            idx, a, b, la, lb = idx[front], a[front], b[front], la[front], lb[front]
            with np.errstate(divide="ignore", invalid="ignore"):
                tc = (lam_near - la) / (lb - la)
            s0 = np.where(la < lam_near, tc, 0.0)
            s1 = np.where(lb < lam_near, tc, 1.0)
            pa = proj.project(a + s0[:, None] * (b - a))[0]
            pb = proj.project(a + s1[:, None] * (b - a))[0]
            t0, t1 = _clip_to_image(pa, pb, width, height)
            inside = t1 > t0
            for i in np.flatnonzero(inside):
                lam0 = la[i] + s0[i] * (lb[i] - la[i])
                lam1 = la[i] + s1[i] * (lb[i] - la[i])
                c0 = s0[i] + (s1[i] - s0[i]) * image_to_edge(t0[i], lam0, lam1)
                c1 = s0[i] + (s1[i] - s0[i]) * image_to_edge(t1[i], lam0, lam1)
                q0 = pa[i] + t0[i] * (pb[i] - pa[i])
                q1 = pa[i] + t1[i] * (pb[i] - pa[i])
                length = float(np.linalg.norm(q1 - q0))
                if length > 0.0:
                    curves.append(Curve(MESH, k, j, int(e.verts[idx[i], 0]), int(e.verts[idx[i], 1]),
                                        a[i], b[i], float(c0), float(c1), length))
    for j, sph in enumerate(np.asarray(scene.spheres, dtype=np.float64).reshape(-1, 4)):
        phi = np.linspace(0.0, 2.0 * np.pi, SPHERE_BINS + 1)
        pts, _ = sphere_circle(sph[:3], float(sph[3]), eye, phi)
        if pts is None:
            continue
        px, lam = proj.project(pts)
        if np.any(lam <= 0):
            continue            # part of the circle behind the eye: the sphere surrounds the image plane
        seg = np.linalg.norm(np.diff(px, axis=0), axis=1)
        curves.append(Curve(SPHERE, j, length=float(seg.sum())))
    return curves


def draw(curves: list[Curve], scene, proj: Projection, n: int, rng: np.random.Generator) -> Samples:
    """``n`` stratified samples along the curves' total image length."""
    lengths = np.array([c.length for c in curves])
    total = float(lengths.sum())
    u = (np.arange(n) + rng.random(n)) / n * total
    cum = np.concatenate([[0.0], np.cumsum(lengths)])
    owner = np.clip(np.searchsorted(cum, u, side="right") - 1, 0, len(curves) - 1)
    local = np.clip((u - cum[owner]) / np.maximum(lengths[owner], 1e-300), 0.0, 1.0)
    px = np.zeros((n, 2))
    normal = np.zeros((n, 2))
    weight = np.full(n, total)
    point = np.zeros((n, 3))
    s = np.zeros(n)
    eye = proj.origin
    for ci in np.unique(owner):
        c = curves[ci]
        rows = np.flatnonzero(owner == ci)
        t = local[rows]
        if c.kind == MESH:
            # uniform in the image along the clipped segment: its end points' blends c.s0, c.s1
            pa = proj.project(c.a + c.s0 * (c.b - c.a))
            pb = proj.project(c.a + c.s1 * (c.b - c.a))
            la, lb = pa[1][()], pb[1][()]
            sb = c.s0 + (c.s1 - c.s0) * image_to_edge(t, la, lb)
            x = c.a[None] + sb[:, None] * (c.b - c.a)[None]
            q = proj.project(x)[0]
            d = pb[0] - pa[0]
            nn = np.array([-d[1], d[0]]) / np.linalg.norm(d)
            px[rows], normal[rows], point[rows], s[rows] = q, nn, x, sb
        else:
            sph = np.asarray(scene.spheres, dtype=np.float64).reshape(-1, 4)[c.index]
            grid = np.linspace(0.0, 2.0 * np.pi, SPHERE_BINS + 1)
            pts, basis = sphere_circle(sph[:3], float(sph[3]), eye, grid)
            seg = np.linalg.norm(np.diff(proj.project(pts)[0], axis=0), axis=1)
            cs = np.concatenate([[0.0], np.cumsum(seg)])
            pos = t * cs[-1]
            b = np.clip(np.searchsorted(cs, pos, side="right") - 1, 0, SPHERE_BINS - 1)
            frac = (pos - cs[b]) / np.maximum(seg[b], 1e-300)
            phi = grid[b] + frac * (grid[1] - grid[0])
            x, _ = sphere_circle(sph[:3], float(sph[3]), eye, phi, basis)
            h = 1e-6
            xp, _ = sphere_circle(sph[:3], float(sph[3]), eye, phi + h, basis)
            xm, _ = sphere_circle(sph[:3], float(sph[3]), eye, phi - h, basis)
            dq = (proj.project(xp)[0] - proj.project(xm)[0]) / (2.0 * h)       # d pixel / d phi
            speed = np.linalg.norm(dq, axis=1)
            nn = np.stack([-dq[:, 1], dq[:, 0]], axis=1) / np.maximum(speed, 1e-300)[:, None]
            # density per image length: (seg_b / total) / dphi / |dq/dphi|
            weight[rows] = total * speed * (grid[1] - grid[0]) / np.maximum(seg[b], 1e-300)
            px[rows], normal[rows], point[rows], s[rows] = proj.project(x)[0], nn, x, phi
    return Samples(px, normal, weight, point, owner, s)


# ------------------------------------------------------------------------------------------------
# The estimate


def primary_term(bound: Bound, adjoint: np.ndarray, wanted: list, boundary_spp: int, seed: int,
                 topology: dict | None = None):
    """(Forces on the geometry's points, {camera parameter name: gradient}): the boundary term of
    primary visibility for the loss whose adjoint image is ``adjoint`` (H, W, 3); ``wanted``: the
    parameters asked for (the camera's are differentiated here, the geometry's by ``forces.chain``);
    ``topology``: the meshes' edge lists by mesh (``mesh_edges``), filled here and shared with the
    secondary term of the same call."""
    rs = bound.settings
    cams = {p.name: np.zeros(3) for p in wanted if p.kind == "camera"}
    if boundary_spp <= 0:
        return Forces.empty(), cams
    w, h = rs.width, rs.height
    scene = bound.dev.scene
    proj = Projection.of(bound.camera, w, h)
    reads_normals = bound.dev.geometry.has_corner_normals != 0
    curves = candidate_curves(scene, reads_normals, proj, w, h, bound.dev.geometry.extent,
                              {} if topology is None else topology)
    if not curves:
        return Forces.empty(), cams
    n = boundary_spp * w * h
    rng = np.random.default_rng([seed, SEED_SALT])
    smp = draw(curves, scene, proj, n, rng)
    pix = np.floor(smp.px).astype(np.int64)
    ok = (pix[:, 0] >= 0) & (pix[:, 0] < w) & (pix[:, 1] >= 0) & (pix[:, 1] < h)
    a = np.zeros((n, 3))
    a[ok] = adjoint[pix[ok, 1], pix[ok, 0]]
    live = ok & np.any(a != 0, axis=1)
    rad = _trace_pairs(bound, proj, smp.px[live], smp.normal[live], seed)
    dl = rad[0::2] - rad[1::2]                      # L_minus - L_plus
    wgt = np.zeros(n)
    wgt[live] = np.sum(a[live] * dl, axis=1) * smp.weight[live] / n
    idx = np.flatnonzero(wgt != 0.0)
    if not len(idx):
        return Forces.empty(), cams
    # the force on each sample's point: weight x (d pixel / d X)^T n
    jac = proj.jacobian(smp.point[idx])
    force = wgt[idx, None] * np.einsum("nij,ni->nj", jac, smp.normal[idx])
    table = CurveTable.of(curves)
    owner = smp.owner[idx]
    s = np.where(table.sphere[owner], 0.0, smp.s[idx])
    forces = Forces(smp.point[idx], force, table.sphere[owner], table.index[owner], table.placement[owner],
                    np.stack([table.va[owner], table.vb[owner], table.va[owner]], axis=1),
                    np.stack([1.0 - s, s, np.zeros_like(s)], axis=1))
    for p in wanted:
        if p.kind == "camera":
            cams[p.name] = _camera_fd(p, idx, wgt, smp, table, scene, bound)
    return forces, cams


def _trace_pairs(bound: Bound, proj: Projection, px: np.ndarray, normal: np.ndarray, seed: int) -> np.ndarray:
    """(2N, 3) float64 radiance of the rays at px - EDGE_OFFSET n and px + EDGE_OFFSET n."""
    if not len(px):
        return np.zeros((0, 3))
    pts = np.empty((2 * len(px), 2))
    pts[0::2] = px - EDGE_OFFSET * normal
    pts[1::2] = px + EDGE_OFFSET * normal
    dev = bound.dev
    dirs = wp.array(proj.direction(pts).astype(np.float32), dtype=wp.vec3, device=dev.device)
    out = wp.zeros(len(pts), dtype=wp.vec3, device=dev.device)
    rp = bound.params(0, count=1, seed=(seed ^ SEED_SALT) & 0x7FFFFFFF)
    one_i = wp.zeros(1, dtype=wp.int32, device=dev.device)
    eye = wp.array([proj.origin.astype(np.float32)], dtype=wp.vec3, device=dev.device)
    wp.launch(BOUNDARY.build(bound), dim=len(pts), device=dev.device, inputs=[
        *bound.scene_args(rp), STAGE_PRIMARY, wp.uint32(0), one_i, one_i, one_i, dirs, eye,
        wp.zeros(1, dtype=wp.vec4i, device=dev.device), wp.zeros(1, dtype=wp.vec2, device=dev.device),
        wp.zeros(1, dtype=wp.vec3, device=dev.device), out])
    return out.numpy().astype(np.float64)


@dataclass
class CurveTable:
    """The curves' fields as arrays (one row per curve): whether a sphere's, the mesh or sphere
    index, the placement, the edge's two vertex rows."""

    sphere: np.ndarray
    index: np.ndarray
    placement: np.ndarray
    va: np.ndarray
    vb: np.ndarray

    @classmethod
    def of(cls, curves: list[Curve]) -> "CurveTable":
        return cls(np.array([c.kind == SPHERE for c in curves]), np.array([c.index for c in curves]),
                   np.array([c.placement for c in curves]), np.array([c.va for c in curves]),
                   np.array([c.vb for c in curves]))


def _camera_fd(p, idx, wgt, smp: Samples, table: CurveTable, scene, bound: Bound) -> np.ndarray:
    """The camera's term: n . d pixel / d (position or direction) of each sample's point (a sphere's
    silhouette point moves with the eye too)."""
    rs = bound.settings
    spheres = np.asarray(scene.spheres, dtype=np.float64).reshape(-1, 4)
    owner = smp.owner[idx]
    eye0 = Projection.of(bound.camera, rs.width, rs.height).origin
    groups = {}                    # sphere -> (its samples' rows, the basis they were drawn with)
    for j in np.unique(table.index[owner][table.sphere[owner]]):
        rows = np.flatnonzero(table.sphere[owner] & (table.index[owner] == j))
        groups[int(j)] = (rows, sphere_circle(spheres[j, :3], float(spheres[j, 3]), eye0, smp.s[idx[rows[:1]]])[1])

    def pixels(proj: Projection) -> np.ndarray:
        x = smp.point[idx].copy()
        for j, (rows, basis) in groups.items():
            x[rows] = sphere_circle(spheres[j, :3], float(spheres[j, 3]), proj.origin, smp.s[idx[rows]], basis)[0]
        return proj.project(x)[0]

    # n . d pixel / d theta per sample, weighted: linear in the pixels, so the difference of the sums
    return camera_derivative(bound, p.field, lambda proj: np.sum(wgt[idx] * np.sum(pixels(proj) * smp.normal[idx], axis=1)))


def camera_derivative(bound: Bound, field: str, objective) -> np.ndarray:
    """(3,): d objective(projection) / d camera.<field> ("position" or "direction") by central
    differences (the camera's frame is a smooth float64 function of both)."""
    rs = bound.settings
    cam0 = bound.camera
    v0 = np.asarray(getattr(cam0, field), dtype=np.float64)
    g = np.zeros(3)
    hstep = 1e-6 * max(1.0, float(np.linalg.norm(v0)))
    for i in range(3):
        vals = []
        for sgn in (1.0, -1.0):
            v = v0.copy()
            v[i] += sgn * hstep
            vals.append(objective(Projection.of(replace(cam0, **{field: tuple(v)}), rs.width, rs.height)))
        g[i] = (vals[0] - vals[1]) / (2.0 * hstep)
    return g
