"""Camera, gradient-sky and procedural-texture parameters against central finite differences.

One scene serves all three (so one pair of kernels per estimator is compiled): a quad much larger
than the view, with Perlin noise (``proc:noise``) as its diffuse colour, half diffuse and half fuzzy
mirror, under the gradient sky, at depth 2 (the camera ray's hit, then one bounce into the sky). No
silhouette is in view and no fuzzed direction dips below the quad, so the image is a smooth function
of the camera and of the texture's scale: the pathwise derivative is the derivative.

* Linear parameters (sky colours, texture colours): with common random numbers the image is linear
  in them, so a central difference agrees with the gradient to float32 rounding (rel 2e-3, as in
  test_param_gradients.py).
* Non-linear ones (camera position and direction, noise scale): central differences D(h) at eight
  steps h0 (1 + k/7) are fitted as D(h) = R + a h^2 (the central difference's error model). R is the
  reference and the fit's standard error se(R) (6 degrees of freedom) covers both the truncation left
  over and float32 noise: |gradient - R| <= 6 se(R) (about 1 in 1000 two-sided under the fit's t
  distribution) + 1e-5 |gradient| (float32 accumulation of the gradient itself). The test also
  requires 6 se(R) < 1% of the gradient's largest component: the reference resolves it.
* Path replay (auto's choice for the sky and texture parameters) equals the tape (auto's choice
  for the camera) to float32 rounding.
* Where a silhouette is in view the interior term alone is biased: the boundary term
  (diff.boundary) carries the rest, shown on a small quad seen whole.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from warp_spt.diff.check import check_gradients
from warp_spt.diff.gradients import render_gradients
from warp_spt.diff.params import parameters
from warp_spt.io.loader import load_scene
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

from tests.support.scenes import quad_obj, write_scene_files
from tests.diff.test_param_gradients import _assert_colours_match_fd, _image_sum, _ones
from tests.diff.test_param_gradients import _fd as central_difference

NOISE_MTL = ("newmtl quad\nKd 1 1 1\nmap_Kd proc:noise scale=1.5 color1=0.1,0.2,0.3 color2=0.9,0.8,0.6\n"
             "Roughness 0.5\nFuzz 0.2\n")
# Up is +Y: the view is nearly along -Z, and with the default Z up the image's axes would be
# cross(direction, up) of a near-zero vector, whose rotation makes the image strongly non-linear in
# the direction (central differences then need much smaller steps)
CAM = Camera(position=(0.1, -0.2, 2.0), direction=(0.05, 0.1, -1.0), fov=60.0, aperture=0.0, focus=2.0,
             up=(0.0, 1.0, 0.0))
SKY = Sky.gradient(zenith=(0.4, 0.6, 1.0), nadir=(0.9, 0.8, 0.7))
RS = RenderSettings(width=8, height=8, spp=8, max_depth=2, seed=3, integrator="seed")
ESTIMATORS = [("seed", "independent"), ("nee", "independent")]


def noise_quad(folder, half: float):
    obj = quad_obj([(-half, -half, 0), (half, -half, 0), (half, half, 0), (-half, half, 0)])
    return load_scene(*write_scene_files(folder, f"noisequad{half:g}", obj, NOISE_MTL))


@pytest.fixture(scope="module")
def big_quad(scene_dir):
    """4 x 4 units seen from 2 units up with a 60 degree view: its edges are well outside the image."""
    return noise_quad(scene_dir / "noisequad", 2.0)


def fitted_difference(params, rs, name: str, index, h0: float, n: int = 8) -> tuple[float, float]:
    """(R, se(R)): central differences at h0 (1 + k/(n-1)) fitted as R + a h^2 (see the module doc)."""
    hs = h0 * (1.0 + np.arange(n) / (n - 1))
    d = np.array([central_difference(params, rs, name, index, h) for h in hs])
    a = np.stack([np.ones(n), hs ** 2], axis=1)
    coef = np.linalg.lstsq(a, d, rcond=None)[0]
    resid = d - a @ coef
    cov = (resid @ resid / (n - 2)) * np.linalg.inv(a.T @ a)
    return float(coef[0]), math.sqrt(cov[0, 0])


def assert_matches_fit(g: float, ref: float, se: float, scale: float, what) -> None:
    """``scale``: the gradient's size (its largest component), which the reference must resolve.
    Prints the comparison (``pytest -s`` shows the figures of docs/gradients.md)."""
    print(f"{what}: gradient {g:.5f}, fitted FD {ref:.5f} +- {se:.5f} ({abs(g - ref) / se:.2f} se)")
    assert 6 * se < 0.01 * scale, (what, ref, se)
    assert abs(g - ref) <= 6 * se + 1e-5 * abs(g), (what, g, ref, se)


# --- names and values ----------------------------------------------------------------------

def test_new_parameter_names_values_and_validation(big_quad):
    p = parameters(big_quad, CAM, SKY)
    for n in ("quad.diffuse_map.scale", "quad.diffuse_map.color1", "quad.diffuse_map.color2", "sky.zenith",
              "sky.nadir", "camera.position", "camera.direction"):
        assert n in p and n in p.differentiable(), n
    assert "sky.color" not in p
    assert float(p["quad.diffuse_map.scale"]) == pytest.approx(1.5)
    assert p["quad.diffuse_map.color1"] == pytest.approx([0.1, 0.2, 0.3])
    assert p["sky.zenith"] == pytest.approx([0.4, 0.6, 1.0]) and p["sky.nadir"] == pytest.approx([0.9, 0.8, 0.7])
    for name, bad in [("quad.diffuse_map.color1", (-0.1, 0, 0)), ("quad.diffuse_map.scale", np.inf),
                      ("quad.diffuse_map.scale", (1.0, 2.0)), ("sky.zenith", (-1, 0, 0))]:
        with pytest.raises(ValueError):
            p[name] = bad
    before = _image_sum(p, RS)
    p["quad.diffuse_map.scale"] = 3.0
    assert p.scene.scene.procedural[0].params[0] == 3.0 and _image_sum(p, RS) != before
    p["quad.diffuse_map.scale"] = 1.5
    p["sky.zenith"] = (0.0, 0.0, 0.0)
    assert p.sky.zenith == (0.0, 0.0, 0.0) and p.sky.nadir == (0.9, 0.8, 0.7)
    p["sky.zenith"] = (0.4, 0.6, 1.0)
    assert _image_sum(p, RS) == before


def test_the_seed_gradient_sky_is_the_default():
    """The seed's GradientSky, (0.75 - 0.25 z, 0.85 - 0.15 z, 1), as zenith and nadir colours."""
    sky = Sky.gradient()
    for z in (-1.0, -0.3, 0.0, 0.6, 1.0):
        assert sky.radiance(z) == pytest.approx((0.75 - 0.25 * z, 0.85 - 0.15 * z, 1.0), abs=1e-15)
    with pytest.raises(ValueError, match="some colour"):
        Sky.gradient(zenith=(0, 0, 0), nadir=(0, 0, 0))


