"""Gradients of the pbr kind's parameters by name, against finite differences of the expected image.

The pbr kind holds its sampled directions, densities and lobe-choice probabilities still
(``bsdfs.common.held``): a sample's derivative is f'/p, the detached-sampling estimator, so
the gradient is the derivative of the *expected* image. Its lobe choice moves with the parameters,
so finite differences with common random numbers are not smooth sample by sample, but their mean
over seeds is the derivative of the expectation. The check: over 12 seeds, the mean gradient (path
replay, and the tape) against the mean central difference of the fast renderer, within 4
combined standard errors, with the derivative resolved (more than 5 standard errors from 0). The
expected image is linear in metallic and transmission (they weigh the lobes), so their steps are large.

The scene: one pbr quad (metal, dielectric layer, transmission, anisotropy together) filling the
view under the gradient sky, lit from the side by a lamp that the diffuse base sees and the mirror
direction does not; one bounce.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from warp_spt.diff.gradients import render_gradients
from warp_spt.diff.params import parameters
from warp_spt.io.loader import load_scene
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

from tests.support.scenes import quad_obj, write_scene_files
from tests.diff.test_param_gradients import _image_sum, _ones

CAM = Camera(position=(0.3, -0.2, 2.0), direction=(-0.15, 0.1, -1.0), fov=50.0, aperture=0.0, focus=2.0)
RS = RenderSettings(width=6, height=6, spp=512, max_depth=2, seed=3, integrator="nee", sampler="independent")
# (name, component, finite-difference step): the expected image is linear in metallic and transmission
# (the mixture's weights), so their steps can be large, which quiets the differences; anisotropy's
# alpha is quadratic in it, and a step of 0.2 moved its differences by 6% (-5.93 against -5.60 at 0.05)
NAMES = [("cup.base_color", 0, 0.05), ("cup.metallic", (), 0.3), ("cup.roughness", (), 0.15),
         ("cup.transmission", (), 0.25), ("cup.anisotropy", (), 0.05)]


@pytest.fixture(scope="module")
def cup(scene_dir):
    mtl = ("newmtl cup\nKd 0.7 0.5 0.3\nPm 0.4\nPr 0.45\nd 0.7\nNi 1.5\naniso 0.5\nanisor 0.1\n"
           "newmtl lamp\nKd 0 0 0\nKe 6 6 6\n")
    obj = (quad_obj([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], material="cup")
           + "v 2.5 -1 0.3\nv 2.5 1 0.3\nv 2.5 1 2.3\nv 2.5 -1 2.3\nusemtl lamp\nf 5 6 7\nf 5 7 8\n")
    return load_scene(*write_scene_files(scene_dir, "cup", obj, mtl))


def test_pbr_parameters_are_named(cup):
    p = parameters(cup, CAM, Sky.gradient())
    for name, _, _ in NAMES:
        assert name in p
    assert p["cup.metallic"] == pytest.approx(0.4) and p["cup.transmission"] == pytest.approx(0.3)


@pytest.mark.parametrize("mode", ["prb", "tape"])
def test_pbr_gradients_are_the_derivative_of_the_expected_image(cup, mode):
    p = parameters(cup, CAM, Sky.gradient())
    feats = p.scene.features
    seeds = 12
    grads = {n: [] for n, _, _ in NAMES}
    for s in range(seeds):
        r = render_gradients(p, replace(RS, seed=s), adjoint=_ones(RS), wrt=[n for n, _, _ in NAMES], mode=mode)
        assert r.mode == mode
        for n, i, _ in NAMES:
            grads[n].append(float(np.asarray(r.grads[n], dtype=np.float64)[i]))
    for n, i, h in NAMES:
        fd = []
        v0 = np.array(p[n], dtype=np.float64)
        for s in range(seeds):
            ends = []
            for step in (h, -h):
                v = v0.copy()
                if v.ndim:
                    v[i] += step
                else:
                    v = v + step
                p[n] = v
                ends.append(_image_sum(p, replace(RS, seed=100 + s, features=feats)))
            fd.append((ends[0] - ends[1]) / (2 * h))
        p[n] = v0
        g, f = np.array(grads[n]), np.array(fd)
        se = np.sqrt(g.var(ddof=1) / seeds + f.var(ddof=1) / seeds)
        print(f"{mode} {n}: gradient {g.mean():.4f} (se {g.std(ddof=1) / np.sqrt(seeds):.4f}), finite differences "
              f"{f.mean():.4f} (se {f.std(ddof=1) / np.sqrt(seeds):.4f})")
        assert abs(f.mean()) > 5 * se, (n, f.mean(), se)          # resolved: the test can fail
        assert abs(g.mean() - f.mean()) < 4 * se + 0.02 * abs(f.mean()), (n, g.mean(), f.mean(), se)


def test_pbr_ior_gradient_through_the_tape(cup):
    """The index of refraction is a pathwise parameter (it bends the seed's glass and smooth
    refraction), so only the tape takes it; on this rough cup (its layer's F0 and the rough
    transmission's weights depend on it, the sampled directions are held still) it is the
    derivative of the expected image, as the others."""
    p = parameters(cup, CAM, Sky.gradient())
    feats = p.scene.features
    seeds = 12
    g = np.array([float(render_gradients(p, replace(RS, seed=s), adjoint=_ones(RS), wrt=["cup.ior"], mode="tape")
                        .grads["cup.ior"]) for s in range(seeds)])
    v0, h, fd = float(p["cup.ior"]), 0.1, []
    for s in range(seeds):
        ends = []
        for step in (h, -h):
            p["cup.ior"] = v0 + step
            ends.append(_image_sum(p, replace(RS, seed=100 + s, features=feats)))
        fd.append((ends[0] - ends[1]) / (2 * h))
    p["cup.ior"] = v0
    f = np.array(fd)
    se = np.sqrt(g.var(ddof=1) / seeds + f.var(ddof=1) / seeds)
    print(f"tape cup.ior: gradient {g.mean():.4f}, finite differences {f.mean():.4f}, se {se:.4f}")
    assert abs(f.mean()) > 5 * se, (f.mean(), se)
    assert abs(g.mean() - f.mean()) < 4 * se + 0.02 * abs(f.mean()), (g.mean(), f.mean(), se)
