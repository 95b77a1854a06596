"""warp_spt: a small physically based path tracer on NVIDIA Warp.

The public surface, in the order data flows::

    scene = warp_spt.load_scene(["box.obj", "balls.obj"], ["box.mtl"])   # text -> numpy Scene
    image = warp_spt.render(scene, warp_spt.Camera(), width=512, height=512, spp=16)  # linear float32
    warp_spt.save_image("out.png", image)                                  # tone-mapped PNG, .npy or .pfm

:func:`load_obj` and :func:`load_mtl` read single files; :class:`SceneError` is the one exception for
bad scene input (it names the file and line); :class:`Film` holds float64 sums so renders of
separate sample ranges merge exactly; :func:`render_film` returns one. :func:`render_scene` takes a
:class:`RenderSettings` (integrator and sampler chosen by name from ``INTEGRATORS`` and ``SAMPLERS``)
and returns a :class:`RenderResult` (film, image, stats). :func:`render_progressive` renders in
passes until a sample count, a time budget or a target error, optionally adaptively, and returns a
:class:`ProgressiveResult` (image, per-pixel standard error, per-pixel sample counts, stats);
:func:`relative_error` is the one definition of an image's relative error (docs/error.md).
"""

from __future__ import annotations

from .camera import Camera
from .errors import SceneError
from .film import Film, save_image, tonemap_seed, tonemap_srgb
from .loader import load_scene
from .mtl import load_mtl
from .obj import load_obj
from .progressive import ProgressiveResult, relative_error, render_progressive
from .integrators import INTEGRATORS
from .renderer import RenderResult, RenderSettings, RenderStats, render, render_film, render_scene
from .samplers import SAMPLERS
from .scene import Material, ObjData, Scene
from .sky import Sky

__version__ = "0.1.0"

__all__ = [
    "Camera",
    "INTEGRATORS",
    "RenderResult",
    "RenderSettings",
    "RenderStats",
    "SAMPLERS",
    "Film",
    "Material",
    "ObjData",
    "ProgressiveResult",
    "Scene",
    "SceneError",
    "Sky",
    "load_mtl",
    "load_obj",
    "load_scene",
    "render",
    "relative_error",
    "render_film",
    "render_progressive",
    "render_scene",
    "save_image",
    "tonemap_seed",
    "tonemap_srgb",
    "__version__",
]
