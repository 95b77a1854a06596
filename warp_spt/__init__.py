"""warp_spt: a small physically based path tracer on NVIDIA Warp.

The public surface: :func:`load_scene` (OBJ/MTL files to a :class:`Scene`), :func:`render` (a Scene
to a linear float32 image), :class:`Camera`, :class:`Sky`, :func:`save_image` and :class:`SceneError`.
"""

from __future__ import annotations

__version__ = "0.1.0"
