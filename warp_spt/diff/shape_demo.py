"""Shape from views: a sphere mesh refined into a target shape from rendered images of it.

``examples/shape_from_views.py`` runs it at the documented size (docs/gradients.md) and
``notebooks/shape_from_views.ipynb`` at a small one; it lives in the package so that the notebook
finds it wherever Jupyter starts its kernel.

The target is a blob: the unit sphere pushed out and in by a few low-frequency bumps
(``target_radius``), genus 0, grey and diffuse, under a procedural environment map (``sky_map``: a
blue sky brightening to the zenith, a warm sun-like patch, a brown ground) whose rays that miss the
blob are black, so that every view shows the outline. Eight cameras look at it from a ring around it
and from above and below. The targets are rendered at the true shape with 16x the samples and another
seed. The optimisation starts from an icosphere of radius 1 and runs Large Steps
(:mod:`warp_spt.diff.large_steps`) on ``blob.obj.positions`` with the L2 loss summed over the views:
each view's gradient is one ``render_gradients`` call with that view's camera, which holds the
boundary term of the blob's outline (``warp_spt.diff.boundary``). The secondary boundary term
(outlines seen from the surface, shadows' edges) is left out (``secondary_spp=0``): at 32x32 pixels
and 4 spp it took 1.07 s of a view's 1.2 s, and on the convex start it changed no gradient.

``chamfer`` measures the shape: the symmetric mean distance from the mesh's vertices to the target's
surface and from dense samples of the target surface (``target_samples``) to the mesh's.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
import warp as wp

from warp_spt.diff.gradients import render_gradients
from warp_spt.diff.large_steps import LargeSteps
from warp_spt.diff.params import parameters
from warp_spt.io.loader import load_scene
from warp_spt.losses import l2
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

POSITIONS = "blob.obj.positions"           # the OBJ file's mesh, by its name
MTL = "newmtl grey\nKd 0.7 0.7 0.7\nRoughness 1\n"
BUMPS = [((0.0, 0.0, 1.0), 0.35), ((0.9, 0.3, -0.3), 0.25), ((-0.5, 0.8, 0.2), -0.2), ((-0.4, -0.7, -0.6), 0.2)]
BUMP_WIDTH = 0.5                            # radians-ish: a bump spans about a third of the sphere


def icosphere(subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    """(V, 3) unit vectors and (F, 3) faces of an icosahedron subdivided ``subdivisions`` times
    (V = 10 * 4**n + 2: 162, 642, 2562), outward-facing."""
    t = (1 + 5 ** 0.5) / 2
    v = np.array([(-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0), (0, -1, t), (0, 1, t), (0, -1, -t),
                  (0, 1, -t), (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)], dtype=np.float64)
    f = np.array([(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11), (1, 5, 9), (5, 11, 4),
                  (11, 10, 2), (10, 7, 6), (7, 1, 8), (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
                  (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    for _ in range(subdivisions):
        e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
        unique, inverse = np.unique(e, axis=0, return_inverse=True)
        mid = v[unique].mean(axis=1)
        mid /= np.linalg.norm(mid, axis=1, keepdims=True)
        ab, bc, ca = (inverse.reshape(3, -1) + len(v))
        v = np.concatenate([v, mid])
        a, b, c = f.T
        f = np.concatenate([np.stack(x, axis=1) for x in ((a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca))])
    return v, f


def target_radius(d: np.ndarray) -> np.ndarray:
    """The target's radius along unit directions ``d`` (..., 3): 1 plus Gaussian bumps in angle."""
    r = np.ones(d.shape[:-1])
    for axis, height in BUMPS:
        a = np.asarray(axis) / np.linalg.norm(axis)
        angle = np.arccos(np.clip(d @ a, -1.0, 1.0))
        r += height * np.exp(-(angle / BUMP_WIDTH) ** 2)
    return r


def target_mesh(subdivisions: int = 4) -> tuple[np.ndarray, np.ndarray]:
    d, f = icosphere(subdivisions)
    return d * target_radius(d)[:, None], f


