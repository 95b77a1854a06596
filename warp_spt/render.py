"""render(): split the image into tiles, launch the specialised kernel from a thread pool, return linear HDR."""

from __future__ import annotations

from typing import Callable

import numpy as np

from .camera import Camera
from .scene import Scene
from .sky import Sky

ProgressFn = Callable[[int, int], None]


def render(
    scene: Scene,
    camera: Camera | None = None,
    *,
    width: int = 500,
    height: int = 500,
    spp: int = 16,
    max_depth: int = 6,
    sky: Sky | None = None,
    seed: int = 0,
    threads: int | None = None,
    device: str = "cpu",
    texture_filter: str = "nearest",
    progress: bool | ProgressFn = False,
    sample_offset: int = 0,
) -> np.ndarray:
    """Render ``scene`` and return a float32 (height, width, 3) array of linear radiance.

    (Work in progress: the engine lands with issue 3.)
    """
    raise NotImplementedError
