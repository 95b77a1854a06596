"""The path-tracing kernel: camera rays, closest hits, the seed's materials, accumulation.

``get_kernel(features)`` builds (once per feature set and process; Warp's disk cache keeps the
compiled code across processes) a forward-only kernel with everything the scene does not use
compiled out. Each thread renders one pixel: ``sample_count`` samples from global sample index
``sample_start`` on, summed in float64 and added to the film, so a large sample count never drifts.
"""

from __future__ import annotations

import threading

import numpy as np
import warp as wp

from .camera import Camera
from .device_scene import Features, SceneArrays
from .geometry import KIND_MISS, NO_HIT, make_closest_hit
from .sampling import concentric_disk, stream_state
from .shading import make_shading, offset_origin, sky_radiance


@wp.struct
class CameraParams:
    """The image plane of camera.Camera.frame(), in float32.

    Primary rays use ``to_upper_left`` (the corner relative to the origin, subtracted in float64):
    with the absolute corner, a camera at 1e5 rounded every target point to 1/128 unit before the
    origin was subtracted, which bent primary rays by up to a few percent
    (tests/test_stability.py, shifted Cornell box).
    """

    origin: wp.vec3
    to_upper_left: wp.vec3     # upper_left - origin
    x_step: wp.vec3
    y_step: wp.vec3
    right: wp.vec3
    up: wp.vec3
    lens_radius: float


def camera_params(camera: Camera, width: int, height: int) -> CameraParams:
    """Pack a Camera's frame for the kernel."""
    f = dict(camera.frame(width, height))
    f["to_upper_left"] = f["upper_left"] - f["origin"]     # in float64, before rounding to float32
    c = CameraParams()
    for name in ("origin", "to_upper_left", "x_step", "y_step", "right", "up"):
        setattr(c, name, wp.vec3(*np.asarray(f[name], dtype=np.float32).tolist()))
    c.lens_radius = float(f["lens_radius"])
    return c


@wp.func
def camera_ray(cam: CameraParams, x: float, y: float, r1: float, r2: float, r3: float, r4: float):
    """The primary ray through pixel (x, y) at offset (r1, r2) in the pixel, lens sample (r3, r4).

    The image plane is the focal plane, so every lens point sees the same target: a thin lens.
    """
    target = cam.to_upper_left + cam.x_step * (x + r1) - cam.y_step * (y + r2)   # relative to origin
    lens = wp.vec3(0.0, 0.0, 0.0)
    if cam.lens_radius > 0.0:
        k = concentric_disk(r3, r4)
        lens = (cam.right * k[0] + cam.up * k[1]) * cam.lens_radius
    return cam.origin + lens, wp.normalize(target - lens)


def _make_kernel(features: Features):
    closest_hit = make_closest_hit(features)
    surface_at, emission, sample_scatter = make_shading(features)

    @wp.func
    def radiance(s: SceneArrays, o_in: wp.vec3, d_in: wp.vec3, max_depth: int, sky_kind: int,
                 sky_color: wp.vec3, bilinear: int, state_in: wp.uint32):
        state = state_in
        o = o_in
        d = d_in
        throughput = wp.vec3(1.0, 1.0, 1.0)
        total = wp.vec3(0.0, 0.0, 0.0)
        depth = int(0)
        rays = int(0)
        while depth < max_depth:   # max_depth counts hits, as in the seed
            h = closest_hit(s, o, d, NO_HIT)
            rays += 1
            if h.kind == KIND_MISS:
                total += wp.cw_mul(throughput, sky_radiance(sky_kind, sky_color, d))
                break
            depth += 1
            sf = surface_at(s, h, o, d)
            if wp.static(features.emitters):
                total += wp.cw_mul(throughput, emission(s, sf, bilinear))
            if depth >= max_depth:
                break
            sc, state = sample_scatter(s, sf, d, bilinear, state)
            if sc.alive == 0:
                break
            throughput = wp.cw_mul(throughput, sc.weight)
            if wp.max(wp.max(throughput[0], throughput[1]), throughput[2]) <= 0.0:
                break
            o = offset_origin(sf.p, sf.ng, sc.through, s.extent)
            d = sc.dir
        return total, rays

    @wp.kernel(enable_backward=False, module="unique")
    def trace(s: SceneArrays, cam: CameraParams, width: int, pixel_start: int, sample_start: int,
              sample_count: int, max_depth: int, sky_kind: int, sky_color: wp.vec3, seed: wp.uint32,
              bilinear: int, film: wp.array(dtype=wp.vec3d), counters: wp.array2d(dtype=wp.int64)):
        pix = pixel_start + wp.tid()
        x = float(pix % width)
        y = float(pix // width)
        acc = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0))
        bad = int(0)
        rays = int(0)
        for j in range(sample_count):
            state = stream_state(seed, pix, sample_start + j)
            r1 = wp.randf(state)
            r2 = wp.randf(state)
            r3 = wp.randf(state)
            r4 = wp.randf(state)
            o, d = camera_ray(cam, x, y, r1, r2, r3, r4)
            L, n = radiance(s, o, d, max_depth, sky_kind, sky_color, bilinear, state)
            rays += n
            if wp.isfinite(L):
                acc += wp.vec3d(wp.float64(L[0]), wp.float64(L[1]), wp.float64(L[2]))
            else:
                bad += 1           # counted and reported by render(); tests require zero
        film[pix] = film[pix] + acc
        counters[pix, 0] = counters[pix, 0] + wp.int64(rays)
        counters[pix, 1] = counters[pix, 1] + wp.int64(bad)

    return trace


_kernels: dict[Features, wp.Kernel] = {}
_lock = threading.Lock()


def get_kernel(features: Features, device: str = "cpu") -> wp.Kernel:
    """The specialised kernel for ``features``, compiled and loaded on ``device`` (main thread only)."""
    with _lock:
        k = _kernels.get(features)
        if k is None:
            k = _kernels[features] = _make_kernel(features)
    wp.load_module(k.module, device=device)
    return k
