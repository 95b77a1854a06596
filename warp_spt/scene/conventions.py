"""The command line's conventions for a scene it was not told about: which way is up, the look.

Two kinds of scene reach ``warp-spt``: the seed's own (its demo, its OBJ spheres ``b`` and MTL tags,
usually with an explicit ``-cam``), which must render exactly as the seed renders them, and users'
models exported by other tools, which are Y-up (the convention of OBJ exporters and glTF) and
usually come without materials. :func:`up_axis` and :func:`wants_studio` are the rules, written
once; ``warp-spt``, its animations and ``warp-spt view`` all apply them. Pure functions of what the
loader recorded (:attr:`Scene.seed_dialect`, :attr:`Scene.bare`) and of the flags given.
"""

from __future__ import annotations

from dataclasses import dataclass

SEED_UP, MODEL_UP = "z", "y"


@dataclass(frozen=True)
class UpChoice:
    """The up axis a command uses and why, for its "framed" line."""

    axis: str
    reason: str          # "" when the user gave --up

    @property
    def note(self) -> str:
        """E.g. ``Y up (a standard OBJ model; --up z to change)``; empty for an explicit --up."""
        if not self.reason:
            return ""
        other = SEED_UP if self.axis == MODEL_UP else MODEL_UP
        return f"{self.axis.upper()} up ({self.reason}; --up {other} to change)"


def up_axis(given: str | None, *, demo: bool, seed_dialect: bool, cam_given: bool) -> UpChoice:
    """The world's up axis: ``--up`` always wins; the built-in demo, a scene in the seed's dialect
    or an explicit ``-cam`` (the seed's camera convention) keep the seed's Z; any other model (a
    standard OBJ) is Y up, as OBJ exporters and glTF write them."""
    if given:
        return UpChoice(given, "")
    if demo:
        return UpChoice(SEED_UP, "the built-in demo")
    if seed_dialect:
        return UpChoice(SEED_UP, "the seed's OBJ/MTL dialect")
    if cam_given:
        return UpChoice(SEED_UP, "-cam uses the seed's Z-up convention")
    return UpChoice(MODEL_UP, "a standard OBJ model")


def wants_studio(given: bool | None, *, bare: bool, sky_given: bool) -> bool:
    """The studio look (clay, ground, key light, soft sky): ``--studio``/``--no-studio`` win; else on
    for a bare model (no material library read) with no sky flag."""
    if given is not None:
        return given
    return bare and not sky_given