def target_samples(count: int = 20_000, seed: int = 0) -> np.ndarray:
    """(count, 3) points on the target surface: uniform directions (the surface is star-shaped)
    pushed to its radius; the same for every run."""
    d = np.random.default_rng(seed).normal(size=(count, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return d * target_radius(d)[:, None]


@wp.kernel(module="unique")
def _distance_to_mesh(mesh: wp.uint64, points: wp.array(dtype=wp.vec3), out: wp.array(dtype=float)):
    i = wp.tid()
    q = wp.mesh_query_point_no_sign(mesh, points[i], 1.0e6)
    out[i] = wp.length(points[i] - wp.mesh_eval_position(mesh, q.face, q.u, q.v))


def distance_to_mesh(points: np.ndarray, v: np.ndarray, f: np.ndarray) -> np.ndarray:
    """(N,) each point's distance to the nearest point of the triangles (``v``, ``f``): exact, by Warp's
    closest-point query on a BVH."""
    device = "cpu"
    mesh = wp.Mesh(points=wp.array(np.asarray(v, np.float32), dtype=wp.vec3, device=device),
                   indices=wp.array(np.asarray(f, np.int32).reshape(-1), dtype=wp.int32, device=device))
    pts = wp.array(np.asarray(points, np.float32), dtype=wp.vec3, device=device)
    out = wp.zeros(len(points), dtype=float, device=device)
    wp.launch(_distance_to_mesh, dim=len(points), inputs=[mesh.id, pts, out], device=device)
    return out.numpy().astype(np.float64)


def chamfer(v: np.ndarray, f: np.ndarray, samples: np.ndarray, target: tuple[np.ndarray, np.ndarray]) -> float:
    """Symmetric Chamfer distance between the mesh (``v``, ``f``) and the target: (the mean distance
    of the mesh's vertices to the target's surface (``target`` = its vertices and faces) plus that
    of the target's ``samples`` to the mesh's surface) / 2, in scene units. Point-to-surface
    distances, not point-to-point: a vertex sample's own spacing (0.1 on the quick sphere) would
    otherwise be a floor of the same size as the start's distance."""
    return float(0.5 * (distance_to_mesh(v, *target).mean() + distance_to_mesh(samples, v, f).mean()))


def sky_map(height: int = 16) -> np.ndarray:
    """(H, 2H, 3) an equirectangular map, row 0 the zenith: sky brightening upwards, a bright patch
    (a soft sun) 35 degrees from the zenith, brown ground below the horizon."""
    theta = np.pi * (np.arange(height) + 0.5) / height
    phi = 2 * np.pi * (np.arange(2 * height) + 0.5) / (2 * height)
    up = np.cos(theta)[:, None, None]
    img = (0.25 + 0.75 * np.clip(up, 0, 1)) * np.array([0.5, 0.7, 1.0]) * np.ones((1, 2 * height, 1))
    sun = np.exp(-((theta[:, None] - 0.6) ** 2 + (phi[None, :] - 1.0) ** 2) / 0.08)
    img = img + sun[..., None] * np.array([5.0, 4.5, 3.5])
    img = np.where(up > 0, img, np.array([0.35, 0.28, 0.2]))
    return img.astype(np.float32)


SKY = Sky.environment(sky_map(), up=(0.0, 0.0, 1.0), background=(0.0, 0.0, 0.0))


def cameras(count: int = 8, distance: float = 4.5) -> list[Camera]:
    """``count - 2`` cameras on a ring 15 degrees above the equator, one above, one below."""
    dirs = [(np.cos(a) * 0.966, np.sin(a) * 0.966, 0.259)
            for a in 2 * np.pi * (np.arange(count - 2) + 0.25) / (count - 2)]
    dirs += [(0.05, 0.1, 0.99), (-0.1, 0.05, -0.99)]
    out = []
    for d in dirs:
        p = distance * np.asarray(d) / np.linalg.norm(d)
        up = (0.0, 0.0, 1.0) if abs(d[2]) < 0.9 else (1.0, 0.0, 0.0)
        out.append(Camera(position=tuple(p), direction=tuple(-p), fov=36.0, aperture=0.0,
                          focus=distance, up=up))
    return out


def obj_text(v: np.ndarray, f: np.ndarray) -> str:
    return ("usemtl grey\n" + "".join(f"v {x:.7f} {y:.7f} {z:.7f}\n" for x, y, z in v)
            + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f))


def mesh_scene(v: np.ndarray, f: np.ndarray):
    """The scene of one grey mesh named ``blob.obj`` (flat normals: the shading follows the facets)."""
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "blob.obj").write_text(obj_text(v, f))
        (Path(tmp) / "blob.mtl").write_text(MTL)
        return load_scene([str(Path(tmp) / "blob.obj")], [str(Path(tmp) / "blob.mtl")])


