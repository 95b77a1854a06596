"""Scenes far from the origin: shifted to it in float64 before anything is rounded to float32.

:func:`recentre` is called by every renderer on a host Scene (a DeviceScene is used as it is), so a
scene 1e5 away renders like the same scene at the origin; :func:`describe_bounds` and
:func:`format_point` print bounds and points the way the command line shows them.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Sequence

import numpy as np

from warp_spt.scene.camera import Camera
from warp_spt.scene.model import Scene

# recentre: scenes whose centre lies farther from the origin than this many times their size.
RECENTRE_RATIO = 4.0


# ---------------------------------------------------------------------------------------------
# Framing


# ---------------------------------------------------------------------------------------------
# The probe: a low-resolution pinhole look through the camera


# ---------------------------------------------------------------------------------------------
# Warnings


def format_point(v: Sequence[float]) -> str:
    """A point as (x, y, z) with 6 significant digits."""
    return "(" + ", ".join(f"{x:.6g}" for x in v) + ")"


def describe_bounds(scene: Scene) -> str:
    """The scene's bounds for the CLI's 'loaded' line."""
    b = scene.bounds
    return f"bounds {format_point(b[0])}..{format_point(b[1])}"


# ---------------------------------------------------------------------------------------------
# Far from the origin


def recentre(scene: Scene, camera: Camera | None = None, *, ratio: float = RECENTRE_RATIO
             ) -> tuple[Scene, Camera, np.ndarray]:
    """Shift a scene far from the origin (and its camera) so that its centre is at the origin.

    Returns (scene', camera', offset) with world = local + offset. The subtraction is done in float64
    on the positions as parsed (float64: nothing was rounded to float32 before), and the result is
    rounded to float32 once, so the local coordinates are exact to float32 *relative to the scene's
    size*, not to its distance from the origin. Scenes whose centre lies within ``ratio`` times their
    size of the origin are returned unchanged (offset 0), so ordinary scenes render bit for bit as before.
    """
    camera = camera or Camera()
    b = scene.bounds
    size = float(np.max(b[1] - b[0])) if np.all(np.isfinite(b)) else 0.0
    centre = 0.5 * (b[0] + b[1])
    if not size > 0.0 or float(np.max(np.abs(centre))) <= ratio * size:
        return scene, camera, np.zeros(3)
    meshes = [replace(m, positions=(m.positions.astype(np.float64) - centre).astype(np.float32))
              for m in scene.meshes]
    spheres = scene.spheres.astype(np.float32)
    if len(spheres):
        spheres[:, :3] = (scene.spheres[:, :3].astype(np.float64) - centre).astype(np.float32)
    moved = replace(scene, meshes=meshes, spheres=spheres)
    cam = replace(camera, position=tuple(float(v) for v in np.asarray(camera.position, np.float64) - centre))
    return moved, cam, centre
