"""Engine correctness against independent, analytic expectations (small images, few samples)."""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.upload.device_scene import DeviceScene, Features
from warp_spt.io.loader import load_scene
from warp_spt.rendering import tiles as R
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

from tests.support.scenes import box_obj, material, quad_obj, write_scene_files

INSIDE = Camera(position=(0.1, -0.3, 0.2), direction=(0.3, 1.0, 0.1), fov=120.0, aperture=0.0, focus=1.0)


@pytest.fixture(scope="module")
def furnace(scene_dir):
    """A closed box, every wall diffuse albedo A with emission E (and a mirror-ish lobe of the same colour)."""
    mtl = material("wall", Kd=(0.5, 0.7, 0.9), Kl=(0.2, 0.1, 0.3), Roughness=0.6, Fuzz=0.0)
    objs, mtls = write_scene_files(scene_dir, "furnace", box_obj(subdivide=3), mtl)
    return DeviceScene(load_scene(objs, mtls))


@pytest.mark.parametrize("depth", [1, 2, 5, 40])
def test_furnace_box_matches_geometric_series(furnace, depth):
    # Every path in a closed box hits exactly `depth` walls; each hit adds E * A^k. With Fuzz 0 the
    # specular lobe is a perfect mirror of the same colour, so every sample of the seed's estimator is
    # the same number (NEE's furnace, a statistical check: tests/integrators/test_light_transport.py).
    a = np.array([0.5, 0.7, 0.9])
    e = np.array([0.2, 0.1, 0.3])
    expected = e * (1 - a**depth) / (1 - a)
    img = R.render(furnace, INSIDE, width=12, height=9, spp=4, max_depth=depth, integrator="seed",
                   sky=Sky.constant(100.0, 100.0, 100.0))   # any leak to the sky would show at once
    assert np.allclose(img, expected, rtol=2e-5, atol=0), (img.min((0, 1)), img.max((0, 1)), expected)


def test_emitter_seen_directly_returns_its_radiance(scene_dir):
    quad = quad_obj([(-5, 2, -5), (5, 2, -5), (5, 2, 5), (-5, 2, 5)], material="lamp")
    objs, mtls = write_scene_files(scene_dir, "lamp", quad, material("lamp", Kd=(1, 1, 1), Kl=(3.0, 2.0, 0.5)))
    cam = Camera(position=(0, 0, 0), direction=(0, 1, 0), fov=60.0, aperture=0.0, focus=2.0)
    img = R.render(load_scene(objs, mtls), cam, width=8, height=8, spp=2, max_depth=1, sky=Sky.constant(0, 0, 0))
    assert np.array_equal(img, np.broadcast_to(np.float32([3.0, 2.0, 0.5]), img.shape))


def _pixel_directions(cam: Camera, w: int, h: int) -> np.ndarray:
    f = cam.frame(w, h)
    x, y = np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5)
    p = f["upper_left"] + x[..., None] * f["x_step"] - y[..., None] * f["y_step"]
    d = p - f["origin"]
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


@pytest.mark.parametrize("sky", [Sky.black(), Sky.pink(), Sky.constant(0, 0, 0), Sky.gradient()])
def test_miss_returns_the_sky(scene_dir, sky):
    # The only geometry is a sphere behind the camera, so every camera ray misses.
    objs, mtls = write_scene_files(scene_dir, "behind", "b 0 -50 0 1\n")
    cam = Camera(position=(0, 0, 0), direction=(0.2, 1, 0.4), fov=20.0, aperture=0.0, focus=1.0)
    img = R.render(load_scene(objs, mtls), cam, width=16, height=12, spp=8, max_depth=3, sky=sky)
    d = _pixel_directions(cam, 16, 12)
    expected = np.stack([np.float32(sky.radiance(z)) for z in d[..., 2].ravel()]).reshape(12, 16, 3)
    # Constant skies are exact. The gradient's red channel changes by 0.25 per unit of z, and z
    # varies by less than the pixel's angular size across a pixel: the pixel mean stays within that.
    tol = 0.25 * np.radians(20.0) / 16 if sky.kind else 0.0
    assert np.allclose(img, expected, atol=tol, rtol=0)


def test_diffuse_sphere_in_uniform_sky_is_albedo_times_sky(scene_dir):
    # A convex diffuse body under a uniform sky: every bounce escapes, so L = albedo * sky exactly.
    mtl = material("ball", Kd=(0.25, 0.5, 0.75), Roughness=1)
    objs, mtls = write_scene_files(scene_dir, "ball", "usemtl ball\nb 0 5 0 1.5\n", mtl)
    cam = Camera(position=(0, 0, 0), direction=(0, 1, 0), fov=10.0, aperture=0.0, focus=5.0)
    img = R.render(load_scene(objs, mtls), cam, width=8, height=8, spp=4, max_depth=4, integrator="seed",
                   sky=Sky.constant(2.0, 2.0, 2.0))
    assert np.allclose(img, [0.5, 1.0, 1.5], rtol=1e-6)


