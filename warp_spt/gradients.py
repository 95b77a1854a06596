"""Differentiable rendering: images whose gradients with respect to material parameters flow through ``wp.Tape``.

Differentiation is a mode of the same integrator, not a copy of it: the kernel here runs the very
``step`` function of the fast kernel (``warp_spt.integrators``), in a loop unrolled to a fixed depth
with the path's ``alive`` flag instead of a dynamic loop, because Warp differentiates a dynamic loop
correctly only when the carried state is additive (a ``break`` silently zeroes gradients).
Visibility is not differentiated (no edge sampling): gradients reach material colours and emission,
which is exact for them because the sampled paths do not depend on those values.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import warp as wp

from .camera import Camera
from .device_scene import DeviceScene, Features, Geometry, Materials, Textures
from .integrators import CameraParams, RenderParams, camera_params, check_integrator, get_step
from .lights import Lights, light_table, sky_emits
from .sky import Sky

MAX_UNROLLED_DEPTH = 8     # compile time grows quickly with the unrolled depth


def _make_kernel(step, start_path, depth: int):
    @wp.kernel(module="unique")
    def trace_diff(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, cam: CameraParams,
                   rp: RenderParams, image: wp.array(dtype=wp.vec3)):
        pix = wp.tid()
        inv_spp = 1.0 / float(rp.sample_count)
        for j in range(rp.sample_count):
            path = start_path(cam, pix, rp.width, rp.seed, rp.sample_start + j)
            for _bounce in range(wp.static(depth)):      # unrolled: each step traces one ray
                if path.alive != 0:
                    path = step(geo, mats, tex, lights, rp, path)
            wp.atomic_add(image, pix, path.radiance * inv_spp)

    return trace_diff


_kernels: dict[tuple[str, str, Features, int], wp.Kernel] = {}


@dataclass
class DiffRender:
    """A differentiable render: ``image`` (H*W vec3, on the tape) and the parameters it depends on."""

    image: wp.array
    tape: wp.Tape
    width: int
    height: int

    def numpy(self) -> np.ndarray:
        return self.image.numpy().reshape(self.height, self.width, 3)


def enable_material_gradients(scene: DeviceScene) -> None:
    """Make the material colour and emission arrays of ``scene`` carry gradients
    (``scene.materials.diffuse.grad`` etc. after ``tape.backward``)."""
    m = scene.materials
    for name in ("diffuse", "reflect", "refract", "emission"):
        a = getattr(m, name)
        if not a.requires_grad:
            setattr(m, name, wp.array(a.numpy(), dtype=wp.vec3, device=a.device, requires_grad=True))


def render_differentiable(scene: DeviceScene, camera: Camera | None = None, *, width: int = 32,
                          height: int = 32, spp: int = 4, max_depth: int = 4, sky: Sky | None = None,
                          seed: int = 0, texture_filter: str = "nearest", integrator: str = "seed",
                          sampler: str = "independent") -> DiffRender:
    """Render on a ``wp.Tape``; call ``result.tape.backward(grads={result.image: adjoint})`` and read
    e.g. ``scene.materials.diffuse.grad`` (call :func:`enable_material_gradients` first).

    Single-threaded (the tape is global in Warp 1.19). ``max_depth`` is unrolled, at most
    MAX_UNROLLED_DEPTH. Same integrator, sampler and samples 0..spp-1 as :func:`warp_spt.render`
    (Russian roulette off).
    """
    if not 1 <= max_depth <= MAX_UNROLLED_DEPTH:
        raise ValueError(f"max_depth must be in [1, {MAX_UNROLLED_DEPTH}] for differentiable renders")
    if width < 1 or height < 1 or spp < 1:
        raise ValueError("width, height and spp must be positive")
    check_integrator(integrator)
    sky = sky or Sky.black()
    feats = replace(scene.features, sky=sky_emits(sky))
    key = (integrator, sampler, feats, max_depth)
    if key not in _kernels:
        _kernels[key] = _make_kernel(*get_step(integrator, sampler, feats), max_depth)
    kernel = _kernels[key]
    rp = RenderParams()
    rp.width, rp.pixel_start, rp.sample_start, rp.sample_count = width, 0, 0, spp
    rp.max_depth, rp.roulette_depth, rp.seed = max_depth, 0, wp.uint32(seed & 0xFFFFFFFF)
    image = wp.zeros(width * height, dtype=wp.vec3, device=scene.device, requires_grad=True)
    tape = wp.Tape()
    with tape:
        wp.launch(kernel, dim=width * height, device=scene.device, inputs=[
            scene.geometry, scene.materials, scene.textures(texture_filter), light_table(scene, sky),
            camera_params(camera or Camera(), width, height), rp, image])
    return DiffRender(image, tape, width, height)
