"""warp_spt: a small physically based path tracer on NVIDIA Warp.

The public surface, in the order data flows::

    scene = warp_spt.load_scene(["box.obj", "balls.obj"], ["box.mtl"])   # text -> numpy Scene
    image = warp_spt.render(scene, warp_spt.Camera(), width=512, height=512, spp=16)  # linear float32
    warp_spt.save_image("out.png", image)                                  # tone-mapped PNG, .npy or .pfm

:func:`quick_view` renders the command line's first image of a scene in one call (framed, Y up
for a standard OBJ, the studio look for a scene with no light of its own); :func:`first_view` returns
that view's scene, camera and sky. :meth:`Camera.frame` fits a camera to a scene (``Camera.frame(scene, up="y")`` for a Y-up model) and
:meth:`Camera.look_at` aims one at a point. :func:`render` recentres scenes far from the origin
(:func:`warp_spt.scene.recentre.recentre`) before rendering. :func:`load_obj` and :func:`load_mtl` read
single files; :class:`SceneError` is the one exception for bad scene input (it names the file and
line); :class:`Film` holds float64 sums so renders of separate sample ranges merge exactly;
:func:`render_film` returns one. :func:`render_scene` takes a :class:`RenderSettings` (integrator
and sampler chosen by name from ``INTEGRATORS`` and ``SAMPLERS``) and returns a
:class:`RenderResult`, the one result type of every render (image, per-pixel standard error and sample
counts, film, stats). :func:`texture` registers a procedural texture written as a Warp function
(:mod:`warp_spt.device.proctex`), usable as ``map_Kd proc:NAME``. :func:`render_progressive` renders in
passes until a sample count, a time budget or a target error, optionally adaptively, and returns a
:class:`RenderResult` with a per-pixel standard error (``ProgressiveResult`` is another name for it);
:func:`relative_error` is the one definition of an image's relative error (docs/error.md).

Gradients: :func:`parameters` names what a user can edit (``"wall.diffuse"``, ``"ball.roughness"``,
``"quad.diffuse_map"``, ``"sky.color"``, ``"camera.position"``...); :func:`render_gradients` returns the image and the
gradients of a loss (``warp_spt.losses``) by name, on every core (docs/gradients.md);
:func:`check_gradients` compares them with finite differences of the render and prints a table.

The names are imported on first use (PEP 562), so ``import warp_spt`` is cheap and the command line
can install its Ctrl-C handling before numpy and Warp are loaded.
"""

from __future__ import annotations

import importlib

TYPE_CHECKING = False   # typing.TYPE_CHECKING without importing typing (start-up time)

__version__ = "0.1.0"

# public name -> submodule that defines it
_EXPORTS = {
    "Camera": "scene.camera",
    "Film": "rendering.film",
    "GradientCheck": "diff.check",
    "GradientResult": "diff.gradients",
    "INTEGRATORS": "integrators",
    "RenderResult": "rendering.result",
    "RenderSettings": "rendering.settings",
    "RenderStats": "rendering.result",
    "SAMPLERS": "samplers",
    "Material": "scene.model",
    "ProcParams": "device.proctex",
    "ProgressiveResult": "rendering.result",
    "ObjData": "scene.model",
    "Scene": "scene.model",
    "SceneParameters": "diff.params",
    "SceneError": "scene.errors",
    "Sky": "scene.sky",
    "load_environment": "images.environment",
    "add_volume": "media.grid",
    "SunLight": "scene.lights",
    "PointLight": "scene.lights",
    "SpotLight": "scene.lights",
    "load_gltf": "gltf",
    "load_mtl": "io.mtl",
    "load_obj": "io.obj",
    "load_ply": "io.ply",
    "load_scene": "io.loader",
    "parameters": "diff.params",
    "check_gradients": "diff.check",
    "proc_texture": "device.proctex",
    "register_texture": "device.proctex",
    "relative_error": "rendering.result",
    "render": "rendering.tiles",
    "render_film": "rendering.tiles",
    "render_gradients": "diff.gradients",
    "render_arrays": "diff.interop",
    "render_torch": "diff.interop",
    "render_progressive": "rendering.progressive",
    "render_scene": "rendering.tiles",
    "quick_view": "rendering.tiles",
    "first_view": "rendering.first_view",
    "FirstView": "rendering.first_view",
    "save_image": "images.files",
    "texture": "device.proctex",
    "tonemap_seed": "images.files",
    "tonemap_srgb": "images.files",
    "to_display": "images.files",
    "up_axis": "scene.conventions",
}

_SUBMODULES = ("demo", "losses")    # reached as warp_spt.losses.l2 etc.

__all__ = sorted(_EXPORTS) + list(_SUBMODULES) + ["__version__"]

if TYPE_CHECKING:  # pragma: no cover - for type checkers and IDEs only
    from warp_spt import demo, losses
    from warp_spt.device.proctex import (
        ProcParams,
        proc_texture,
        register_texture,
        texture,
    )
    from warp_spt.diff.check import GradientCheck, check_gradients
    from warp_spt.diff.gradients import GradientResult, render_gradients
    from warp_spt.diff.interop import render_arrays, render_torch
    from warp_spt.diff.params import SceneParameters, parameters
    from warp_spt.integrators import INTEGRATORS
    from warp_spt.images.files import save_image, to_display, tonemap_seed, tonemap_srgb
    from warp_spt.images.environment import load_environment
    from warp_spt.media.grid import add_volume
    from warp_spt.gltf import load_gltf
    from warp_spt.io.loader import load_scene
    from warp_spt.io.mtl import load_mtl
    from warp_spt.io.obj import load_obj
    from warp_spt.io.ply import load_ply
    from warp_spt.rendering.film import Film
    from warp_spt.rendering.progressive import render_progressive
    from warp_spt.rendering.result import (
        ProgressiveResult,
        RenderResult,
        RenderStats,
        relative_error,
    )
    from warp_spt.rendering.settings import RenderSettings
    from warp_spt.rendering.first_view import FirstView, first_view
    from warp_spt.rendering.tiles import quick_view, render, render_film, render_scene
    from warp_spt.samplers import SAMPLERS
    from warp_spt.scene.camera import Camera
    from warp_spt.scene.conventions import up_axis
    from warp_spt.scene.errors import SceneError
    from warp_spt.scene.model import Material, ObjData, Scene
    from warp_spt.scene.lights import PointLight, SpotLight, SunLight
    from warp_spt.scene.sky import Sky


def __getattr__(name: str):
    if name in _SUBMODULES:
        return importlib.import_module(f".{name}", __name__)
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'warp_spt' has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_EXPORTS) | set(_SUBMODULES))