# --- linear parameters: exact with common random numbers -------------------------------------

def test_sky_and_texture_colour_gradients_match_finite_differences(big_quad):
    """Seed integrator: its paths do not depend on the sky (NEE's light table is weighted by it)."""
    p = parameters(big_quad, CAM, SKY)
    names = ["sky.zenith", "sky.nadir", "quad.diffuse_map.color1", "quad.diffuse_map.color2"]
    _assert_colours_match_fd(p, RS, names, least=1e-2, abs_tol=1e-4)


def test_path_replay_equals_the_tape_for_sky_and_procedural_parameters(big_quad):
    """Path replay (what ``mode="auto"`` takes for these) reads the light table's sky adjoints and the
    procedural parameters' array adjoints; the tape's adjoint of the unrolled step is the reference.
    The camera needs the tape: with it in ``wrt``, auto takes the tape and "prb" refuses by name."""
    p = parameters(big_quad, CAM, SKY)
    names = ["sky.zenith", "sky.nadir", "quad.diffuse_map.scale", "quad.diffuse_map.color1",
             "quad.diffuse_map.color2"]
    prb = render_gradients(p, RS, adjoint=_ones(RS), wrt=names)
    tape = render_gradients(p, RS, adjoint=_ones(RS), wrt=names, mode="tape")
    assert (prb.mode, tape.mode) == ("prb", "tape")
    for n in names:
        assert np.abs(tape.grads[n]).max() > 1e-2, n
        np.testing.assert_allclose(prb.grads[n], tape.grads[n], rtol=2e-4, atol=1e-5, err_msg=n)
    assert render_gradients(p, RS, adjoint=_ones(RS), wrt=["sky.zenith", "camera.position"]).mode == "prb"
    # the camera moves every hit: path replay takes it with its pathwise kernel, the tape's values
    tape = render_gradients(p, RS, adjoint=_ones(RS), wrt=["camera.direction"], mode="tape").grads["camera.direction"]
    pw = render_gradients(p, RS, adjoint=_ones(RS), wrt=["camera.direction"], mode="prb")
    assert pw.mode == "prb" and np.abs(tape).max() > 1e-3
    np.testing.assert_allclose(pw.grads["camera.direction"], tape, rtol=1e-3, atol=1e-5)


