"""The camera on the device: the one camera frame, its float32 kernel struct and the primary ray.

:func:`camera_frame` is the single definition of what a kernel knows of a :class:`Camera` (the
vectors of :data:`CAMERA_FIELDS`, in float64): the kernel parameters (:func:`camera_params`), the
camera's Jacobian for gradients (``warp_spt.diff.params.camera_jacobian``) and the view probes
(:func:`pinhole_directions`) all derive from it, so they cannot drift apart.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_spt.device.sampling import concentric_disk
from warp_spt.scene.camera import Camera

# The vector fields of CameraParams, in this order (the gradients' deltas follow it too).
CAMERA_FIELDS = ("origin", "to_upper_left", "x_step", "y_step", "right", "up")


@wp.struct
class CameraParams:
    """The image plane of camera.Camera.frame(), in float32.

    Primary rays use ``to_upper_left`` (the corner relative to the origin, subtracted in float64):
    with the absolute corner, a camera at 1e5 rounded every target point to 1/128 unit before the
    origin was subtracted, which bent primary rays by up to a few percent
    (tests/rendering/test_stability.py, shifted Cornell box).
    """

    origin: wp.vec3
    to_upper_left: wp.vec3     # upper_left - origin
    x_step: wp.vec3
    y_step: wp.vec3
    right: wp.vec3
    up: wp.vec3
    lens_radius: float


def camera_frame(camera: Camera, width: int, height: int) -> dict[str, np.ndarray | float]:
    """The camera's frame for a width x height image, float64: the :data:`CAMERA_FIELDS` vectors
    and ``lens_radius``. ``to_upper_left`` is subtracted here, in float64, before any rounding."""
    f = dict(camera.image_plane(width, height))
    f["to_upper_left"] = f["upper_left"] - f["origin"]
    out: dict[str, np.ndarray | float] = {k: np.asarray(f[k], dtype=np.float64) for k in CAMERA_FIELDS}
    out["lens_radius"] = float(f["lens_radius"])
    return out


def camera_params(camera: Camera, width: int, height: int) -> CameraParams:
    """Pack a Camera's frame (:func:`camera_frame`) for the kernel."""
    f = camera_frame(camera, width, height)
    c = CameraParams()
    for name in CAMERA_FIELDS:
        setattr(c, name, wp.vec3(*np.asarray(f[name], dtype=np.float32).tolist()))
    c.lens_radius = float(f["lens_radius"])
    return c


def pinhole_directions(camera: Camera, width: int, height: int) -> tuple[np.ndarray, np.ndarray]:
    """(origin (3,), unit directions (height, width, 3)), float64: the rays through the pixel
    centres of a pinhole camera with this frame (what :func:`camera_ray` gives at offset 0.5, no lens)."""
    f = camera_frame(camera, width, height)
    xs, ys = np.meshgrid(np.arange(width) + 0.5, np.arange(height) + 0.5)
    d = f["to_upper_left"] + xs[..., None] * f["x_step"] - ys[..., None] * f["y_step"]
    return f["origin"], d / np.linalg.norm(d, axis=-1, keepdims=True)


@wp.func
def camera_ray(cam: CameraParams, x: float, y: float, r1: float, r2: float, r3: float, r4: float):
    """The primary ray through pixel (x, y) at offset (r1, r2) in the pixel, lens sample (r3, r4).

    The image plane is the focal plane, so every lens point sees the same target: a thin lens.
    """
    target = cam.to_upper_left + cam.x_step * (x + r1) - cam.y_step * (y + r2)   # relative to origin
    lens = wp.vec3(0.0, 0.0, 0.0)
    if cam.lens_radius > 0.0:
        k = concentric_disk(r3, r4)
        lens = (cam.right * k[0] + cam.up * k[1]) * cam.lens_radius
    return cam.origin + lens, wp.normalize(target - lens)
