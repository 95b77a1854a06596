"""Sun, point and spot lights (issue 34, part 2) against independent checks.

* A point light of intensity I at height h over a diffuse plane of albedo a: each pixel's radiance
  is the mean over its footprint of a / pi * I cos / r^2 (closed form, integrated in numpy).
* A spot over the same plane: the same with glTF's falloff, evaluated in numpy from its formula.
* The sun of radius r > 0, fully above the horizon, gives irradiance E cos(theta_sun) exactly (the
  projected solid angle of a cap is pi sin^2 r cos theta): the plane's radiance a / pi E cos.
* The sun of radius 0 against a distant small emitting sphere of the same irradiance, over a floor
  with a box casting a shadow: two independent sets of renders agree per pixel (Welch's t).
* A scene whose only light is a delta light renders with every integrator that samples lights.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.io.loader import load_scene
from warp_spt.scene.lights import PointLight, SpotLight, SunLight, spot_falloff

from tests.support.scenes import material, write_scene_files
from tests.support.stability_scenes import GENERAL, quads_obj, sky, t_quantile
from tests.integrators.test_light_transport import ALBEDO, FLOOR, FLOOR_CAM, assert_matches_expected, floor_points, seed_batches

W, H = 12, 10


def floor_scene(folder, lights, extra_quads=(), spheres=(), mtl_extra="") -> DeviceScene:
    obj = quads_obj([("floor", FLOOR), *extra_quads], spheres=spheres)
    mtl = material("floor", Kd=(ALBEDO,) * 3, Roughness=1) + mtl_extra
    objs, mtls = write_scene_files(folder, f"punctual_{abs(hash((obj, mtl))) % 10**8}", obj, mtl)
    scene = load_scene(objs, mtls, warn=lambda message: None)
    return DeviceScene(replace(scene, lights=list(lights)))


def expected_under(light_fn, sub: int) -> np.ndarray:
    """(H, W) mean over each pixel's footprint of a / pi * E(x), E(x) = light_fn(points)."""
    pts = floor_points(FLOOR_CAM, W, H, sub)
    return (ALBEDO / np.pi * light_fn(pts.reshape(-1, 3)).reshape(H, W, -1)).mean(axis=2)


def point_irradiance(pos, intensity, falloff=None):
    def e(x):
        d = np.asarray(pos) - x
        r2 = (d * d).sum(1)
        cos = d[:, 2] / np.sqrt(r2)
        out = intensity * cos / r2
        if falloff is not None:
            out = out * falloff(-d / np.sqrt(r2)[:, None])
        return out
    return e


def check_against(dev, fn, spp=4, batches=8, **kw):
    # the footprint quadrature's own error, per pixel: 16x16 points against 8x8 (large only where a
    # spot's edge crosses the pixel)
    e16, e8 = expected_under(fn, 16), expected_under(fn, 8)
    slack = (np.abs(e16 - e8) / np.maximum(e16, 1e-12))[..., None]
    b = seed_batches(dev, FLOOR_CAM, batches, spp, 0, width=W, height=H, max_depth=2, sky=sky(0.0),
                     integrator="nee", features=GENERAL, **kw)
    assert_matches_expected(b, np.repeat(e16[..., None], 3, axis=2), rel_slack=slack)
    return e16


def test_point_light_over_a_diffuse_plane(scene_dir):
    pos, i = (0.3, 0.5, 1.5), 7.0
    dev = floor_scene(scene_dir, [PointLight(position=pos, intensity=(i, i, i))])
    e = check_against(dev, point_irradiance(pos, i))
    assert e.max() > 2 * e.min() > 0           # the light really varies over the image


def test_spot_falloff_over_a_diffuse_plane(scene_dir):
    pos, i, inner, outer = (0.0, 0.4, 2.0), 20.0, 10.0, 25.0
    axis = np.array([0.0, 0.3, -1.0])
    axis /= np.linalg.norm(axis)
    spot = SpotLight(position=pos, direction=tuple(axis), intensity=(i, i, i), inner_deg=inner, outer_deg=outer)
    dev = floor_scene(scene_dir, [spot])

    def falloff(to_x):          # to_x: unit directions from the light to the points
        return np.array([spot_falloff(float(c), inner, outer) for c in to_x @ axis])

    e = check_against(dev, point_irradiance(pos, i, falloff))
    assert (e == 0).any() and (e > 0).sum() > 10      # the cone's edge crosses the image


def test_spot_falloff_formula():
    # glTF's recommended falloff: full inside the inner cone, none outside the outer, the square of a
    # linear ramp in the cosine between (checked at the ramp's middle)
    ci, co = math.cos(math.radians(10)), math.cos(math.radians(30))
    assert spot_falloff(1.0, 10, 30) == 1.0 and spot_falloff(co - 1e-6, 10, 30) == 0.0
    assert math.isclose(spot_falloff((ci + co) / 2, 10, 30), 0.25, rel_tol=1e-12)


@pytest.mark.parametrize("radius", [0.0, 5.0])
def test_sun_irradiance_on_a_plane(scene_dir, radius):
    d = np.array([0.4, -0.3, 1.0])
    e_sun = 2.5
    dev = floor_scene(scene_dir, [SunLight(direction=tuple(d), color=(e_sun,) * 3, radius_deg=radius)])
    cos = d[2] / np.linalg.norm(d)
    expected = np.full((H, W, 3), ALBEDO / np.pi * e_sun * cos)
    b = seed_batches(dev, FLOOR_CAM, 8, 4, 0, width=W, height=H, max_depth=2, sky=sky(0.0),
                     integrator="nee", features=GENERAL)
    assert_matches_expected(b, expected)
    if radius == 0.0:
        assert np.allclose(b, expected, rtol=1e-4)      # a delta sun: every sample is the same


