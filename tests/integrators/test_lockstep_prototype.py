"""The lockstep prototype (benchmarks/lockstep_prototype.py, issue 45; not part of the package) renders
the same film as today's fast kernel: the same random numbers per (pixel, sample, dimension), the
same vertex functions, the lanes' radiance summed in sample order. Checked bit for bit on the tests'
Cornell box (glossy and glass balls: the lobe and Fresnel requests in the batch, specular vertices
without light samples), a gradient sky (escaped paths' MIS), roulette on, and a sample count that
is not a multiple of the lanes (masked lanes)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
import warp as wp

BENCH = Path(__file__).resolve().parents[2] / "benchmarks"


@pytest.mark.slow
def test_lockstep_film_is_todays(tmp_path):
    sys.path.insert(0, str(BENCH))
    try:
        from lockstep_prototype import make_lockstep_kernel
    finally:
        sys.path.remove(str(BENCH))
    from tests.support.stability_scenes import cornell_camera, cornell_files
    from warp_spt.emitters import declare_sky, light_table
    from warp_spt.integrators import RenderParams, camera_params, nee
    from warp_spt.integrators.common import make_kernel, make_start_path
    from warp_spt.io.loader import load_scene
    from warp_spt.samplers import get_sampler
    from warp_spt.scene.sky import Sky
    from warp_spt.upload.device_scene import DeviceScene

    dev = DeviceScene(load_scene(*cornell_files(tmp_path), warn=lambda message: None))
    sky = Sky.gradient()
    feats = dev.features.with_lights(declare_sky(sky))
    sampler = get_sampler("sobol-affine")
    size, spp = 12, 3
    n = size * size
    rp = RenderParams()
    rp.width, rp.pixel_start, rp.sample_start, rp.sample_count = size, 0, 5, spp
    rp.max_depth, rp.roulette_depth, rp.seed = 6, 2, wp.uint32(3)
    inputs = [dev.geometry, dev.materials, dev.textures(), light_table(dev, sky),
              camera_params(cornell_camera(), size, size), rp]
    films = []
    for kernel in (make_kernel(nee.make_path_step(feats, sampler, light_sampling=True), make_start_path(sampler)),
                   make_lockstep_kernel(feats, sampler, lanes=2)):
        film, counters = wp.zeros(n, dtype=wp.vec3d), wp.zeros((n, 2), dtype=wp.int64)
        wp.launch(kernel, dim=n, inputs=[*inputs, film, counters, None])
        films.append((film.numpy(), counters.numpy()))
    (today, today_counts), (lockstep, lockstep_counts) = films
    assert today.mean() > 0.0
    np.testing.assert_array_equal(lockstep, today)
    np.testing.assert_array_equal(lockstep_counts, today_counts)
