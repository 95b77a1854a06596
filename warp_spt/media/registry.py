"""The medium kinds, in ``scene.families.MEDIUM_KINDS`` order (a medium row's ``kind`` is its index
there), and what they declare a scene needs (``Features.media``). Kind ``NAME`` is the module
``warp_spt.media.NAME`` (its ``NAME``, ``declare`` and ``make``): a new kind is that module and its
name in the list."""

from __future__ import annotations

import importlib

from warp_spt.device.media_table import media_of
from warp_spt.scene.families import MEDIUM_KINDS, check_kind
from warp_spt.scene.media import interface_rows


def _kind(name: str):
    module = importlib.import_module(f"warp_spt.media.{name}")
    check_kind("media", name, getattr(module, "NAME", None))
    return module


KINDS = {name: _kind(name) for name in MEDIUM_KINDS}


def declare(scene) -> tuple[str, ...]:
    """``Features.media`` of a scene (sorted): what the kinds of its media declare (``declare(medium)``:
    the kind's name and any code path of its own), "emission" where some medium emits and
    "interface" where shadow rays cross pass-through medium boundaries; () for a scene without media."""
    media, _, rows = media_of(scene)
    if not media:
        return ()
    names = set().union(*(KINDS[m.kind].declare(m) for m in media))
    if any(max(m.emission) > 0 and max(m.sigma_a) > 0 for m in media):
        names.add("emission")
    if (interface_rows(scene.materials) & (rows >= 0)).any():
        names.add("interface")
    return tuple(sorted(names))
