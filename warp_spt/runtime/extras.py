"""How to install an optional part of warp_spt: one wording for every message that needs one.

warp_spt is installed from a clone (it is not on PyPI), so a hint gives the command that works
there, ``pip install ".[view]"`` run in the clone's folder, and the one for a published package.
"""

from __future__ import annotations


def install_hint(extra: str) -> str:
    """E.g. ``pip install ".[view]" in the warp_spt clone (or "warp-spt[view]" once published)``."""
    return f'pip install ".[{extra}]" in the warp_spt clone (or "warp-spt[{extra}]" if installed from an index)'
