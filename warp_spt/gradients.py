"""Differentiable rendering: images whose gradients with respect to material parameters flow through ``wp.Tape``.

The fast renderer (``integrator``) is forward-only with a dynamic bounce loop. Warp differentiates
a dynamic loop correctly only when the carried state is additive, and a ``break`` silently zeroes
gradients, so this module builds a second kernel from the SAME intersection and shading functions
with the bounce loop unrolled to a fixed depth and an ``alive`` flag instead of ``break``.
Visibility is not differentiated (no edge sampling): gradients reach material colours and emission,
which is exact for them because the sampled paths do not depend on those values.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from .camera import Camera
from .device_scene import DeviceScene, Features, SceneArrays
from .geometry import KIND_MISS, NO_HIT, make_closest_hit
from .integrator import CameraParams, camera_params, camera_ray
from .sampling import stream_state
from .shading import make_shading, offset_origin, sky_radiance
from .sky import Sky

MAX_UNROLLED_DEPTH = 8     # compile time grows quickly with the unrolled depth


def _make_kernel(features: Features, depth: int):
    closest_hit = make_closest_hit(features)
    surface_at, emission, sample_scatter = make_shading(features)

    @wp.kernel(module="unique")
    def trace_diff(s: SceneArrays, cam: CameraParams, width: int, spp: int, sky_kind: int,
                   sky_color: wp.vec3, seed: wp.uint32, bilinear: int, image: wp.array(dtype=wp.vec3)):
        pix = wp.tid()
        x = float(pix % width)
        y = float(pix // width)
        inv_spp = 1.0 / float(spp)
        for j in range(spp):
            state = stream_state(seed, pix, j)
            r1 = wp.randf(state)
            r2 = wp.randf(state)
            r3 = wp.randf(state)
            r4 = wp.randf(state)
            o, d = camera_ray(cam, x, y, r1, r2, r3, r4)
            throughput = wp.vec3(1.0, 1.0, 1.0)
            total = wp.vec3(0.0, 0.0, 0.0)
            alive = int(1)
            for bounce in range(wp.static(depth)):      # unrolled: no break, an alive flag instead
                if alive != 0:
                    h = closest_hit(s, o, d, NO_HIT)
                    if h.kind == KIND_MISS:
                        total = total + wp.cw_mul(throughput, sky_radiance(sky_kind, sky_color, d))
                        alive = 0
                    else:
                        sf = surface_at(s, h, o, d)
                        if wp.static(features.emitters):
                            total = total + wp.cw_mul(throughput, emission(s, sf, bilinear))
                        if bounce == wp.static(depth - 1):
                            alive = 0
                        else:
                            sc, state = sample_scatter(s, sf, d, bilinear, state)
                            if sc.alive == 0:
                                alive = 0
                            else:
                                throughput = wp.cw_mul(throughput, sc.weight)
                                o = offset_origin(sf.p, sf.ng, sc.through, s.extent)
                                d = sc.dir
            wp.atomic_add(image, pix, total * inv_spp)

    return trace_diff


_kernels: dict[tuple[Features, int], wp.Kernel] = {}


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
    """Make the material colour and emission arrays of ``scene`` carry gradients."""
    s = scene.arrays
    for name in ("mat_diffuse", "mat_reflect", "mat_refract", "mat_emission"):
        a = getattr(s, name)
        if not a.requires_grad:
            setattr(s, name, wp.array(a.numpy(), dtype=wp.vec3, device=a.device, requires_grad=True))


def render_differentiable(scene: DeviceScene, camera: Camera | None = None, *, width: int = 32,
                          height: int = 32, spp: int = 4, max_depth: int = 4, sky: Sky | None = None,
                          seed: int = 0, texture_filter: str = "nearest") -> DiffRender:
    """Render on a ``wp.Tape``; call ``result.tape.backward(grads={result.image: adjoint})`` and read
    e.g. ``scene.arrays.mat_diffuse.grad`` (call :func:`enable_material_gradients` first).

    Single-threaded (the tape is global in Warp 1.19). ``max_depth`` is unrolled, at most
    MAX_UNROLLED_DEPTH. Uses the same random streams as :func:`warp_spt.render` for samples 0..spp-1.
    """
    if not 1 <= max_depth <= MAX_UNROLLED_DEPTH:
        raise ValueError(f"max_depth must be in [1, {MAX_UNROLLED_DEPTH}] for differentiable renders")
    if width < 1 or height < 1 or spp < 1:
        raise ValueError("width, height and spp must be positive")
    key = (scene.features, max_depth)
    if key not in _kernels:
        _kernels[key] = _make_kernel(scene.features, max_depth)
    kernel = _kernels[key]
    sky = sky or Sky.black()
    image = wp.zeros(width * height, dtype=wp.vec3, device=scene.device, requires_grad=True)
    tape = wp.Tape()
    with tape:
        wp.launch(kernel, dim=width * height, device=scene.device, inputs=[
            scene.arrays, camera_params(camera or Camera(), width, height), width, spp, int(sky.kind),
            wp.vec3(*sky.color), wp.uint32(seed & 0xFFFFFFFF), int(texture_filter == "bilinear"), image])
    return DiffRender(image, tape, width, height)