def test_delta_sun_matches_a_distant_sphere(scene_dir):
    # A sphere of radius rho at distance D along w emitting L gives irradiance L pi (rho / D)^2 to a
    # plane facing it; the sun of radius 0 with that irradiance must render the same image (a box
    # casts its shadow on the floor; the sphere's penumbra is 5e-3 rad wide, under a pixel here).
    w = np.array([0.5, -0.4, 1.0])
    w /= np.linalg.norm(w)
    dist, rho, lum = 2000.0, 10.0, 50.0
    e_sun = lum * math.pi * (rho / dist) ** 2          # the cap's L pi sin^2 a, sin a = rho / D
    box = [("box", [(-0.4, -0.4, 0.8), (0.4, -0.4, 0.8), (0.4, 0.4, 0.8), (-0.4, 0.4, 0.8)])]
    mtl_box = material("box", Kd=(0.3, 0.3, 0.3), Roughness=1)
    centre = tuple(float(c) for c in w * dist)
    sphere_dev = floor_scene(scene_dir, [], box, spheres=[("sun", centre, rho)],
                             mtl_extra=mtl_box + material("sun", Kd=(0, 0, 0), Kl=(lum,) * 3))
    sun_dev = floor_scene(scene_dir, [SunLight(direction=tuple(w), color=(e_sun,) * 3)], box, mtl_extra=mtl_box)
    kw = dict(width=W, height=H, max_depth=3, sky=sky(0.0), integrator="nee", features=GENERAL)
    a = seed_batches(sphere_dev, FLOOR_CAM, 8, 8, 0, **kw)
    b = seed_batches(sun_dev, FLOOR_CAM, 8, 8, 100, **kw)
    ma, mb = a.mean(0), b.mean(0)
    se = np.sqrt(a.var(0, ddof=1) / len(a) + b.var(0, ddof=1) / len(b))
    bound = t_quantile(1e-4 / (2 * ma.size), 7)
    assert (np.abs(ma - mb) <= bound * se + 1e-3 * np.abs(mb) + 1e-6).all(), np.max(np.abs(ma - mb) / (se + 1e-12))
    assert mb.min() < 0.5 * mb.max()          # the shadow is in the image


@pytest.mark.parametrize("integrator", ["nee", "guided", "ears"])
def test_only_delta_lights_render(scene_dir, integrator):
    pos, i = (0.3, 0.5, 1.5), 7.0
    dev = floor_scene(scene_dir, [PointLight(position=pos, intensity=(i, i, i))])
    assert dev.features.lights == ("punctual",) and not dev.features.emitters
    from warp_spt.rendering.settings import RenderSettings
    from warp_spt.rendering.tiles import render_scene
    img = render_scene(dev, FLOOR_CAM, RenderSettings(width=W, height=H, spp=16, max_depth=2, sky=sky(0.0),
                                                      integrator=integrator)).image
    e = expected_under(point_irradiance(pos, i), 8)
    # the footprint's sampling is the only noise (a few % per pixel at 16 spp); the guided and ears
    # integrators' own agreement with nee is tests/integrators/test_light_transport.py's
    assert np.allclose(img[..., 0], e, rtol=0.15) and abs(img[..., 0].mean() / e.mean() - 1) < 0.02


# --------------------------------------------------------------------------------------------
# Gradients against finite differences (common random numbers: the same seed on both sides)

def _fd(params, rs, name, h):
    from warp_spt.rendering.tiles import render_scene

    v = params[name].astype(np.float64)
    out = np.zeros(3)
    for i in range(3):
        vals = []
        for s in (1, -1):
            params[name] = v + s * h * np.eye(3)[i]
            vals.append(render_scene(params.scene, params.camera, rs).image.astype(np.float64).sum())
        out[i] = (vals[0] - vals[1]) / (2 * h)
    params[name] = v
    return out


@pytest.mark.parametrize("light, names", [
    (PointLight(position=(0.3, 0.5, 1.5), intensity=(7.0, 5.0, 3.0), name="bulb"), ["bulb.position", "bulb.intensity"]),
    (SpotLight(position=(0.0, 0.4, 2.0), direction=(0.0, 0.3, -1.0), intensity=(20.0, 20.0, 20.0), inner_deg=10,
               outer_deg=40, name="spot"), ["spot.position"]),
    (SunLight(direction=(0.4, -0.3, 1.0), color=(2.5, 2.0, 1.5)), ["sun.direction", "sun.color"]),
])
def test_light_gradients_match_finite_differences(scene_dir, light, names):
    from warp_spt.diff.gradients import render_gradients
    from warp_spt.diff.params import parameters
    from warp_spt.rendering.settings import RenderSettings

    dev = floor_scene(scene_dir, [light])
    p = parameters(dev, FLOOR_CAM, sky(0.0))
    rs = RenderSettings(width=8, height=6, spp=4, max_depth=2, sky=sky(0.0), integrator="nee")
    assert set(names) <= set(p.names())
    for name in names:
        r = render_gradients(p, rs, adjoint=np.ones((rs.height, rs.width, 3), np.float32), wrt=[name])
        assert r.mode == "prb"          # a position moves the light samples: the pathwise kernel
        g = r.grads[name]
        fd = _fd(p, rs, name, 1e-2 if name.endswith(("position", "direction")) else 1e-1)
        assert np.allclose(g, fd, rtol=0.02, atol=0.02 * np.abs(fd).max()), (name, g, fd)
        assert np.abs(fd).max() > 0
