"""The seed's camera: Z up, a position and a view direction, horizontal field of view, thin lens."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Camera:
    """A pinhole or thin-lens camera in the seed's conventions (SEMANTICS §3).

    ``direction`` is a view direction, not a look-at target. ``fov`` is the full horizontal angle in
    degrees. The image plane lies at ``focus`` along the view direction, so it is also the plane in
    focus; ``aperture`` is the lens radius (0 gives a pinhole). The defaults frame the seed's
    Cornell box.
    """

    position: tuple[float, float, float] = (4.0, -55.0, 16.0)
    direction: tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov: float = 38.0
    aperture: float = 0.001
    focus: float = 27.0

    def validate(self) -> None:
        """Raise ValueError for a camera no renderer can use."""
        vals = [*self.position, *self.direction, self.fov, self.aperture, self.focus]
        if not all(math.isfinite(v) for v in vals):
            raise ValueError("camera values must be finite numbers")
        if float(np.linalg.norm(np.asarray(self.direction, dtype=np.float64))) == 0.0:
            raise ValueError("camera view direction must not be zero")
        if not 0.0 < self.fov < 180.0:
            raise ValueError(f"camera fov must be in (0, 180) degrees, got {self.fov}")
        if self.aperture < 0.0:
            raise ValueError(f"camera aperture must be >= 0, got {self.aperture}")
        if self.focus <= 0.0:
            raise ValueError(f"camera focus distance must be > 0, got {self.focus}")

    def frame(self, width: int, height: int) -> dict[str, np.ndarray]:
        """The image plane in world space (float64): origin, upper-left corner and pixel steps.

        Row 0 is the top of the image. Pixel (x, y) covers
        ``upper_left + (x + a) * x_step - (y + b) * y_step`` for a, b in [0, 1).
        Looking straight up or straight down is well defined (the seed gave NaN looking down, Q12).
        """
        self.validate()
        d = np.asarray(self.direction, dtype=np.float64)
        d = d / np.linalg.norm(d)
        if d[2] >= 0.99999:      # straight up: the seed's choice of axes
            right, up = np.array([1.0, 0.0, 0.0]), np.array([0.0, -1.0, 0.0])
        elif d[2] <= -0.99999:   # straight down: mirror of the above, so +Y is up in the image
            right, up = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
        else:
            right = np.cross(d, [0.0, 0.0, 1.0])
            right /= np.linalg.norm(right)
            up = np.cross(right, d)
            up /= np.linalg.norm(up)
        half = self.focus * math.tan(math.radians(self.fov) / 2.0)
        centre = np.asarray(self.position, dtype=np.float64) + d * self.focus
        upper_left = centre - right * half + up * half * height / width
        step = 2.0 * half / width
        return {
            "origin": np.asarray(self.position, dtype=np.float64),
            "upper_left": upper_left,
            "x_step": right * step,
            "y_step": up * step,
            "right": right,
            "up": up,
            "lens_radius": np.float64(self.aperture),
        }
