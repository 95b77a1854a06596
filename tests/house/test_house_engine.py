"""The engine's plumbing after issue 20 ("the house"): one set-up, registries of records, one kernel
cache, no Warp initialised at import time, one camera frame."""

from __future__ import annotations

import subprocess
import sys
from dataclasses import replace

import numpy as np
import pytest

import warp_spt
from warp_spt.upload.device_scene import DeviceScene
from warp_spt.io.loader import load_scene
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

from tests.support.scenes import box_obj, material, write_scene_files

CAM = Camera(position=(0.1, -0.3, 0.2), direction=(0.3, 1.0, 0.1), fov=100.0, aperture=0.0, focus=1.0)
KW = dict(width=8, height=6, spp=2, max_depth=3, seed=4, sampler="independent", threads=1,
          sky=Sky.constant(0.5, 0.5, 0.5))


@pytest.fixture(scope="module")
def box(scene_dir):
    mtl = material("wall", Kd=(0.5, 0.7, 0.9), Kl=(0.2, 0.1, 0.3), Roughness=0.6)
    objs, mtls = write_scene_files(scene_dir, "engine_box", box_obj(), mtl)
    return DeviceScene(load_scene(objs, mtls))


def test_the_public_registries_keep_their_names():
    assert sorted(warp_spt.INTEGRATORS) == ["ears", "guided", "nee", "seed", "volpath"]
    assert sorted(warp_spt.SAMPLERS) == ["independent", "sobol", "sobol-affine"]
    assert warp_spt.INTEGRATORS["seed"].replayable and warp_spt.INTEGRATORS["nee"].stride == 8


def test_a_dummy_integrator_is_one_record_and_one_line(box, monkeypatch):
    from warp_spt.integrators import INTEGRATORS
    from warp_spt.rendering.setup import Bound

    seen = {}

    def prepare(bound):
        seen["prepare"] = bound
        return "own data"

    def passes(bound, result):
        seen["passes"] = bound.data
        return result

    dummy = replace(INTEGRATORS["seed"], name="dummy", prepare=prepare, passes=passes)
    monkeypatch.setitem(INTEGRATORS, "dummy", dummy)          # the one line a plugin needs
    img = warp_spt.render(box, CAM, integrator="dummy", **KW)
    assert isinstance(seen["prepare"], Bound) and seen["passes"] == "own data"
    np.testing.assert_array_equal(img, warp_spt.render(box, CAM, integrator="seed", **KW))


def test_unknown_names_are_refused_before_anything_is_built(box):
    with pytest.raises(ValueError, match="unknown integrator"):
        warp_spt.render(box, CAM, integrator="nope", **KW)
    with pytest.raises(ValueError, match="unknown sampler"):
        warp_spt.render(box, CAM, **{**KW, "sampler": "nope"})


def test_every_kernel_kind_is_built_once_in_the_one_cache(box):
    from warp_spt.diff.gradients import render_gradients
    from warp_spt.diff.params import parameters
    from warp_spt.integrators import get_kernel
    from warp_spt.rendering.aux_buffers import feature_buffers
    from warp_spt.rendering.settings import RenderSettings
    from warp_spt.rendering.setup import KERNEL_KINDS, bind
    from warp_spt.runtime import kernel_cache

    warp_spt.render(box, CAM, **KW)
    feature_buffers(box, CAM, 8, 6, spp=1)
    p = parameters(box, CAM, KW["sky"])
    rs = RenderSettings(**{k: v for k, v in KW.items() if k != "sky"})
    render_gradients(p, rs, adjoint=np.ones((6, 8, 3), np.float32), wrt=["sky.color"], mode="prb")
    # the tape unrolled once (its kernel's compile grows with the depth; the cache's rule does not)
    render_gradients(p, replace(rs, max_depth=1), adjoint=np.ones((6, 8, 3), np.float32), wrt=["sky.color"],
                     mode="tape")
    assert set(KERNEL_KINDS) == {"fast", "aov", "replay", "replay_pathwise", "tape", "boundary"}
    kinds = {k[0] for k in kernel_cache.entries()}
    assert {"fast", "aov", "replay", "tape", "step", "vertex", "sampler"} <= kinds
    n = len(kernel_cache.entries())
    b = bind(box, CAM, rs)
    assert b.kernel is get_kernel(b.features, box.device, rs.integrator, rs.sampler)
    assert len(kernel_cache.entries()) == n          # nothing built twice


