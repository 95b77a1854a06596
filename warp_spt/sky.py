"""The seed's three skies (SEMANTICS §9) plus any constant colour: the radiance of a missed ray."""

from __future__ import annotations

import math
from dataclasses import dataclass

SKY_CONSTANT = 0
SKY_GRADIENT = 1


@dataclass(frozen=True)
class Sky:
    """``kind`` SKY_CONSTANT returns ``color``; SKY_GRADIENT is (0.75-0.25z, 0.85-0.15z, 1) for direction z."""

    kind: int = SKY_CONSTANT
    color: tuple[float, float, float] = (0.3, 0.6, 0.8)

    @staticmethod
    def black() -> "Sky":
        """The seed's 'BlackSky', which is a dull light blue (0.3, 0.6, 0.8) (quirk Q2). The default."""
        return Sky(SKY_CONSTANT, (0.3, 0.6, 0.8))

    @staticmethod
    def gradient() -> "Sky":
        """The seed's GradientSky: white at the nadir to (0.5, 0.7, 1) at the zenith."""
        return Sky(SKY_GRADIENT, (0.0, 0.0, 0.0))

    @staticmethod
    def pink() -> "Sky":
        """The seed's PinkSky, the constant (1, 0.431, 0.888)."""
        return Sky(SKY_CONSTANT, (1.0, 0.431, 0.888))

    @staticmethod
    def constant(r: float, g: float, b: float) -> "Sky":
        """Any constant radiance; ``Sky.constant(0, 0, 0)`` is a truly black sky."""
        c = (float(r), float(g), float(b))
        if not all(math.isfinite(v) and v >= 0.0 for v in c):
            raise ValueError(f"sky colour must be finite and non-negative, got {c}")
        return Sky(SKY_CONSTANT, c)

    @staticmethod
    def from_index(k: int) -> "Sky":
        """The seed's ``-sky K``: 1 gradient, 2 pink, anything else the (blue) BlackSky."""
        return {1: Sky.gradient(), 2: Sky.pink()}.get(int(k), Sky.black())

    def radiance(self, z: float) -> tuple[float, float, float]:
        """Reference value in Python for a unit direction with Z component ``z`` (used by tests)."""
        if self.kind == SKY_GRADIENT:
            return (0.75 - 0.25 * z, 0.85 - 0.15 * z, 1.0)
        return self.color
