"""The white triangle in the viewer's top-left corner (issue 43, item 8): the studio's key-light
sphere showed in the frame where a 4:3 view moved the camera back from a tall model (the bust). The
key is now moved out of the frame along its line from the model, its radius scaled with it (the same
solid angle from the model's centre); a key that was out of the frame stays where it was.

Checked by a camera ray through every pixel of the frame, intersected with the sphere analytically,
not by the frustum test the placement uses."""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.io.loader import load_scene
from warp_spt.rendering.first_view import first_view
from warp_spt.scene.studio import key_sphere

from tests.support.models import write_model


def pixels_that_see(sphere: np.ndarray, camera, width: int, height: int) -> int:
    """How many pixel-centre rays (and rays through the frame's four corners) hit ``sphere``."""
    d, right, top = camera.axes()
    tx = np.tan(np.radians(camera.fov) / 2)
    ty = tx * height / width
    xs = np.concatenate([(2 * (np.arange(width) + 0.5) / width - 1), [-1.0, 1.0]])
    ys = np.concatenate([(1 - 2 * (np.arange(height) + 0.5) / height), [-1.0, 1.0]])
    X, Y = np.meshgrid(xs, ys)
    rays = d + X[..., None] * tx * right + Y[..., None] * ty * top
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    oc = np.asarray(camera.position, np.float64) - sphere[:3]
    b = rays @ oc
    disc = b * b - (oc @ oc - float(sphere[3]) ** 2)
    hit = (disc >= 0) & (-b + np.sqrt(np.maximum(disc, 0)) > 0)
    return int(hit.sum())


@pytest.fixture(scope="module")
def bust(tmp_path_factory):
    return load_scene([str(write_model(tmp_path_factory.mktemp("bust") / "bust.obj", shape="bust"))])


@pytest.mark.parametrize("size", [(384, 288), (512, 512), (640, 360)])
def test_the_key_light_is_out_of_the_first_views_frame(bust, size):
    fv = first_view(bust, None, width=size[0], height=size[1])
    assert fv.studio
    key = np.asarray(fv.scene.spheres[-1], np.float64)
    assert pixels_that_see(key, fv.camera, *size) == 0


def test_it_was_in_the_frame_before_and_moves_out_lighting_the_model_the_same(bust):
    fv = first_view(bust, None, width=384, height=288)
    bounds = fv.subject.bounds
    centre = bounds.mean(axis=0)
    placed = key_sphere(bounds, fv.up.axis, fv.camera).astype(np.float64)               # the frame not known
    moved = key_sphere(bounds, fv.up.axis, fv.camera, 384 / 288).astype(np.float64)     # as the viewer calls it
    assert pixels_that_see(placed, fv.camera, 384, 288) > 0                             # the white triangle
    assert pixels_that_see(moved, fv.camera, 384, 288) == 0
    # on the line from the model's centre, the same angular size seen from it
    a, b = placed[:3] - centre, moved[:3] - centre
    assert np.linalg.norm(np.cross(a, b)) <= 1e-5 * np.linalg.norm(a) * np.linalg.norm(b)
    assert moved[3] / np.linalg.norm(b) == pytest.approx(placed[3] / np.linalg.norm(a), rel=1e-5)
    assert np.linalg.norm(b) > np.linalg.norm(a)


def test_a_key_already_out_of_the_frame_stays_where_it_was(bust):
    fv = first_view(bust, None, width=512, height=512)
    bounds = fv.subject.bounds
    assert np.array_equal(key_sphere(bounds, fv.up.axis, fv.camera, 1.0), key_sphere(bounds, fv.up.axis, fv.camera))
