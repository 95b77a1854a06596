"""The gradient sky follows the up axis (issue 11): a Y-up scene seen with ``--up y`` shows the same
sky as the equivalent Z-up scene. The Y-up scene is the Z-up one under the rotation
R(x, y, z) = (x, z, -y), which takes Z to Y and is exact in floating point (a signed permutation),
so every camera ray and mirror reflection of one scene is R of the other's, up to rounding."""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp

from warp_spt.cli.main import main
from warp_spt.emitters import Lights, sample_sky, sky_pdf, sky_radiance
from warp_spt.io.loader import load_scene
from warp_spt.rendering.tiles import render
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

from tests.support.scenes import material, write_scene_files


def rot(p) -> tuple[float, float, float]:
    """Z-up coordinates to Y-up ones."""
    return (p[0], p[2], -p[1])


BALLS = [((0.0, 0.0, 0.0), 1.0, "mirror"), ((2.5, 0.0, 0.3), 1.0, "matte")]
CAM_POS, CAM_DIR = (1.25, -8.0, 0.6), (0.0, 1.0, -0.08)
MTL = material("mirror", Kd=(0, 0, 0), Kr=(1, 1, 1), Roughness=0, Fuzz=0) + material("matte", Kd=(0.8, 0.8, 0.8))


def scene_files(tmp_path, up: str, balls=BALLS):
    move = rot if up == "y" else tuple
    obj = "".join(f"usemtl {m}\nb {' '.join(f'{v:g}' for v in move(c))} {r:g}\n" for c, r, m in balls)
    return write_scene_files(tmp_path / up, "balls", obj, MTL)


def cli_render(tmp_path, up: str, *extra: str) -> np.ndarray:
    objs, mtls = scene_files(tmp_path, up, BALLS[:1])
    move = rot if up == "y" else tuple
    out = tmp_path / f"{up}.npy"
    cam = [f"{v:g}" for v in (*move(CAM_POS), *move(CAM_DIR), 50, 8, 0)]
    assert main(["-obj", objs[0], "-mtl", mtls[0], "-cam", *cam, "-sky", "1", "--up", up, "-res", "24", "16",
                 "-sr", "2", "-depth", "4", "--quiet", "-out", str(out), *extra]) == 0
    return np.load(out)


def test_up_y_shows_the_same_sky_as_the_equivalent_z_up_scene(tmp_path):
    z_up, y_up = cli_render(tmp_path, "z"), cli_render(tmp_path, "y")
    # the sky seen directly and in the mirror ball: the same to float32 rounding (a ray grazing the
    # ball's rim may hit in one scene and miss in the other: a few pixels at most)
    close = np.isclose(y_up, z_up, rtol=1e-4, atol=1e-5).all(axis=2)
    assert close.mean() > 0.97, close.mean()
    assert np.abs(y_up.mean(axis=(0, 1)) - z_up.mean(axis=(0, 1))).max() < 2e-3
    # not vacuous: the sky varies across the image (0.5..1 in red), and a sky kept around Z in the
    # Y-up scene (the old behaviour) gives another image
    assert np.ptp(z_up[..., 0]) > 0.1
    objs, mtls = scene_files(tmp_path, "y", BALLS[:1])
    cam = Camera(position=rot(CAM_POS), direction=rot(CAM_DIR), fov=50, focus=8, aperture=0, up=(0, 1, 0))
    sideways = render(load_scene(objs, mtls, warn=lambda m: None), cam, width=24, height=16, spp=2, max_depth=4,
                      sky=Sky.gradient(up=(0, 0, 1)))
    assert np.abs(sideways - z_up).mean() > 0.02
    following = render(load_scene(objs, mtls, warn=lambda m: None), cam, width=24, height=16, spp=2, max_depth=4,
                       sky=Sky.gradient())           # the API: the sky follows the camera's up
    assert np.array_equal(following, y_up)


def test_the_z_up_default_is_the_seed_sky():
    assert Sky.gradient().up_axis() == (0.0, 0.0, 1.0)
    assert Sky.gradient().up_axis((0, 3, 0)) == (0.0, 1.0, 0.0)
    assert Sky.gradient(up=(2, 0, 0)).up_axis((0, 1, 0)) == (1.0, 0.0, 0.0)     # its own axis wins
    assert Sky.from_index(1) == Sky.gradient() and Sky.gradient().up is None


