"""Scenes far from the origin: shifted to it in float64 before anything is rounded to float32.

:func:`recentre` is called by every renderer on a host Scene (a DeviceScene is used as it is), so a
scene 1e5 away renders like the same scene at the origin; :func:`describe_bounds` and
:func:`format_point` print bounds and points the way the command line shows them.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Sequence

import numpy as np

from warp_spt.scene.camera import RECENTRE_RATIO, Camera, exact_bounds, far_centre
from warp_spt.scene.lights import PUNCTUAL_TYPES
from warp_spt.scene.lights import moved as moved_light
from warp_spt.scene.model import Scene


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
    """The scene's bounds for the CLI's 'loaded' line, with its extent: corners printed with the
    digits that tell them apart (a 2-unit model 1e9 from the origin shows both), and the size."""
    b = exact_bounds(scene)
    span = float(np.max(b[1] - b[0]))
    far = float(np.max(np.abs(b)))
    digits = 6 if not span > 0.0 else min(17, 6 + max(0, math.ceil(math.log10(max(far / span, 1.0)))))
    point = lambda v: "(" + ", ".join(f"{x:.{digits}g}" for x in v) + ")"
    return f"bounds {point(b[0])}..{point(b[1])}, {describe_extent(scene)}"


def describe_extent(scene: Scene) -> str:
    """The scene's size along x, y and z, e.g. ``size 2 x 1.6 x 1.1``, from the exact bounds."""
    b = exact_bounds(scene)
    return "size " + " x ".join(f"{x:.3g}" for x in b[1] - b[0])


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
    centre = far_centre(scene, ratio)
    if centre is None:
        return scene, camera, np.zeros(3)
    meshes = [replace(m, positions=(m.positions.astype(np.float64) - centre).astype(np.float32))
              if m.transforms is None else replace(m, transforms=_moved_transforms(m.transforms, centre))
              for m in scene.meshes]
    spheres = scene.spheres.astype(np.float32)
    if len(spheres):
        spheres[:, :3] = (scene.spheres[:, :3].astype(np.float64) - centre).astype(np.float32)
    lights = [moved_light(x, centre) if isinstance(x, PUNCTUAL_TYPES) else x for x in scene.lights]
    moved = replace(scene, meshes=meshes, spheres=spheres, lights=lights, fog=_moved_medium(scene.fog, centre),
                    interiors={k: _moved_medium(v, centre) for k, v in scene.interiors.items()})
    cam = replace(camera, position=tuple(float(v) for v in np.asarray(camera.position, np.float64) - centre))
    return moved, cam, centre


def _moved_transforms(transforms: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Instances moved by ``-centre``: their translations only (the shared mesh stays in its own frame)."""
    out = np.array(transforms, dtype=np.float64)
    out[:, :3, 3] -= centre
    return out


def _moved_medium(medium, centre: np.ndarray):
    """A density grid placed ``centre`` further from the origin's side: it moves with the geometry
    (a homogeneous medium has no place)."""
    if medium is None or getattr(medium, "density", None) is None:
        return medium
    shift = np.eye(4)
    shift[:3, 3] = -centre
    to_world = np.eye(4) if medium.to_world is None else np.asarray(medium.to_world, np.float64)
    return replace(medium, to_world=shift @ to_world)
