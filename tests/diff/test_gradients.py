"""Gradients of an image through wp.Tape against finite differences of the fast forward renderer."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import warp as wp

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.diff.gradients import enable_material_gradients, render_differentiable
from warp_spt.io.loader import load_scene
from warp_spt.rendering import tiles as R
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

from tests.support.scenes import box_obj, material, write_scene_files

CAM = Camera(position=(0.0, -2.5, 0.3), direction=(0.0, 1.0, -0.1), fov=70.0, aperture=0.0, focus=2.0)
SKY = Sky.constant(0.4, 0.5, 0.6)
# The seed integrator (NEE gradients are checked in test_param_gradients.py and test_param_gradients2.py)
KW = dict(width=10, height=8, spp=4, max_depth=3, seed=11, sky=SKY, integrator="seed")


@pytest.fixture(scope="module")
def room(scene_dir):
    """An open-fronted box (walls, glossy floor), a diffuse ball and a glowing ball under a sky."""
    mtl = (material("wall", Kd=(0.6, 0.5, 0.4), Roughness=0.8, Fuzz=0.3)
           + material("ball", Kd=(0.2, 0.7, 0.3), Roughness=1)
           + material("lamp", Kd=(1, 1, 1), Kl=(3.0, 2.5, 2.0), Roughness=1))
    box = box_obj((-1.5, -1.0, -1.0), (1.5, 2.0, 1.5), material="wall", subdivide=2)
    # drop the box's -Y face (the first two triangles of axis 1, side 0) so the sky gets in
    lines = box.splitlines()
    faces = [i for i, l in enumerate(lines) if l.startswith("f ")]
    per_face = len(faces) // 6
    open_front = [l for i, l in enumerate(lines) if i not in set(faces[2 * per_face:3 * per_face])]
    obj = "\n".join(open_front) + "\nusemtl ball\nb 0.4 0.8 -0.5 0.5\nusemtl lamp\nb -0.6 1.0 0.6 0.3\n"
    objs, mtls = write_scene_files(scene_dir, "room", obj, mtl)
    return load_scene(objs, mtls)


def _row(scene, name: str) -> int:
    return scene.materials.names.index(name)


def _forward_sum(scene, field: str, row: int, channel: int, delta: float) -> float:
    s = copy.deepcopy(scene)
    getattr(s.materials, field)[row, channel] += delta
    return float(R.render(DeviceScene(s), CAM, **KW).astype(np.float64).sum())


def test_differentiable_render_matches_the_fast_renderer(room):
    dev = DeviceScene(room)
    diff = render_differentiable(dev, CAM, **KW).numpy()
    fast = R.render(dev, CAM, **KW)
    # same random streams, same functions: the two kernels agree to float32 rounding
    assert np.allclose(diff, fast, rtol=1e-4, atol=1e-5)


@pytest.mark.parametrize("field,name", [("diffuse", "ball"), ("diffuse", "wall"), ("emission", "lamp"),
                                        ("reflect", "wall")])
def test_tape_gradient_matches_finite_differences(room, field, name):
    dev = DeviceScene(room)
    enable_material_gradients(dev)
    result = render_differentiable(dev, CAM, **KW)
    result.tape.backward(grads={result.image: wp.array(np.ones((KW["width"] * KW["height"], 3), np.float32),
                                                       dtype=wp.vec3)})
    grad = getattr(dev.materials, field).grad.numpy()
    row = _row(room, name)
    h = 1e-2
    for c in range(3):
        # With common random numbers the sampled paths do not depend on colours, so the image is a
        # low-degree polynomial in them and central differences are accurate to float rounding.
        fd = (_forward_sum(room, field, row, c, h) - _forward_sum(room, field, row, c, -h)) / (2 * h)
        assert abs(grad[row, c]) > 1e-3
        assert grad[row, c] == pytest.approx(fd, rel=2e-3, abs=1e-3)