@dataclass
class ShapeRun:
    """The recovered vertices, the Chamfer distance per iteration (after each step), the loss, the
    seconds per iteration, the CG iterations per solve, and one view's target, start and result."""

    positions: np.ndarray
    start_chamfer: float
    chamfers: list[float]
    losses: list[float]
    seconds_per_iteration: float
    cg_iterations: list[int]
    target: np.ndarray
    start_image: np.ndarray
    final_image: np.ndarray

    @property
    def chamfer(self) -> float:
        return self.chamfers[-1]


def recover(quick: bool = False, seed: int = 0, log=None, views: int | None = None, lam: float | None = None,
            lr: float | None = None, iterations: int | None = None) -> ShapeRun:
    """Run the optimisation on a 642-vertex sphere (``quick``: 6 views of 24x24 pixels, 4 spp, 30
    iterations; else 8 views of 32x32, 8 spp, 80) with Large Steps' ``lr`` 0.3 and ``lam`` 20 (of lr 0.02, 0.08,
    0.2 and 0.3 over 30 quick iterations, 0.3 fell furthest; lam 40 with lr 0.4 no further than lam 20);
    ``log(iteration, loss, chamfer)`` is called after each step."""
    sub, size, spp, its, step, smooth = (3, 24, 4, 30, 0.3, 20.0) if quick else (3, 32, 8, 80, 0.3, 20.0)
    its = iterations or its
    views = views or (6 if quick else 8)
    lam = smooth if lam is None else lam
    lr = step if lr is None else lr
    samples = target_samples()
    tv, tf = target_mesh()
    cams = cameras(views)
    rs = RenderSettings(width=size, height=size, spp=spp, max_depth=2, integrator="seed", tile_pixels=size * size)
    truth = parameters(mesh_scene(tv, tf), cams[0], SKY)
    targets = [render_scene(truth.scene, c, replace(rs, sky=SKY, spp=16 * spp, seed=10_000 + 100 * seed + k)).image
               for k, c in enumerate(cams)]
    v0, f0 = icosphere(sub)
    params = parameters(mesh_scene(v0, f0), cams[0], SKY)
    start_image = render_scene(params.scene, cams[0], replace(rs, sky=SKY, spp=16 * spp)).image
    start = chamfer(v0, f0, samples, (tv, tf))
    opt = LargeSteps(params, POSITIONS, lr=lr, lam=lam)
    chamfers, losses = [], []
    t0 = time.perf_counter()
    for it in range(its):
        total = np.zeros(params.info(POSITIONS).shape)
        loss = 0.0
        for k, (cam, target) in enumerate(zip(cams, targets)):
            params.camera = cam
            s = 1_000_000 * seed + 1000 * it + 2 * k
            r = render_gradients(params, replace(rs, seed=s), loss=l2(target), wrt=[POSITIONS],
                                 gradient_seed=s + 1, secondary_spp=0)
            total += r.grads[POSITIONS]
            loss += float(r.loss)
        opt.step({POSITIONS: total})
        chamfers.append(chamfer(params[POSITIONS], f0, samples, (tv, tf)))
        losses.append(loss)
        if log is not None:
            log(it, loss, chamfers[-1])
    seconds = (time.perf_counter() - t0) / its
    params.camera = cams[0]
    final = render_scene(params.scene, cams[0], replace(rs, sky=SKY, spp=16 * spp)).image
    return ShapeRun(params[POSITIONS].astype(np.float64), start, chamfers, losses, seconds, opt.cg_iterations,
                    targets[0], start_image, final)


def figure(run: ShapeRun, scale: int = 4):
    """The start, the result and the target (the first view) side by side over the Chamfer curve
    (log10), as a PIL image."""
    from warp_spt.diff.inverse_demo import strip_figure

    return strip_figure([run.start_image, run.final_image, run.target], "chamfer",
                        [run.start_chamfer] + run.chamfers, scale, what="Chamfer distance")