def block_means(img: np.ndarray) -> np.ndarray:
    return img.reshape(-1, 3).mean(axis=0)


def test_light_sampling_of_a_tilted_sky_matches_the_z_up_scene(tmp_path):
    """nee samples the sky around its up axis: a diffuse ball lit by the sky has the same expected
    image in both scenes (Welch t on independent seeds; diffuse bounces are not rotated, so the two
    images differ by noise only)."""
    imgs = {}
    for up in ("z", "y"):
        move = rot if up == "y" else tuple
        objs, mtls = scene_files(tmp_path, up, BALLS[1:])
        scene = load_scene(objs, mtls, warn=lambda m: None)
        cam = Camera(position=move(CAM_POS), direction=move(CAM_DIR), fov=50, focus=8, aperture=0,
                     up=move((0.0, 0.0, 1.0)))
        imgs[up] = np.array([block_means(render(scene, cam, width=16, height=12, spp=8, max_depth=3,
                                                sky=Sky.gradient(), seed=s, integrator="nee"))
                             for s in range(8)])
    z, y = imgs["z"], imgs["y"]
    se = np.sqrt(z.var(axis=0, ddof=1) / len(z) + y.var(axis=0, ddof=1) / len(y))
    t = (y.mean(axis=0) - z.mean(axis=0)) / se
    # 3 channels: |t| < 5 is a false failure with probability < 1e-3 even for 7 degrees of freedom
    assert (np.abs(t) < 5).all(), t
    assert math.isfinite(float(se.sum())) and (se > 0).all()


@wp.kernel(enable_backward=False)
def _sky_kernel(lights: Lights, u: wp.array(dtype=wp.vec2), dirs: wp.array(dtype=wp.vec3),
                pdf: wp.array(dtype=float), radiance: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    d = sample_sky(lights, u[i])
    dirs[i] = d
    pdf[i] = sky_pdf(lights, d)
    radiance[i] = sky_radiance(lights, d)


@pytest.mark.parametrize("up", [(0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (1.0, -2.0, 3.0)])
def test_sky_sampling_density_and_radiance_follow_the_up_axis(tmp_path, up):
    from warp_spt.upload.device_scene import DeviceScene
    from warp_spt.emitters import light_table, sky_density, sky_frame

    objs, mtls = scene_files(tmp_path, "z", BALLS[1:])
    sky = Sky.gradient(up=up)
    lights = light_table(DeviceScene(load_scene(objs, mtls, warn=lambda m: None)), sky)
    n = 200_000
    u = np.random.default_rng(1).random((n, 2)).astype(np.float32)
    out = [wp.zeros(n, dtype=t) for t in (wp.vec3, float, wp.vec3)]
    wp.launch(_sky_kernel, dim=n, inputs=[lights, wp.array(u, dtype=wp.vec2), *out])
    d, pdf, rad = (o.numpy().astype(np.float64) for o in out)
    t, b, axis = sky_frame(sky.up)
    z = d @ axis
    a, slope = sky_density(sky)
    # the reference: density (a + slope z) / (4 pi a) in z along the axis, uniform in azimuth around it
    np.testing.assert_allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-5)
    np.testing.assert_allclose(pdf, (a + slope * z) / (4 * np.pi * a), rtol=1e-5)
    np.testing.assert_allclose(rad, np.stack([0.75 - 0.25 * z, 0.85 - 0.15 * z, np.ones(n)], 1), atol=1e-5)
    edges = np.linspace(-1, 1, 11)
    expected = n * np.diff(a * edges + 0.5 * slope * edges ** 2) / (2 * a)     # integral of (a + slope z) / 2a
    counts = np.histogram(z, edges)[0]
    chi2 = ((counts - expected) ** 2 / expected).sum()
    assert chi2 < 35, chi2          # 9 degrees of freedom: P(chi2 > 35) < 1e-4
    for other in (t, b):            # uniform azimuth: no mean across the axis
        assert abs((d @ other).mean()) < 5 * np.sqrt(0.5 / n)
