"""The seed's three skies (SEMANTICS §9) plus any constant colour: the radiance of a missed ray.

A Sky is checked when it is made (ValueError, as for :class:`warp_spt.scene.camera.Camera`): its colour
must lie in [0, MAX_RADIANCE] (:mod:`warp_spt.scene.limits`), so no sky can overflow a sample. The
gradient sky varies with the height of a direction along an up axis: the sky's own ``up`` if given,
else the camera's (the seed's Z by default), so a Y-up scene seen by a Y-up camera gets the same
sky as the equivalent Z-up scene.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

if TYPE_CHECKING:     # numpy comes with it: the command line reads this module before its Ctrl-C handlers
    from warp_spt.scene.environment import EnvironmentMap
from warp_spt.scene.limits import MAX_COORDINATE, MAX_ENV_ROTATE, MAX_RADIANCE, MIN_DIRECTION

SKY_CONSTANT = 0
SKY_GRADIENT = 1
SKY_ENVIRONMENT = 2
Z_UP = (0.0, 0.0, 1.0)


ZENITH = (0.5, 0.7, 1.0)      # the seed's GradientSky, looking straight up
NADIR = (1.0, 1.0, 1.0)       # and straight down


@dataclass(frozen=True)
class Sky:
    """``kind`` SKY_CONSTANT returns ``color``; SKY_GRADIENT blends linearly in z, the direction's
    component along the up axis, from ``nadir`` (z = -1) to ``zenith`` (z = 1); the seed's is
    (0.75-0.25z, 0.85-0.15z, 1).

    ``up`` is that axis (any non-zero 3-vector, stored normalised), or None to follow the camera's
    ``up`` (see :func:`warp_spt.emitters.light_table`). A constant sky does not depend on it.

    SKY_ENVIRONMENT is an environment map (``env``, see :meth:`environment`): its radiance
    times ``strength``, turned by ``rotate`` degrees about the up axis; ``background``, if given, is
    the colour camera rays see where they miss the scene (the map still lights it).

    ``plus`` (an environment sky only) is a constant or gradient sky lit beside the map: two infinite
    lights, one table entry each (the ``sky`` and ``environment`` light kinds), chosen by power, both
    in every MIS density; a ray that misses sees the sum of their radiances (a camera ray the
    ``background`` instead, if one is set). Its ``up``, if None, is the map's up axis.
    """

    kind: int = SKY_CONSTANT
    color: tuple[float, float, float] = (0.3, 0.6, 0.8)
    up: tuple[float, float, float] | None = None
    zenith: tuple[float, float, float] = ZENITH
    nadir: tuple[float, float, float] = NADIR
    env: EnvironmentMap | None = None
    strength: float = 1.0
    rotate: float = 0.0
    background: tuple[float, float, float] | None = None
    plus: Sky | None = None

    def __post_init__(self) -> None:
        problem = sky_problem(self.kind, self.color, self.up) or self._environment_problem() or self._plus_problem()
        for name in ("zenith", "nadir"):
            problem = problem or colour_problem(f"sky {name}", getattr(self, name))
        if not problem and self.kind == SKY_GRADIENT and max(self.zenith + self.nadir) <= 0.0:
            problem = "a gradient sky needs some colour at its zenith or nadir"
        if problem:
            raise ValueError(problem)
        for name in ("color", "zenith", "nadir"):
            object.__setattr__(self, name, tuple(float(c) for c in getattr(self, name)))
        if self.up is not None:
            object.__setattr__(self, "up", _unit(self.up))

    def _environment_problem(self) -> str | None:
        if (self.kind == SKY_ENVIRONMENT) != (self.env is not None):
            return "an environment sky (SKY_ENVIRONMENT) needs an EnvironmentMap, and only it takes one"
        if self.env is not None:
            from warp_spt.scene.environment import EnvironmentMap

            if not isinstance(self.env, EnvironmentMap):
                return f"environment must be a warp_spt.scene.environment.EnvironmentMap, got {type(self.env).__name__}"
        if not (isinstance(self.strength, (int, float)) and 0.0 <= float(self.strength) <= MAX_RADIANCE):
            return f"environment strength must be a number in [0, {MAX_RADIANCE:g}], got {self.strength!r}"
        if not (isinstance(self.rotate, (int, float)) and abs(float(self.rotate)) <= MAX_ENV_ROTATE):   # NaN fails
            return (f"environment rotation must be a number of degrees in [-{MAX_ENV_ROTATE:g}, {MAX_ENV_ROTATE:g}], "
                    f"got {self.rotate!r}")
        if self.background is not None:
            return colour_problem("environment background", self.background)
        return None

    def _plus_problem(self) -> str | None:
        """The light table holds one entry per infinite kind: one map and one constant/gradient sky."""
        if self.plus is None:
            return None
        if self.kind != SKY_ENVIRONMENT:
            return ("only an environment sky takes a plus sky (Sky.environment(..., plus=Sky.gradient())); "
                    f"this sky is kind {self.kind} itself")
        if not isinstance(self.plus, Sky) or self.plus.kind not in (SKY_CONSTANT, SKY_GRADIENT):
            return ("plus must be a constant or gradient Sky (one environment map per scene), got "
                    f"{self.plus!r:.80}")
        return None

    @staticmethod
    def environment(image, rotate: float = 0.0, strength: float = 1.0, background=None, up=None,
                    name: str = "environment map", plus: "Sky | None" = None) -> "Sky":
        """An environment map: ``image`` an (H, W, 3) equirectangular radiance array with W = 2 H (or an
        :class:`EnvironmentMap`; ``warp_spt.load_environment`` reads .hdr, .exr, .pfm and PNG files),
        scaled by ``strength`` and turned ``rotate`` degrees about the up axis (``up``, default the
        camera's); camera rays that miss see ``background`` (an RGB colour) instead, if given.
        ``plus``: a constant or gradient sky that lights the scene beside the map (its radiance added)."""
        from warp_spt.scene.environment import EnvironmentMap

        env = image if isinstance(image, EnvironmentMap) else EnvironmentMap(image, name)
        return Sky(SKY_ENVIRONMENT, (0.0, 0.0, 0.0), None if up is None else tuple(up), env=env,
                   strength=float(strength), rotate=float(rotate),
                   background=None if background is None else tuple(float(c) for c in background), plus=plus)

    def colour_sky(self) -> Sky | None:
        """The constant or gradient sky among this sky's lights (the ``sky`` light kind's part): itself,
        an environment map's ``plus``, or None."""
        return self.plus if self.kind == SKY_ENVIRONMENT else self

    @staticmethod
    def black() -> "Sky":
        """The seed's 'BlackSky', which is a dull light blue (0.3, 0.6, 0.8) (quirk Q2). The default."""
        return Sky(SKY_CONSTANT, (0.3, 0.6, 0.8))

    @staticmethod
    def gradient(zenith=ZENITH, nadir=NADIR, up=None) -> "Sky":
        """The seed's GradientSky: white at the nadir to (0.5, 0.7, 1) at the zenith of ``up``
        (default: the camera's up axis); both colours settable (in [0, MAX_RADIANCE], not both black)."""
        return Sky(SKY_GRADIENT, (0.0, 0.0, 0.0), None if up is None else tuple(up), tuple(zenith), tuple(nadir))

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
        """Any constant radiance in [0, MAX_RADIANCE]; ``Sky.constant(0, 0, 0)`` is a truly black sky."""
        return Sky(SKY_CONSTANT, (r, g, b))

    @staticmethod
    def from_index(k: int) -> "Sky":
        """The seed's ``-sky K``: 1 gradient, 2 pink, anything else the (blue) BlackSky."""
        return {1: Sky.gradient(), 2: Sky.pink()}.get(int(k), Sky.black())

    def with_colours(self, **colours) -> Sky:
        """This sky with fields of ``colour_sky()`` replaced (the parameters ``sky.<field>``): an
        environment map's plus sky is replaced inside it (checked by Sky, as any new sky)."""
        if self.kind == SKY_ENVIRONMENT:
            if self.plus is None:
                raise ValueError("this environment sky has no constant or gradient part (plus) to set "
                                 f"{', '.join(colours)} of")
            return replace(self, plus=replace(self.plus, **colours))
        return replace(self, **colours)

    def colour_fields(self) -> tuple[str, ...]:
        """The colours this sky is made of, in the order of their rows in the device's colour array
        (``warp_spt.emitters.sky``) and of the parameters ``sky.<field>`` (``warp_spt.diff.params``); an
        environment sky's are its ``plus`` sky's (fields of ``colour_sky()``)."""
        part = self.colour_sky()
        if part is None:
            return ()
        return ("color",) if part.kind != SKY_GRADIENT else ("zenith", "nadir")

    def up_axis(self, camera_up=Z_UP) -> tuple[float, float, float]:
        """The unit up axis the gradient follows: ``up``, else ``camera_up`` (normalised)."""
        return self.up if self.up is not None else _unit(camera_up)

    def radiance(self, z: float) -> tuple[float, float, float]:
        """Reference value in Python for a unit direction whose component along the up axis is ``z``."""
        if self.kind == SKY_GRADIENT:
            mean, slope = self.gradient_terms()
            return tuple(m + k * z for m, k in zip(mean, slope))
        return self.color


