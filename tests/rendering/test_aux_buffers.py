"""Albedo and normal feature images for the denoiser (warp_spt.rendering.aux_buffers), checked against the
materials written in the scene: what a pixel shows, directly or through a mirror, has a known colour."""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.rendering.aux_buffers import feature_buffers
from warp_spt.scene.camera import Camera

from tests.support.scenes import material
from tests.support.stability_scenes import GENERAL, quads_obj, scene_from_text

FLOOR, BALL, MIRROR = (0.6, 0.6, 0.6), (0.8, 0.3, 0.2), (0.9, 0.5, 0.9)


@pytest.fixture(scope="module")
def buffers(tmp_path_factory):
    obj = quads_obj([("floor", [(-6, -6, 0), (6, -6, 0), (6, 6, 0), (-6, 6, 0)])],
                    spheres=[("ball", (-1.3, 0.0, 1.0), 1.0), ("mirror", (1.3, 0.0, 1.0), 1.0)])
    mtl = (material("floor", Kd=FLOOR, Roughness=1) + material("ball", Kd=BALL, Roughness=1)
           + material("mirror", Kd=MIRROR, Roughness=0, Fuzz=0))
    dev = scene_from_text(tmp_path_factory.mktemp("aux"), "aux", obj, mtl)
    cam = Camera(position=(0.0, -9.0, 4.0), direction=(0.0, 1.0, -0.35), fov=45.0, aperture=0.0, focus=9.0)
    return feature_buffers(dev, cam, 40, 30, spp=4, features=GENERAL)


def test_albedo_is_the_colour_of_the_first_non_specular_surface(buffers):
    albedo, _ = buffers
    flat = albedo.reshape(-1, 3).astype(np.float64)
    m, f, b = np.array(MIRROR), np.array(FLOOR), np.array(BALL)
    # direct: floor, ball, sky (1); through the mirror: its reflect colour (Kd, the seed's model) times those
    expected = {"floor": f, "ball": b, "sky": np.ones(3), "mirror-floor": m * f, "mirror-ball": m * b,
                "mirror-sky": m}
    dist = np.stack([np.abs(flat - v).max(axis=1) for v in expected.values()])
    pure = dist.min(axis=0) < 1e-5                    # every sample of the pixel saw the same thing
    counts = dict(zip(expected, np.bincount(dist.argmin(axis=0)[pure], minlength=len(expected))))
    assert pure.mean() > 0.75, pure.mean()            # the rest are edges, averaged over 4 samples
    assert all(counts[k] > 0 for k in ("floor", "ball", "sky", "mirror-floor", "mirror-sky")), counts
    assert np.all((albedo >= 0) & (albedo <= 1))


def test_normals_are_unit_or_zero_and_the_floor_faces_up(buffers):
    albedo, normal = buffers
    length = np.linalg.norm(normal, axis=2)
    assert np.all((np.abs(length - 1) < 1e-4) | (length == 0))
    floor = np.abs(albedo - np.array(FLOOR, np.float32)).max(axis=2) < 1e-5
    assert floor.sum() > 50
    np.testing.assert_allclose(normal[floor], np.tile([0.0, 0.0, 1.0], (floor.sum(), 1)), atol=1e-5)
    sky = np.abs(albedo - 1).max(axis=2) < 1e-6
    assert sky.any() and np.all(length[sky] == 0)


def test_bad_spp_is_rejected(buffers, tmp_path):
    from warp_spt.upload.device_scene import DeviceScene  # noqa: F401

    with pytest.raises(ValueError):
        feature_buffers(None, None, 4, 4, spp=0)