def test_the_cache_serves_a_plain_builder_too():
    from warp_spt.runtime import kernel_cache

    calls = []

    @kernel_cache.memoize("test-builder")
    def build(x, scale=1):
        calls.append(x)
        return [x * scale]

    assert build(2, scale=3) is build(2, scale=3) and calls == [2]
    assert ("test-builder", ((2,), (("scale", 3),))) in kernel_cache.entries("test-builder")


def test_importing_the_engine_does_not_initialise_warp():
    code = ("import warp_spt.device.textures, warp_spt.rendering.tiles, warp_spt.diff.gradients\n"
            "import warp._src.context as c\n"
            "assert c.runtime is None, 'Warp was initialised at import time'\n")
    subprocess.run([sys.executable, "-c", code], check=True)


def test_one_camera_frame_feeds_the_kernel_and_the_jacobian():
    from warp_spt.device.camera_rays import (
        CAMERA_FIELDS,
        camera_frame,
        camera_params,
        pinhole_directions,
    )
    from warp_spt.diff.params import camera_frame as frame_rows

    cam = Camera(position=(1e5, 2.0, 3.0), direction=(0.2, 1.0, -0.1), fov=50.0, aperture=0.1, focus=5.0)
    f = camera_frame(cam, 16, 9)
    packed = camera_params(cam, 16, 9)
    for name in CAMERA_FIELDS:
        np.testing.assert_array_equal(np.array(getattr(packed, name)), f[name].astype(np.float32))
    np.testing.assert_array_equal(frame_rows(cam, 16, 9), np.stack([f[k] for k in CAMERA_FIELDS]))
    origin, dirs = pinhole_directions(cam, 16, 9)
    plane = cam.image_plane(16, 9)
    centre = plane["upper_left"] + 8.5 * plane["x_step"] - 4.5 * plane["y_step"] - origin
    np.testing.assert_allclose(dirs[4, 8], centre / np.linalg.norm(centre), atol=1e-9)


def test_device_scene_hands_out_its_caches_through_methods(box):
    from warp_spt.emitters import light_table

    a = light_table(box, Sky.black())
    assert light_table(box, Sky.black()) is a
    box.invalidate_lights()
    assert light_table(box, Sky.black()) is not a
    texels, tiles = box.atlas_arrays()
    np.testing.assert_array_equal(box.atlas_tiles(), tiles.numpy())


def test_capabilities_of_the_record_are_enforced(box, monkeypatch):
    from warp_spt.diff.gradients import render_gradients
    from warp_spt.diff.params import parameters
    from warp_spt.integrators import INTEGRATORS
    from warp_spt.rendering.settings import RenderSettings

    monkeypatch.setitem(INTEGRATORS, "no-tape", replace(INTEGRATORS["seed"], name="no-tape", tape=False,
                                                        make_vertex=None))
    p = parameters(box, CAM, KW["sky"])
    rs = RenderSettings(width=8, height=6, spp=1, max_depth=2, integrator="no-tape")
    adj = np.ones((6, 8, 3), np.float32)
    with pytest.raises(ValueError, match="not differentiable through the tape"):
        render_gradients(p, rs, adjoint=adj, wrt=["sky.color"], mode="tape")
    with pytest.raises(ValueError, match="path replay cannot"):
        render_gradients(p, rs, adjoint=adj, wrt=["sky.color"], mode="prb")


def test_an_unregistered_kernel_kind_is_named(box):
    from warp_spt.rendering.setup import bind

    with pytest.raises(ValueError, match="unknown kernel kind 'nope'"):
        bind(box, CAM, mode="nope")


def test_a_render_imports_only_the_integrator_it_uses():
    # start-up time (docs/performance.md, Start-up): the registry imports a module on first look-up
    code = ("import sys, warp_spt.rendering.setup, warp_spt.io.loader\n"
            "from warp_spt.integrators import INTEGRATORS, get_integrator\n"
            "lazy = ['warp_spt.integrators.ears', 'warp_spt.integrators.guided', 'warp_spt.integrators.volpath', 'PIL']\n"
            "assert sorted(INTEGRATORS) == ['ears', 'guided', 'nee', 'seed', 'volpath'] and 'ears' in INTEGRATORS\n"
            "assert not [m for m in lazy if m in sys.modules], [m for m in lazy if m in sys.modules]\n"
            "assert get_integrator('ears').name == 'ears' and 'warp_spt.integrators.ears' in sys.modules\n")
    subprocess.run([sys.executable, "-c", code], check=True)
