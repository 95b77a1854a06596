"""Far from the origin (issue 10): a recentred scene renders statistically like the same scene at the origin.

The stability suite's closed room scaled to 1 unit (its light hangs 1/128 below the ceiling, its
balls have radii 0.11 and 0.125) and moved 1e5 from the origin: there the engine's epsilon is
5e-7 * 1e5 = 0.05, far coarser than those features, yet every coordinate is exact in float32 (its
spacing at 1e5 is 1/128). Recentred, the room renders like the same room at the origin.
"""

from __future__ import annotations

import numpy as np

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.io.loader import load_scene
from warp_spt.rendering.tiles import render
from warp_spt.scene.recentre import recentre

from tests.support.stability_scenes import (
    assert_same_image,
    cornell_camera,
    cornell_files,
    render_batches,
    sky,
)

SCALE, SHIFT = 1.0 / 32.0, 1e5
BATCHES, BATCH_SPP, SIZE = 32, 16, 24
KW = dict(width=SIZE, height=SIZE, max_depth=6, sky=sky(50.0))


def recentred(folder, shift):
    scene = load_scene(*cornell_files(folder, SCALE, shift), warn=lambda m: None)
    local, cam, offset = recentre(scene, cornell_camera(SCALE, shift))
    return DeviceScene(local), cam, offset


def test_a_translated_room_renders_like_the_room_at_the_origin(scene_dir):
    dev0, cam0, off0 = recentred(scene_dir, 0.0)
    dev1, cam1, off1 = recentred(scene_dir, SHIFT)
    assert not off0.any(), "a scene at the origin is left alone (bit-identical renders)"
    assert np.allclose(off1, SHIFT + 0.5)
    # recentring is exact here: the shifted room's local coordinates are the unshifted room's, minus its centre
    p0 = dev0.scene.meshes[0].positions.astype(np.float64) - 0.5
    assert np.array_equal(dev1.scene.meshes[0].positions.astype(np.float64), p0)
    a = render_batches(dev0, cam0, BATCHES, BATCH_SPP, seed=1, **KW)
    b = render_batches(dev1, cam1, BATCHES, BATCH_SPP, seed=2, **KW)
    c = assert_same_image(a, b, f"1-unit room shifted {SHIFT:g}")
    print(f"worst block |t| {c.worst:.2f} / {c.bound:.2f}; whole image t {c.z_total:+.2f} / {c.bound_total:.2f}; "
          f"difference {c.rel_diff:.2%} +- {c.rel_se:.2%}")


def test_the_render_wrapper_recentres(scene_dir):
    scene = load_scene(*cornell_files(scene_dir, SCALE, SHIFT), warn=lambda m: None)
    dev, cam, _ = recentred(scene_dir, SHIFT)
    kw = dict(width=8, height=8, spp=2, max_depth=3, sky=sky(50.0))
    assert np.array_equal(render(scene, cornell_camera(SCALE, SHIFT), **kw), render(dev, cam, **kw))
