"""Albedo and normal feature images for the denoiser, from the first non-specular hit.

Open Image Denoise keeps edges and textures much better when it also sees, per pixel, the surface
colour and normal of what the pixel shows. Through mirrors and glass that is the first surface with
a lobe with a density (the material kind's ``has_density``: a diffuse lobe, Roughness > 0, for the
seed's model), seen through the specular bounces, whose colours tint the albedo.
Rays that leave the scene give albedo 1 (OIDN's convention for a background) and normal 0.

One small kernel of its own per feature set, built from the integrators' pieces (camera ray,
closest hit, surface, material sampling), averaged over a few jittered samples per pixel so that
edges are anti-aliased like the image; OIDN prefilters them, so they may be a little noisy.
"""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import warp as wp

from warp_spt.core.device_scene import (
    DeviceScene,
    Features,
    Geometry,
    Materials,
    Textures,
)
from warp_spt.core.geometry import KIND_MISS, NO_HIT, make_closest_hit
from warp_spt.core.materials import make_materials
from warp_spt.core.sampling import stream_state
from warp_spt.core.surface import make_surface, offset_origin
from warp_spt.integrators import camera_params
from warp_spt.integrators.common import CameraParams, camera_ray
from warp_spt.scene.camera import Camera

MAX_SPECULAR = 8          # specular bounces followed before giving up (then: the last surface)

_kernels: dict[Features, wp.Kernel] = {}
_lock = threading.Lock()


def _make_kernel(features: Features):
    closest_hit = make_closest_hit(features)
    surface_at = make_surface(features)
    mats = make_materials(features)

    @wp.kernel(enable_backward=False, module="unique")
    def aux(g: Geometry, m: Materials, t: Textures, cam: CameraParams, width: int, spp: int, seed: wp.uint32,
            albedo: wp.array(dtype=wp.vec3), normal: wp.array(dtype=wp.vec3)):
        pix = wp.tid()
        a_sum = wp.vec3(0.0, 0.0, 0.0)
        n_sum = wp.vec3(0.0, 0.0, 0.0)
        for j in range(spp):
            state = stream_state(seed, pix, j)
            r1 = wp.randf(state)
            r2 = wp.randf(state)
            r3 = wp.randf(state)
            r4 = wp.randf(state)
            o, d = camera_ray(cam, float(pix % width), float(pix // width), r1, r2, r3, r4)
            tint = wp.vec3(1.0, 1.0, 1.0)
            a = tint
            n = wp.vec3(0.0, 0.0, 0.0)
            for bounce in range(MAX_SPECULAR):
                h = closest_hit(g, o, d, NO_HIT)
                if h.kind == KIND_MISS:
                    a = tint
                    break
                sf = surface_at(g, h, o, d)
                a = wp.cw_mul(tint, mats.color(t, m.tex[sf.mat][0], m.diffuse[sf.mat], sf))
                n = sf.ns
                if mats.has_density(m, sf):
                    break                  # the first surface with a lobe that has a density (diffuse)
                u_dir = wp.vec2(wp.randf(state), wp.randf(state))
                bs = mats.sample(m, t, sf, d, 1.0, u_dir, wp.randf(state))     # u_lobe = 1: the specular lobe
                if bs.alive == 0:
                    break
                tint = wp.cw_mul(tint, bs.weight)
                o = offset_origin(sf.p, sf.ng, bs.through, g.extent)
                d = bs.dir
            a_sum += wp.vec3(wp.clamp(a[0], 0.0, 1.0), wp.clamp(a[1], 0.0, 1.0), wp.clamp(a[2], 0.0, 1.0))
            n_sum += n
        albedo[pix] = a_sum / float(spp)
        nl = wp.length(n_sum)
        normal[pix] = wp.where(nl > 0.0, n_sum / nl, wp.vec3(0.0, 0.0, 0.0))

    return aux


def feature_buffers(scene: DeviceScene, camera: Camera | None, width: int, height: int, *, spp: int = 4,
                    seed: int = 0, texture_filter: str = "nearest",
                    features: Features | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(albedo, normal), float32 (height, width, 3): albedo in [0, 1], unit world-space normals (0 for sky).

    ``spp`` jittered camera samples per pixel are averaged; ``features`` overrides the scene's own.
    """
    if not isinstance(spp, (int, np.integer)) or spp < 1:
        raise ValueError(f"spp must be a positive integer, got {spp!r}")
    feats = replace(features or scene.features, sky=False)       # the sky's light is irrelevant here
    with _lock:
        k = _kernels.get(feats)
        if k is None:
            k = _kernels[feats] = _make_kernel(feats)
    n = width * height
    albedo = wp.zeros(n, dtype=wp.vec3, device=scene.device)
    normal = wp.zeros(n, dtype=wp.vec3, device=scene.device)
    wp.launch(k, dim=n, device=scene.device, inputs=[
        scene.geometry, scene.materials, scene.textures(texture_filter), camera_params(camera or Camera(), width, height),
        width, spp, wp.uint32(seed & 0xFFFFFFFF), albedo, normal])
    return albedo.numpy().reshape(height, width, 3), normal.numpy().reshape(height, width, 3)
