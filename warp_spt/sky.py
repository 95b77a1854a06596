"""The seed's three skies (SEMANTICS §9) plus any constant colour: the radiance of a missed ray."""

from __future__ import annotations

import math
from dataclasses import dataclass

SKY_CONSTANT = 0
SKY_GRADIENT = 1


ZENITH = (0.5, 0.7, 1.0)      # the seed's GradientSky, looking straight up
NADIR = (1.0, 1.0, 1.0)       # and straight down


@dataclass(frozen=True)
class Sky:
    """``kind`` SKY_CONSTANT returns ``color``; SKY_GRADIENT blends linearly in the direction's z from
    ``nadir`` (z = -1) to ``zenith`` (z = 1); the seed's is (0.75-0.25z, 0.85-0.15z, 1)."""

    kind: int = SKY_CONSTANT
    color: tuple[float, float, float] = (0.3, 0.6, 0.8)
    zenith: tuple[float, float, float] = ZENITH
    nadir: tuple[float, float, float] = NADIR

    @staticmethod
    def black() -> "Sky":
        """The seed's 'BlackSky', which is a dull light blue (0.3, 0.6, 0.8) (quirk Q2). The default."""
        return Sky(SKY_CONSTANT, (0.3, 0.6, 0.8))

    @staticmethod
    def gradient(zenith=ZENITH, nadir=NADIR) -> "Sky":
        """The seed's GradientSky: white at the nadir to (0.5, 0.7, 1) at the zenith (both settable,
        finite and non-negative, not both black)."""
        z, n = _colour("sky zenith", zenith), _colour("sky nadir", nadir)
        if max(z + n) <= 0.0:
            raise ValueError("a gradient sky needs some colour at its zenith or nadir")
        return Sky(SKY_GRADIENT, (0.0, 0.0, 0.0), z, n)

    def gradient_terms(self) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """(mean, slope): the gradient sky's radiance is mean + slope * z (float64 sums)."""
        mean = tuple(0.5 * (a + b) for a, b in zip(self.zenith, self.nadir))
        slope = tuple(0.5 * (a - b) for a, b in zip(self.zenith, self.nadir))
        return mean, slope

    @staticmethod
    def pink() -> "Sky":
        """The seed's PinkSky, the constant (1, 0.431, 0.888)."""
        return Sky(SKY_CONSTANT, (1.0, 0.431, 0.888))

    @staticmethod
    def constant(r: float, g: float, b: float) -> "Sky":
        """Any constant radiance; ``Sky.constant(0, 0, 0)`` is a truly black sky."""
        return Sky(SKY_CONSTANT, _colour("sky colour", (r, g, b)))

    @staticmethod
    def from_index(k: int) -> "Sky":
        """The seed's ``-sky K``: 1 gradient, 2 pink, anything else the (blue) BlackSky."""
        return {1: Sky.gradient(), 2: Sky.pink()}.get(int(k), Sky.black())

    def radiance(self, z: float) -> tuple[float, float, float]:
        """Reference value in Python for a unit direction with Z component ``z`` (used by tests)."""
        if self.kind == SKY_GRADIENT:
            mean, slope = self.gradient_terms()
            return tuple(m + k * z for m, k in zip(mean, slope))
        return self.color


def _colour(what: str, value) -> tuple[float, float, float]:
    c = tuple(float(v) for v in value)
    if len(c) != 3 or not all(math.isfinite(v) and v >= 0.0 for v in c):
        raise ValueError(f"{what} must be three finite non-negative numbers, got {value}")
    return c
