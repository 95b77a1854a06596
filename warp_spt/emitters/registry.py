"""The light kinds, in ``scene.families.LIGHT_KINDS`` order: that order is the order of their entries
in the light table and of their fields in ``table.Lights``. Kind ``NAME`` is the module
``warp_spt.emitters.NAME`` exporting ``KIND`` (a ``base.LightKind`` named ``NAME``): a new kind is that
module and its name in the list."""

from __future__ import annotations

import importlib

from warp_spt.scene.families import LIGHT_KINDS, check_kind


def _kind(name: str):
    kind = getattr(importlib.import_module(f"warp_spt.emitters.{name}"), "KIND", None)
    check_kind("emitters", name, getattr(kind, "name", None))
    return kind


KINDS = tuple(_kind(name) for name in LIGHT_KINDS)


def declare(scene, used, base) -> tuple[str, ...]:
    """``Features.lights`` of a scene (sorted): what every kind declares it needs from it
    (``LightKind.declare``; ``used``: the material rows its geometry uses, ``base``: its other features)."""
    return tuple(sorted(set().union(*(k.declare(scene, used, base) for k in KINDS))))


def declare_sky(sky) -> frozenset:
    """What every kind declares it needs from a render's sky (``LightKind.declare_sky``)."""
    return frozenset().union(*(k.declare_sky(sky) for k in KINDS))
