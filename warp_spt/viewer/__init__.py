"""Explore a scene interactively: a live viewer in the browser and in Jupyter.

* :class:`Session` (``warp_spt.viewer.session``): the host-independent state machine - camera,
  settings, a background render thread that previews while the camera moves and refines when it
  stops.
* ``warp_spt.viewer.server``: the browser host, ``serve(...)`` and ``main(argv)`` (needs the
  ``view`` extra: aiohttp).
* :class:`Viewer` (``warp_spt.viewer.widget``): the Jupyter host, an anywidget (``view`` extra).

Both hosts load the same front end, ``static/viewer.js``. See docs/viewer.md.
"""

from __future__ import annotations

import importlib

_EXPORTS = {"Session": "session", "ViewSettings": "session", "Viewer": "widget", "serve": "server",
            "main": "server"}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'warp_spt.viewer' has no attribute {name!r}")
    return getattr(importlib.import_module(f".{module}", __name__), name)


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS))
