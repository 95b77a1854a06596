"""Pose estimation: recover an object's translation and rotation from a photo of it.

``examples/pose_estimation.py`` runs it at the documented size (docs/gradients.md) and
``notebooks/pose_estimation.ipynb`` at a small one; it lives in the package so that the notebook finds
it wherever Jupyter starts its kernel.

A box with three colours on its faces (so that every rotation shows a different image) stands under
a gradient sky, seen from above one corner; the target is rendered at its true pose with 16x the
samples and another seed. The optimisation starts 25 degrees off in rotation and a fifth of the box's
size off in position, and runs Adam (:mod:`warp_spt.diff.optim`) on the L2 loss over
``box.obj.translation`` and ``box.obj.rotation`` (a rotation vector), with a fresh seed per iteration and
another for the gradient. The gradient is the tape's interior term (shading moves with the faces) plus
the boundary term of the box's silhouette and edges (``warp_spt.diff.boundary``): without the latter,
an object against its background gets no gradient from its outline at all.

``pose_error`` is the rotation's error in degrees plus the translation's error in percent of the
box's size (one number that is 0 at the true pose); both parts are reported too.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from warp_spt.diff.geometry_params import rodrigues
from warp_spt.diff.gradients import render_gradients
from warp_spt.diff.inverse_demo import OptimisationRun
from warp_spt.diff.optim import Adam
from warp_spt.diff.params import parameters
from warp_spt.io.loader import load_scene
from warp_spt.losses import l2
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

SIZE = (1.0, 0.7, 0.5)                      # the box's sides
START_ROTATION = np.radians(25.0) * np.array([0.48, 0.6, 0.64])      # 25 degrees about a tilted axis
START_TRANSLATION = np.array([0.15, -0.1, 0.08])
CAMERA = Camera(position=(2.2, -2.6, 1.9), direction=(-2.2, 2.6, -1.9), fov=38.0, aperture=0.0, focus=3.9,
                up=(0.0, 0.0, 1.0))
TRANSLATION, ROTATION = "box.obj.translation", "box.obj.rotation"     # the OBJ file's mesh, by its name
SKY = Sky.gradient(zenith=(0.35, 0.5, 0.9), nadir=(0.9, 0.85, 0.8))
MTL = ("newmtl red\nKd 0.8 0.15 0.1\nRoughness 1\n"
       "newmtl green\nKd 0.15 0.7 0.2\nRoughness 1\n"
       "newmtl blue\nKd 0.1 0.2 0.8\nRoughness 0.7\n")


def box_obj() -> str:
    """The box centred on the origin, opposite faces of one colour: x red, y green, z blue."""
    sx, sy, sz = (s / 2 for s in SIZE)
    v = [(x, y, z) for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)]
    quads = {"red": [(0, 1, 3, 2), (4, 6, 7, 5)], "green": [(0, 4, 5, 1), (2, 3, 7, 6)],
             "blue": [(0, 2, 6, 4), (1, 5, 7, 3)]}
    lines = [f"v {x} {y} {z}" for x, y, z in v]
    for name, faces in quads.items():
        lines.append(f"usemtl {name}")
        for a, b, c, d in faces:
            lines.append(f"f {a + 1} {b + 1} {c + 1} {d + 1}")
    return "\n".join(lines) + "\n"


def box_scene():
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "box.obj").write_text(box_obj())
        (Path(tmp) / "box.mtl").write_text(MTL)
        return load_scene([str(Path(tmp) / "box.obj")], [str(Path(tmp) / "box.mtl")])


def rotation_error_deg(r: np.ndarray) -> float:
    """The angle of the rotation ``R(r)`` (the true rotation is the identity)."""
    c = (np.trace(rodrigues(r)) - 1.0) / 2.0
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def pose_error(translation: np.ndarray, rotation: np.ndarray) -> float:
    return rotation_error_deg(rotation) + 100.0 * float(np.linalg.norm(translation)) / max(SIZE)


@dataclass
class PoseRun(OptimisationRun):
    """The recovered pose (the mean of the last sixth of the iterates) beside the run's record."""

    translation: np.ndarray = None
    rotation: np.ndarray = None

    @property
    def error(self) -> float:
        return pose_error(self.translation, self.rotation)

    @property
    def rotation_deg(self) -> float:
        return rotation_error_deg(self.rotation)

    @property
    def translation_percent(self) -> float:
        return 100.0 * float(np.linalg.norm(self.translation)) / max(SIZE)


def recover(quick: bool = False, seed: int = 0, log=None, boundary: bool = True) -> PoseRun:
    """Run the optimisation (``quick``: 24x24 pixels, 8 spp, 60 iterations; else 48x48, 16 spp, 120);
    ``log(iteration, loss, pose_error)`` is called after each step; ``boundary`` False leaves the
    boundary term out (the control of docs/gradients.md)."""
    size, spp, iterations, lr = (24, 8, 60, 0.03) if quick else (48, 16, 120, 0.02)
    params = parameters(box_scene(), CAMERA, SKY)
    rs = RenderSettings(width=size, height=size, spp=spp, max_depth=2, integrator="seed", tile_pixels=size * size)
    target = render_scene(params.scene, CAMERA, replace(rs, sky=SKY, spp=16 * spp, seed=10_000 + seed)).image
    names = [TRANSLATION, ROTATION]
    params[TRANSLATION] = START_TRANSLATION
    params[ROTATION] = START_ROTATION
    start = pose_error(START_TRANSLATION, START_ROTATION)
    start_image = render_scene(params.scene, CAMERA, replace(rs, sky=SKY, spp=16 * spp)).image
    opt = Adam(params, names, lr=lr, decay=0.98)
    errors, losses, tail = [], [], []
    t0 = time.perf_counter()
    for it in range(iterations):
        r = render_gradients(params, replace(rs, seed=1000 * seed + 2 * it), loss=l2(target), wrt=names,
                             gradient_seed=1000 * seed + 2 * it + 1, boundary=boundary)
        opt.step(r.grads)
        t, rot = params[TRANSLATION].astype(np.float64), params[ROTATION].astype(np.float64)
        losses.append(float(r.loss))
        errors.append(pose_error(t, rot))
        if log is not None:
            log(it, losses[-1], errors[-1])
        if it >= iterations - iterations // 6:
            tail.append((t, rot))
    seconds = (time.perf_counter() - t0) / iterations
    t = np.mean([a for a, _ in tail], axis=0)
    rot = np.mean([b for _, b in tail], axis=0)
    params[TRANSLATION], params[ROTATION] = t, rot
    final = render_scene(params.scene, CAMERA, replace(rs, sky=SKY, spp=16 * spp)).image
    return PoseRun(start, errors, losses, seconds, target, start_image, final, translation=t, rotation=rot)


def figure(run: PoseRun, scale: int = 4):
    """The start, the result and the target side by side over the error curve (log10), as a PIL image."""
    return run.strip("pose_error", scale)