def sky_problem(kind, color, up=None) -> str | None:
    """Why these sky values cannot be rendered exactly, or None."""
    if kind not in (SKY_CONSTANT, SKY_GRADIENT, SKY_ENVIRONMENT):
        return f"sky kind must be SKY_CONSTANT (0), SKY_GRADIENT (1) or SKY_ENVIRONMENT (2), got {kind!r}"
    problem = colour_problem("sky colour", color)
    if problem:
        return problem
    if up is not None and not (_numbers(up, 3) and all(math.isfinite(float(v)) for v in up)
                               and MIN_DIRECTION <= max(abs(float(v)) for v in up) <= MAX_COORDINATE):
        return (f"sky up must be a vector with components between {MIN_DIRECTION:g} and {MAX_COORDINATE:g} "
                f"in size (not zero), got {up!r}")
    return None


def colour_problem(what: str, color) -> str | None:
    if not _numbers(color, 3) or not all(0.0 <= float(c) <= MAX_RADIANCE for c in color):   # NaN fails too
        return f"{what} values must be three numbers in [0, {MAX_RADIANCE:g}], got {color!r}"
    return None


def _numbers(values, n: int) -> bool:
    """``values`` is a sequence of ``n`` real numbers (strings are not numbers here)."""
    try:
        return len(values) == n and not any(isinstance(v, (str, bytes)) or float(v) != float(v) for v in values)
    except (TypeError, ValueError):
        return False


def _unit(v) -> tuple[float, float, float]:
    """``v`` normalised in float64, scaled first so that no square overflows; axes stay exact."""
    big = max(abs(float(x)) for x in v)
    s = [float(x) / big for x in v]
    n = math.sqrt(sum(x * x for x in s))
    return (s[0] / n, s[1] / n, s[2] / n)