# --- non-linear parameters -----------------------------------------------------------------

@pytest.mark.parametrize("integrator,sampler", ESTIMATORS)
def test_camera_gradients_match_finite_differences(big_quad, integrator, sampler):
    p = parameters(big_quad, CAM, SKY)
    rs = replace(RS, integrator=integrator, sampler=sampler)
    r = render_gradients(p, rs, adjoint=_ones(rs), wrt=["camera.position", "camera.direction"])
    for name, h0 in (("camera.position", 2e-3), ("camera.direction", 1e-3)):
        g = r.grads[name]
        assert g.shape == (3,) and np.abs(g).max() > 0.5
        for c in range(3):
            ref, se = fitted_difference(p, rs, name, c, h0)
            assert_matches_fit(float(g[c]), ref, se, float(np.abs(g).max()), (integrator, name, c))


def test_camera_gradients_inside_a_sphere_match_finite_differences(scene_dir):
    """The sphere's re-intersection (the far root, from inside): a camera inside a sphere whose
    emission is Perlin noise sees no silhouette; depth 1, so the image is the emission at the hit."""
    mtl = ("newmtl glow\nKd 0.5 0.5 0.5\nKe 1 1 1\n"
           "map_Ke proc:noise scale=1.5 color1=0.1,0.2,0.3 color2=0.9,0.8,0.6\nRoughness 1\n")
    scene = load_scene(*write_scene_files(scene_dir / "insphere", "insphere", "usemtl glow\nb 0 0 0 3\n", mtl))
    cam = Camera(position=(0.3, -0.2, 0.1), direction=(0.2, 1.0, 0.1), fov=60.0, aperture=0.0, focus=2.0)
    p = parameters(scene, cam, SKY)
    rs = replace(RS, max_depth=1)
    r = render_gradients(p, rs, adjoint=_ones(rs), wrt=["camera.position", "camera.direction"])
    for name, h0 in (("camera.position", 2e-3), ("camera.direction", 1e-3)):
        g = r.grads[name]
        for c in range(3):
            ref, se = fitted_difference(p, rs, name, c, h0)
            assert_matches_fit(float(g[c]), ref, se, float(np.abs(g).max()), (name, c))


def test_procedural_scale_gradient_matches_finite_differences(big_quad):
    p = parameters(big_quad, CAM, SKY)
    g = float(render_gradients(p, RS, adjoint=_ones(RS), wrt=["quad.diffuse_map.scale"])
              .grads["quad.diffuse_map.scale"])
    ref, se = fitted_difference(p, RS, "quad.diffuse_map.scale", (), 2e-3)
    assert abs(g) > 0.1
    assert_matches_fit(g, ref, se, abs(g), "scale")


def test_a_silhouette_in_view_needs_the_boundary_term(scene_dir):
    """The same quad, small and seen whole against the sky. Moving the camera down enlarges it in the
    image: the pathwise (interior) gradient does not see its edges move, the boundary term
    (diff.boundary) does. check_gradients over four seeds (gradient and finite differences with
    h = 0.02 at 256 spp, seed s of each a pair) gives the standard error of their difference: with
    the boundary term the two agree within 4 of them (resolved to a fifth of the derivative); without
    it they differ by more than 6 (the big quad above needs none: no edge of it is in view)."""
    p = parameters(noise_quad(scene_dir / "noisequad", 0.5), CAM, SKY)
    kw = dict(adjoint=_ones(RS), wrt=["camera.position"], directions={"camera.position": (0.0, 0.0, 1.0)},
              seeds=range(4), step=0.02, rtol=0.0, print_table=False)
    rs = replace(RS, spp=256)
    (row,) = check_gradients(p, rs, sigmas=4.0, **kw).rows
    (row0,) = check_gradients(p, rs, sigmas=6.0, boundary=False, **kw).rows
    print(f"camera height: {row}\n  interior only: {row0}")
    assert row0.verdict == "DISAGREE", row0
    assert row.verdict == "agree", row
