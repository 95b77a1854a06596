"""Camera navigation as pure math on numpy vectors: orbit, pan, dolly, field of view.

The viewer's camera is an orbit rig: a ``target`` the camera looks at, the camera's ``position``
and the world's ``up`` axis. Every operation returns a new :class:`Rig` (frozen), so the host can
keep the previous one and nothing here has side effects. Screen motions come in *fractions of
the view* (a drag across the whole view is 1), so the same gesture does the same thing at any
window size.

Conventions (those of most turntable viewers): dragging right turns the scene right (the camera
swings left around the target), dragging down lifts the camera; the elevation is kept within
+-MAX_ELEVATION of the horizon, so the view never flips over the pole and never looks exactly along
``up`` (where the image's orientation is a convention of its own).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

MAX_ELEVATION = math.radians(89.0)   # short of the pole: the camera's frame stays well defined
ORBIT_PER_VIEW = math.pi             # radians turned by a drag across the whole view
MIN_FOV, MAX_FOV = 1.0, 170.0        # degrees; the renderer takes (0, 180)
DOLLY_STEP = 0.85                    # distance factor per wheel notch or key press
FOV_STEP = 1.1                       # fov factor per notch


@dataclass(frozen=True)
class Rig:
    """An orbit camera: ``position`` looking at ``target``, ``up`` the world's up axis (unit).

    ``fov`` is the horizontal field of view in degrees, ``aperture`` the lens radius. ``focus`` is
    the focus distance, or None for "the distance to the target" (the target stays sharp).
    """

    position: np.ndarray
    target: np.ndarray
    up: np.ndarray
    fov: float = 38.0
    aperture: float = 0.0
    focus: float | None = None

    @property
    def distance(self) -> float:
        """Distance from the camera to its target."""
        return float(np.linalg.norm(self.position - self.target))

    @property
    def direction(self) -> np.ndarray:
        """Unit view direction, from the position towards the target."""
        return (self.target - self.position) / self.distance

    @property
    def focus_distance(self) -> float:
        return self.distance if self.focus is None else float(self.focus)


def make_rig(position, target, up, fov: float = 38.0, aperture: float = 0.0, focus: float | None = None) -> Rig:
    """A :class:`Rig` from sequences; ``up`` is normalised. Raises ValueError if position == target."""
    p, t, u = (np.asarray(v, dtype=np.float64).reshape(3) for v in (position, target, up))
    if not np.linalg.norm(t - p) > 0.0:
        raise ValueError("the camera's target must differ from its position")
    return Rig(p, t, u / np.linalg.norm(u), float(fov), float(aperture), focus)


def rig_from_view(position, direction, up, depth: float, **fields) -> Rig:
    """A rig whose target lies ``depth`` ahead along ``direction`` (the same view, a chosen pivot)."""
    d = np.asarray(direction, dtype=np.float64)
    d = d / np.linalg.norm(d)
    p = np.asarray(position, dtype=np.float64)
    return make_rig(p, p + d * max(float(depth), 1e-9), up, **fields)


def horizon_basis(up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane perpendicular to ``up``, right-handed with it:
    ``e1 x e2 = up``. Azimuth 0 is e1 and grows towards e2."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = helper - up * float(np.dot(helper, up))
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(up, e1)


def spherical(rig: Rig) -> tuple[float, float, float]:
    """(distance, azimuth, elevation) of the camera around its target, radians."""
    offset = rig.position - rig.target
    r = float(np.linalg.norm(offset))
    e1, e2 = horizon_basis(rig.up)
    elevation = math.asin(max(-1.0, min(1.0, float(np.dot(offset, rig.up)) / r)))
    azimuth = math.atan2(float(np.dot(offset, e2)), float(np.dot(offset, e1)))
    return r, azimuth, elevation


def from_spherical(rig: Rig, r: float, azimuth: float, elevation: float) -> np.ndarray:
    """The position at (distance, azimuth, elevation) around the rig's target."""
    e1, e2 = horizon_basis(rig.up)
    flat = math.cos(elevation) * (math.cos(azimuth) * e1 + math.sin(azimuth) * e2)
    return rig.target + r * (flat + math.sin(elevation) * rig.up)


def orbit(rig: Rig, dx: float, dy: float) -> Rig:
    """Swing the camera around its target by a drag of (dx, dy) view fractions (x right, y down).

    The distance to the target and the target itself never change; the elevation is clamped to
    +-MAX_ELEVATION.
    """
    r, azimuth, elevation = spherical(rig)
    elevation = max(-MAX_ELEVATION, min(MAX_ELEVATION, elevation + dy * ORBIT_PER_VIEW))
    return replace(rig, position=from_spherical(rig, r, azimuth - dx * ORBIT_PER_VIEW, elevation))


def screen_axes(rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """Unit (right, image up) of the view, as the renderer's camera frame defines them."""
    d = rig.direction
    right = np.cross(d, rig.up)
    n = np.linalg.norm(right)
    if n < 1e-9:                      # looking along up: cannot happen within MAX_ELEVATION
        right = horizon_basis(rig.up)[1]
    else:
        right = right / n
    return right, np.cross(right, d)


def pan(rig: Rig, dx: float, dy: float, aspect: float = 1.0) -> Rig:
    """Slide camera and target together so the point under the cursor at the target's depth
    follows a drag of (dx, dy) view fractions. The view direction does not change."""
    right, image_up = screen_axes(rig)
    width = 2.0 * rig.distance * math.tan(math.radians(rig.fov) / 2.0)   # view width at the target
    shift = -dx * width * right + dy * (width / aspect) * image_up
    return replace(rig, position=rig.position + shift, target=rig.target + shift)


def dolly(rig: Rig, steps: float, min_distance: float = 1e-6) -> Rig:
    """Move towards the target (``steps`` > 0) or away from it, by DOLLY_STEP per step; the view
    direction and the target do not change, and the camera never reaches the target."""
    r = max(rig.distance * DOLLY_STEP ** steps, min_distance)
    return replace(rig, position=rig.target - rig.direction * r, focus=None)


def zoom(rig: Rig, steps: float) -> Rig:
    """Narrow (``steps`` > 0) or widen the field of view by FOV_STEP per step, within [MIN_FOV, MAX_FOV]."""
    return with_fov(rig, rig.fov / FOV_STEP ** steps)


def with_fov(rig: Rig, fov: float) -> Rig:
    """The rig with a horizontal field of view of ``fov`` degrees, clamped to [MIN_FOV, MAX_FOV]."""
    return replace(rig, fov=float(min(MAX_FOV, max(MIN_FOV, fov))))


def retarget(rig: Rig, point) -> Rig:
    """Orbit around ``point`` from now on, seen from where the camera is, and focus on it."""
    return make_rig(rig.position, point, rig.up, rig.fov, rig.aperture)


def pixel_ray(rig: Rig, x: float, y: float, aspect: float) -> np.ndarray:
    """Unit direction of the ray through view fraction (x, y) (0..1, y down) of a pinhole camera."""
    right, image_up = screen_axes(rig)
    half = math.tan(math.radians(rig.fov) / 2.0)
    d = rig.direction + (2.0 * x - 1.0) * half * right + (1.0 - 2.0 * y) * (half / aspect) * image_up
    return d / np.linalg.norm(d)