def test_clear_glass_sphere_conserves_energy_in_uniform_sky(scene_dir):
    # White glass (Kd = Kt = 1, no fuzz) scatters without loss: the image converges to the sky.
    mtl = material("glass", Kd=(1, 1, 1), Kt=(1, 1, 1), Roughness=0, Fuzz=0, Kn=1.5, Refractable=True)
    objs, mtls = write_scene_files(scene_dir, "glass", "usemtl glass\nb 0 5 0 1.5\n", mtl)
    cam = Camera(position=(0, 0, 0), direction=(0, 1, 0), fov=40.0, aperture=0.0, focus=5.0)
    img = R.render(load_scene(objs, mtls), cam, width=16, height=16, spp=16, max_depth=64,
                   sky=Sky.constant(1.0, 1.0, 1.0))
    # only paths still bouncing after 64 hits can lose energy; they are vanishingly rare
    assert img.max() <= 1.0 + 1e-5
    assert img.mean() > 0.999


@pytest.fixture(scope="module")
def screen(tmp_path_factory):
    """A 4x4-texel emissive quad 4 units in front of the camera; returns (scene, texels)."""
    from PIL import Image
    folder = tmp_path_factory.mktemp("screen")
    tex = np.random.default_rng(1).integers(0, 256, size=(4, 4, 3), dtype=np.uint8)
    Image.fromarray(tex).save(folder / "t.png")
    quad = quad_obj([(-2, 4, -2), (2, 4, -2), (2, 4, 2), (-2, 4, 2)], material="screen")
    mtl = material("screen", Kd=(0, 0, 0)) + f"map_Kl {folder / 't.png'}\n"
    objs, mtls = write_scene_files(folder, "screen", quad, mtl)
    return load_scene(objs, mtls), tex / 255.0


SCREEN_FOV = 2 * np.degrees(np.arctan(0.5))   # the quad exactly fills the view at distance 4


@pytest.mark.parametrize("aperture", [0.0, 0.5])
def test_textured_emitter_in_focus_matches_texels(screen, aperture):
    # One texel per pixel, whatever the jitter inside the pixel; with a thin lens focused on the
    # quad, every lens point sees the same point of it, so a wide aperture changes nothing.
    scene, texels = screen
    cam = Camera(position=(0, 0, 0), direction=(0, 1, 0), fov=SCREEN_FOV, aperture=aperture, focus=4.0)
    img = R.render(scene, cam, width=4, height=4, spp=4, max_depth=1, sky=Sky.constant(0, 0, 0))
    assert np.allclose(img, texels, atol=1e-6)


def test_out_of_focus_emitter_is_blurred(screen):
    # Focused at 2 instead of 4, a lens of radius 0.5 spreads each point over about 0.5 texel.
    scene, texels = screen
    cam = Camera(position=(0, 0, 0), direction=(0, 1, 0), fov=SCREEN_FOV, aperture=0.5, focus=2.0)
    img = R.render(scene, cam, width=4, height=4, spp=64, max_depth=1, sky=Sky.constant(0, 0, 0))
    assert np.abs(img - texels).mean() > 0.05


def test_same_seed_same_image_across_threads_and_tiles(furnace):
    kw = dict(width=20, height=10, spp=9, max_depth=3, seed=7)
    a = R.render(furnace, INSIDE, threads=1, **kw)
    b = R.render(furnace, INSIDE, threads=2, tile_pixels=37, **kw)
    c = R.render(furnace, INSIDE, threads=2, tile_pixels=1, **kw)
    assert np.array_equal(a, b) and np.array_equal(a, c)


def test_specialised_and_general_kernels_agree(scene_dir):
    mtl = material("ball", Kd=(0.8, 0.3, 0.3), Roughness=0.5, Fuzz=0.3) + material("lamp", Kl=(4, 4, 4))
    objs, mtls = write_scene_files(scene_dir, "spec", "usemtl ball\nb 0 0 0 1\nusemtl lamp\nb 0 0 2.5 0.5\n", mtl)
    scene = DeviceScene(load_scene(objs, mtls))
    assert not scene.features.meshes and not scene.features.textures
    cam = Camera(position=(0, -6, 0), direction=(0, 1, 0), fov=40.0, aperture=0.0, focus=6.0)
    kw = dict(width=12, height=12, spp=4, max_depth=4, seed=3, sky=Sky.gradient())
    a = R.render(scene, cam, **kw)
    res = R.render_scene(scene, cam, RenderSettings(features=Features.general(), **kw))
    assert np.array_equal(a, res.image)
    assert res.stats.dropped_samples == 0
