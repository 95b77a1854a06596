"""The environment map's texels as one named parameter, ``environment.texels`` (issue 34, section 4):
read, set and validated like a texture; its gradient against finite differences of renders.

The image is linear in the texels, so a finite difference of any size is the derivative. Where the
sampling does not depend on the map (uniform sampling, or the tape's pure path tracing) the renders
on both sides take the very same samples and the check is sample for sample. Under importance
sampling the light distribution is rebuilt from the perturbed map while the gradient holds it fixed
(detached): the two agree in expectation (Student t over seeds), which is the claim that detaching
the distribution leaves the gradient unbiased.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

import warp_spt as ws
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.camera import Camera
from warp_spt.scene.environment import EnvironmentMap
from warp_spt.scene.sky import Sky

from tests.support.scenes import material, write_scene_files
from tests.support.stability_scenes import t_quantile

Z = (0.0, 0.0, 1.0)
CAM = Camera(position=(0.0, -5.0, 1.0), direction=(0.0, 1.0, -0.2), fov=35.0, up=Z)
# (row, column) of the texels perturbed: a bright one above the horizon, a dim one beside it, one
# below the horizon (it lights the ball's underside), one the ball cannot see past itself
TEXELS = [(2, 5), (3, 12), (6, 9), (1, 0)]


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    """A diffuse ball (albedo 0.8) on a diffuse floor (so that rays bounce before they escape)."""
    d = tmp_path_factory.mktemp("envtexels")
    obj = ("v -4 -4 -1\nv 4 -4 -1\nv 4 4 -1\nv -4 4 -1\nusemtl floor\nf 1 2 3\nf 1 3 4\n"
           "usemtl white\nb 0 0 0 1\n")
    objs, mtls = write_scene_files(d, "ball", obj, material("white", Kd=(0.8, 0.8, 0.8), Roughness=1)
                                   + material("floor", Kd=(0.5, 0.5, 0.5), Roughness=1))
    return ws.load_scene(objs, mtls)


def env_image() -> np.ndarray:
    rng = np.random.default_rng(4)
    img = rng.uniform(0.2, 1.0, (8, 16, 3)).astype(np.float32)
    img[2, 4:7] = 20.0                      # a bright patch: importance sampling favours it
    return img


def sky(img, sampling="importance"):
    return Sky.environment(EnvironmentMap(img, sampling=sampling), up=Z, background=(0.0, 0.0, 0.0))


def render_sum(scene, img, rs, sampling) -> float:
    return float(ws.render_scene(replace(scene, sky=sky(img, sampling)), CAM, rs).image.astype(np.float64).sum())


def test_the_texels_are_a_parameter_read_set_and_checked(ball):
    img = env_image()
    p = ws.parameters(replace(ball, sky=sky(img)), CAM)
    assert p.info("environment.texels").shape == (8, 16, 3)
    assert np.array_equal(p["environment.texels"], img)
    new = img * 0.5
    p["environment.texels"] = new
    assert np.array_equal(p.sky.env.image, new) and p.sky.env.sampling == "importance"
    with pytest.raises(ValueError, match="environment.texels"):
        p["environment.texels"] = -img
    with pytest.raises(ValueError, match="shape"):
        p["environment.texels"] = img[:4]
    assert "environment.texels" not in ws.parameters(ball, CAM, sky=Sky.black())


@pytest.mark.parametrize("mode,integrator,sampling", [("prb", "nee", "uniform"), ("tape", "seed", "importance")])
def test_texel_gradient_is_the_finite_difference_sample_for_sample(ball, mode, integrator, sampling):
    # the samples do not depend on the map (uniform light sampling; or none: pure path tracing), so the
    # central difference at the same seed is the derivative up to float32 rounding
    img = env_image()
    scene = replace(ball, sky=sky(img, sampling))
    rs = RenderSettings(width=8, height=6, spp=8, max_depth=3, integrator=integrator, seed=3)
    g = ws.render_gradients(ws.parameters(scene, CAM), rs, adjoint=np.ones((6, 8, 3)), wrt=["environment.texels"],
                            mode=mode)
    assert g.mode == mode
    grad = g.grads["environment.texels"]
    assert grad.shape == img.shape
    h = 0.25
    for r, c in TEXELS:
        for ch in (0, 2):
            hi, lo = img.copy(), img.copy()
            hi[r, c, ch] += h
            lo[r, c, ch] -= h
            fd = (render_sum(scene, hi, rs, sampling) - render_sum(scene, lo, rs, sampling)) / (2 * h)
            assert grad[r, c, ch] == pytest.approx(fd, rel=2e-3, abs=1e-4 * abs(grad).max()), (r, c, ch)
    assert (grad[:4] > 0).sum() > 30            # the upper half lights the view: most texels matter


def test_texel_gradient_with_a_detached_distribution_is_unbiased(ball):
    # importance sampling: the renders of the finite difference rebuild the distribution from the
    # perturbed map; the gradient holds it fixed. Both estimate d E[sum I] / d texel: compared over
    # seeds within their joint standard error (Welch t, Bonferroni over the texels)
    img = env_image()
    scene = replace(ball, sky=sky(img))
    rs = RenderSettings(width=6, height=6, spp=16, max_depth=2, integrator="nee")
    k, h = 8, 4.0      # large steps: the image is linear in the texels, and the differences stand out
    grads = []
    for seed in range(k):
        g = ws.render_gradients(ws.parameters(scene, CAM), replace(rs, seed=seed), adjoint=np.ones((6, 6, 3)),
                                wrt=["environment.texels"], mode="prb")
        grads.append(g.grads["environment.texels"])
    grads = np.array(grads)
    bound = t_quantile(1e-3 / len(TEXELS), k - 1)
    for r, c in TEXELS:
        hi, lo = img.copy(), img.copy()
        hi[r, c, 1] += h
        lo[r, c, 1] = max(0.0, img[r, c, 1] - h)
        fds = np.array([(render_sum(scene, hi, replace(rs, seed=100 + s), "importance")
                         - render_sum(scene, lo, replace(rs, seed=200 + s), "importance")) / (hi[r, c, 1] - lo[r, c, 1])
                        for s in range(k)])
        gk = grads[:, r, c, 1]
        se = math.sqrt(gk.var(ddof=1) / k + fds.var(ddof=1) / k)
        assert abs(gk.mean() - fds.mean()) < bound * se + 0.02 * abs(fds.mean()), (r, c, gk.mean(), fds.mean(), se)
    assert abs(grads[:, 2, 5, 1].mean()) > 10 * grads[:, 2, 5, 1].std() / math.sqrt(k)    # not lost in noise
