"""The kinds of each plugin family, by name: one tuple per family, the one list of its kinds.

A family's device registry is built from its tuple here: kind ``NAME`` is the module
``warp_spt.<family>.NAME`` (``emitters``: a module exporting ``KIND``, a ``LightKind`` named ``NAME``;
``media``: a module whose ``NAME`` is ``NAME``), imported in this order, and :func:`check_kind` makes
a registry refuse a module that is not the kind its name says. The order is the light table's (each
kind's entries and its field in ``emitters.table.Lights``) and the index a medium row's ``kind``
holds. Material kinds keep their list beside their columns (``scene.material_schema.MATERIAL_KINDS``);
the samplers' default, ``DEFAULT_SAMPLER``, is here so that the viewer names it without Warp.

So a new light or medium kind is its module and its name here. Nothing here imports Warp: the host
side (a medium's check, a file's reader) names kinds from this list without the device.
"""

from __future__ import annotations

LIGHT_KINDS: tuple[str, ...] = ("triangle", "sphere", "sky", "environment", "punctual")
MEDIUM_KINDS: tuple[str, ...] = ("homogeneous", "grid")
# The sampler every front end uses unless told otherwise (RenderSettings, the command line, the
# viewer and the command it copies), named here without Warp; warp_spt.samplers explains the choice.
DEFAULT_SAMPLER = "sobol-affine"


def check_kind(family: str, name: str, found: str | None) -> None:
    """ImportError unless the module registered as ``family`` kind ``name`` calls itself ``found``."""
    if found != name:
        raise ImportError(f"{family} kind {name!r} (scene/families.py): its module warp_spt.{family}.{name} "
                          f"declares the kind {found!r}; the module and its name in the list must agree")


__all__ = ["DEFAULT_SAMPLER", "LIGHT_KINDS", "MEDIUM_KINDS", "check_kind"]
