"""Albedo and normal feature images for the denoiser, from the first non-specular hit.

Open Image Denoise keeps edges and textures much better when it also sees, per pixel, the surface
colour and normal of what the pixel shows. Through mirrors and glass that is the first surface with
a lobe with a density (the material contract's ``lobes & LOBE_SMOOTH``: for the seed's model a
diffuse lobe, Roughness > 0), seen through the specular bounces, whose colours tint the albedo; its
colour is the kind's ``albedo``.
Rays that leave the scene give albedo 1 (OIDN's convention for a background) and normal 0.

One small kernel of its own per feature set (the "aov" kind of ``rendering.setup.KERNEL_KINDS``),
built from the integrators' pieces (camera ray, closest hit, surface, material sampling, the
sampler interface), averaged over a few jittered samples per pixel so that edges are anti-aliased
like the image; OIDN prefilters them, so they may be a little noisy.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import warp as wp

from warp_spt.device.camera_rays import CameraParams, camera_ray
from warp_spt.upload.device_scene import DeviceScene
from warp_spt.device.structs import Features, Geometry, Materials, Textures
from warp_spt.bsdfs.cutout import make_hit
from warp_spt.accel.ray_queries import KIND_MISS
from warp_spt.device.lobes import LOBE_SMOOTH
from warp_spt.bsdfs import make_materials
from warp_spt.accel.surface import make_surface, offset_origin
from warp_spt.integrators.common import DIM_BOUNCE, DIM_LENS, DIM_PIXEL, RenderParams
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.setup import Bound, KernelKind, bind, register_kind
from warp_spt.runtime import kernel_cache
from warp_spt.samplers import Sampler, get_sampler
from warp_spt.scene.camera import Camera

MAX_SPECULAR = 8          # specular bounces followed before giving up (then: the last surface)
# Sample dimensions per specular bounce, from DIM_BOUNCE: direction (2 dims), then the Fresnel
# choice (no lobe is drawn: the specular lobe is taken, u_lobe = 1).
AOV_STRIDE = 3
AOV_OFF_DIR = 0
AOV_OFF_FRESNEL = 2
# The pass keeps the independent sampler whatever the image's: with it, dimensions drawn in order are
# the PCG draws the pass made before it used the sampler interface, so its images did not change.
AOV_SAMPLER = "independent"


def _make_kernel(features: Features, sampler: Sampler):
    hit = make_hit(features)
    surface_at = make_surface(features)
    mats = make_materials(features)

    @wp.kernel(enable_backward=False, module="unique")
    def aux(g: Geometry, m: Materials, t: Textures, cam: CameraParams, rp: RenderParams,
            albedo: wp.array(dtype=wp.vec3), normal: wp.array(dtype=wp.vec3)):
        pix = rp.pixel_start + wp.tid()
        a_sum = wp.vec3(0.0, 0.0, 0.0)
        n_sum = wp.vec3(0.0, 0.0, 0.0)
        for j in range(rp.sample_count):
            st = sampler.start(rp.seed, pix, rp.sample_start + j)
            r12, st = sampler.next_2d(st, DIM_PIXEL)
            r34, st = sampler.next_2d(st, DIM_LENS)
            o, d = camera_ray(cam, float(pix % rp.width), float(pix // rp.width), r12[0], r12[1], r34[0], r34[1])
            tint = wp.vec3(1.0, 1.0, 1.0)
            a = tint
            n = wp.vec3(0.0, 0.0, 0.0)
            for bounce in range(MAX_SPECULAR):
                h = hit(g, m, t, o, d)
                if h.kind == KIND_MISS:
                    a = tint
                    break
                sf = mats.shade(m, t, surface_at(g, h, o, d))
                a = wp.cw_mul(tint, mats.albedo(m, t, sf))
                n = sf.ns
                if (mats.lobes(m, t, sf) & LOBE_SMOOTH) != 0:
                    break                  # the first surface with a lobe that has a density (diffuse)
                base = DIM_BOUNCE + AOV_STRIDE * bounce
                u_dir, st = sampler.next_2d(st, base + AOV_OFF_DIR)
                u_fresnel, st = sampler.next_1d(st, base + AOV_OFF_FRESNEL)
                bs = mats.sample(m, t, sf, 1.0, u_dir, u_fresnel)     # u_lobe = 1: the last (specular) lobe
                if bs.alive == 0:
                    break
                tint = wp.cw_mul(tint, bs.weight)
                o = offset_origin(sf.p, sf.ng, bs.through, g.extent)
                d = bs.dir
            a_sum += wp.vec3(wp.clamp(a[0], 0.0, 1.0), wp.clamp(a[1], 0.0, 1.0), wp.clamp(a[2], 0.0, 1.0))
            n_sum += n
        albedo[pix] = a_sum / float(rp.sample_count)
        nl = wp.length(n_sum)
        normal[pix] = wp.where(nl > 0.0, n_sum / nl, wp.vec3(0.0, 0.0, 0.0))

    return aux


def get_aov_kernel(features: Features, sampler: str = AOV_SAMPLER, device: str = "cpu") -> wp.Kernel:
    """The albedo/normal kernel for these features and sampler, compiled and loaded on ``device``."""
    k = kernel_cache.cached("aov", (features, sampler), lambda: _make_kernel(features, get_sampler(sampler)))
    return kernel_cache.load(k, device)


def aov_inputs(b: Bound, rp: RenderParams, albedo: wp.array, normal: wp.array) -> list:
    """The albedo/normal kernel's inputs, in its order (it reads no light table)."""
    return [b.dev.geometry, b.dev.materials, b.tex, b.cam, rp, albedo, normal]


register_kind(KernelKind(
    "aov", lambda b: get_aov_kernel(b.features, b.settings.sampler, b.dev.device),
    lambda scene_features, rs, sky: replace(rs.features.covering(scene_features) if rs.features else scene_features,
                                            lights=()),   # it reads no light table
    lights=False))


def feature_buffers(scene: DeviceScene, camera: Camera | None, width: int, height: int, *, spp: int = 4,
                    seed: int = 0, texture_filter: str = "nearest", features: Features | None = None,
                    sampler: str = AOV_SAMPLER) -> tuple[np.ndarray, np.ndarray]:
    """(albedo, normal), float32 (height, width, 3): albedo in [0, 1], unit world-space normals (0 for sky).

    ``spp`` jittered camera samples per pixel are averaged; ``features`` overrides the scene's own.
    """
    if not isinstance(spp, (int, np.integer)) or spp < 1:
        raise ValueError(f"spp must be a positive integer, got {spp!r}")
    rs = RenderSettings(width=width, height=height, spp=spp, seed=seed, texture_filter=texture_filter,
                        features=features, sampler=sampler, device=scene.device)
    b = bind(scene, camera, rs, mode="aov")
    albedo = wp.zeros(b.pixels, dtype=wp.vec3, device=scene.device)
    normal = wp.zeros(b.pixels, dtype=wp.vec3, device=scene.device)
    wp.launch(b.kernel, dim=b.pixels, device=scene.device, inputs=aov_inputs(b, b.params(), albedo, normal))
    return albedo.numpy().reshape(height, width, 3), normal.numpy().reshape(height, width, 3)
