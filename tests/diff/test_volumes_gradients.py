"""Gradients through participating media (issue 35): path replay of volpath against finite differences.

For each medium parameter (sigma_a and sigma_s per channel, g; a grid's density scale) the
gradient of a weighted sum of the image, sum(W * image) with fixed random weights W, is compared
with central finite differences of the forward renderer, common random numbers (the same seed on
both sides), over independent seeds: per seed the paired difference gradient - FD, and the test
asks that its mean lies within T_PAIRED of its standard error plus the FD's truncation allowance.
The FD steps are large (REL of the value) because with common random numbers a small step flips
discrete decisions (absorb, scatter or null; collision before or after a surface) whose jumps make
the FD's variance grow as 1/h; the central difference's truncation error at step h is h^2/6 of the
third derivative, for exp(-sigma d) (h d)^2 / 6 relative: TRUNCATION bounds it for the optical
depths of these scenes (h d <= 0.3). Each reference is also required to be resolved (its standard
error under RESOLVED of the largest component of its parameter's gradient), so that a wrong gradient
cannot pass by noise alone.

Scenes: a floor lit by an area light in chromatic fog (the scene's medium); an index-matched box of
chromatic medium on a floor in a thin fog (an interior medium: shadow rays cross its boundary, and
the floor's light samples pass through it) and the same box filled with a density grid (its
density scale). Analytic: in
a furnace (an index-matched ball of non-absorbing medium under a uniform sky of 1, every pixel 1
for any g and sigma_s) the gradients of g and sigma_s are 0 within their standard errors. The refusals of what is not supported are
checked too.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.diff.gradients import render_gradients
from warp_spt.diff.params import parameters
from warp_spt.io.loader import load_scene
from warp_spt.rendering import tiles as R
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.camera import Camera
from warp_spt.scene.media import Medium
from warp_spt.scene.sky import Sky

from tests.support.scenes import box_obj, write_scene_files

SIZE, SPP, DEPTH = 8, 256, 6
SEEDS = 8
REL = 0.3              # the FD step, relative to the value (g: to 0.5)
T_PAIRED = 4.0         # Student t with 7 degrees of freedom: two-sided p about 5e-3 per component
TRUNCATION = 0.02      # of |gradient|: (h d)^2 / 6 with h d <= 0.3 is 1.5%
RESOLVED = 0.3         # the reference's standard error below this fraction of |gradient|
SKY = Sky.constant(0.2, 0.2, 0.2)
CAM = Camera(position=(0, -5, 0.5), direction=(0, 1, -0.15), fov=50.0, aperture=0.0, focus=5.0)
def _join(*objs: str) -> str:
    """OBJ texts in one file: each one's face indices shifted past the vertices before it."""
    out, base = [], 0
    for text in objs:
        n = 0
        for line in text.splitlines():
            if line.startswith("v "):
                n += 1
                out.append(line)
            elif line.startswith("f "):
                out.append("f " + " ".join(str(int(i) + base) for i in line.split()[1:]))
            else:
                out.append(line)
        base += n
    return "\n".join(out) + "\n"


LAMP = box_obj(lo=(-0.4, -0.4, 1.5), hi=(0.4, 0.4, 1.7), material="lamp")
FLOOR = box_obj(lo=(-3, -3, -1.2), hi=(3, 3, -1.0), material="floor")
MTL = "newmtl floor\nKd 0.8 0.8 0.8\nnewmtl lamp\nKd 0 0 0\nKe 8 8 8\n"


def _settings(seed: int) -> RenderSettings:
    return RenderSettings(width=SIZE, height=SIZE, spp=SPP, max_depth=DEPTH, seed=seed, integrator="volpath", sky=SKY)


def _components(params, names):
    """(name, channel or None, step) for every scalar of the named parameters."""
    out = []
    for n in names:
        v = params[n]
        if v.shape:
            out += [(n, c, REL * float(v[c])) for c in range(3)]
        else:
            out.append((n, None, REL * (0.5 if n.endswith("g") else float(v))))
    return out


def _check(dev, names):
    """Gradient vs central FD (common random numbers) per seed; the paired test of the module docs."""
    params = parameters(dev, CAM, SKY)
    weights = np.random.default_rng(0).uniform(0.5, 1.5, (SIZE, SIZE, 3)).astype(np.float32)
    comps = _components(params, names)

    def value(seed):
        return float((R.render_scene(params.scene, CAM, _settings(seed)).image.astype(np.float64) * weights).sum())

    grads, fds = [], []
    for seed in range(1, SEEDS + 1):
        g = render_gradients(params, _settings(seed), adjoint=weights, wrt=list(names)).grads
        grads.append([g[n][c] if c is not None else float(g[n]) for n, c, _ in comps])
        row = []
        for n, c, h in comps:
            v0 = params[n].astype(np.float64)
            sides = []
            for sign in (1.0, -1.0):
                v = v0.copy()
                if c is None:
                    v = v + sign * h
                else:
                    v[c] += sign * h
                params[n] = v
                sides.append(value(seed))
            params[n] = v0
            row.append((sides[0] - sides[1]) / (2.0 * h))
        fds.append(row)
    grads, fds = np.asarray(grads), np.asarray(fds)
    diff = grads - fds
    se = diff.std(0, ddof=1) / math.sqrt(SEEDS)
    se_fd = fds.std(0, ddof=1) / math.sqrt(SEEDS)
    mean_g = grads.mean(0)
    report = "\n".join(f"{n}[{c}]: gradient {g:.4g}, FD {f:.4g} +- {s:.2g}, |t| {abs(d) / s:.2f}"
                       for (n, c, _), g, f, s, d in zip(comps, mean_g, fds.mean(0), se, diff.mean(0)))
    print("\n" + report)
    # resolved against the parameter's largest component (a channel's derivative may nearly cancel)
    scale = np.array([max(abs(g) for (m, _, _), g in zip(comps, mean_g) if m == n) for n, _, _ in comps])
    assert np.all(se_fd < RESOLVED * scale), report
    assert np.all(np.abs(diff.mean(0)) < T_PAIRED * se + TRUNCATION * np.abs(mean_g)), report


def test_fog_gradients(scene_dir):
    """A chromatic fog (the scene's medium): sigma_a, sigma_s per channel and g. Beside the room, out
    of the camera's and the lamp's way, stands the interior test's box of medium: so the two scenes
    have one feature set and share their kernels (a replay kernel with media is 90 s of the 2-core
    machine's compile); 40 units of fog (a transmittance below 1e-6) keep it out of the image."""
    hidden = box_obj(lo=(40.0, 40.0, -1.0), hi=(42.0, 42.0, 0.6), material="cloud")
    objs, mtls = write_scene_files(scene_dir, "fogroom", _join(FLOOR, LAMP, hidden),
                                   MTL + "newmtl cloud\nindex_matched\n")
    scene = load_scene(objs, mtls)
    scene.interiors = {"cloud": Medium(sigma_a=(0.1, 0.3, 0.5), sigma_s=(0.8, 0.5, 0.3), g=-0.3)}
    scene.fog = Medium(sigma_a=(0.05, 0.1, 0.2), sigma_s=(0.3, 0.2, 0.15), g=0.4)
    dev = DeviceScene(scene)
    assert dev.features == _box_scene(scene_dir, "same_features", Medium(sigma_s=0.5)).features
    _check(dev, ["fog.sigma_a", "fog.sigma_s", "fog.g"])


def _box_scene(scene_dir, name, medium):
    box = box_obj(lo=(-1.0, -1.0, -1.0), hi=(1.0, 1.0, 0.6), material="cloud")
    objs, mtls = write_scene_files(scene_dir, name, _join(FLOOR, LAMP, box), MTL + "newmtl cloud\nindex_matched\n")
    scene = load_scene(objs, mtls)
    scene.interiors = {"cloud": medium}
    scene.fog = Medium(sigma_s=0.02, sigma_a=0.01)
    return DeviceScene(scene)


def test_interior_medium_gradients(scene_dir):
    """A chromatic medium inside an index-matched box in a thin fog: its sigma_a, sigma_s and g."""
    dev = _box_scene(scene_dir, "cloudbox", Medium(sigma_a=(0.1, 0.3, 0.5), sigma_s=(0.8, 0.5, 0.3), g=-0.3))
    _check(dev, ["cloud.medium_sigma_a", "cloud.medium_sigma_s", "cloud.medium_g"])


def test_grid_gradients(scene_dir):
    """The box filled with a density ramp: its density scale (its sigma_s per unit density agreed
    within 1.3 standard errors too, but its FD is not resolved at this sample count)."""
    x = np.linspace(0.2, 1.0, 10, dtype=np.float32)
    rho = np.ascontiguousarray(np.broadcast_to(x[:, None, None], (10, 10, 10)))
    dev = _box_scene(scene_dir, "gridbox", Medium(sigma_a=(0.1, 0.2, 0.3), sigma_s=(0.6, 0.5, 0.4), g=0.2,
                                                  density=rho, density_scale=1.5, origin=(-1.1, -1.1, -1.1),
                                                  voxel_size=0.2))
    assert "grid" in dev.features.media
    _check(dev, ["cloud.medium_density_scale"])


def test_medium_parameters_by_name(scene_dir):
    """Names, values and write-through: a set coefficient renders as a scene built with it."""
    dev = _box_scene(scene_dir, "names", Medium(sigma_a=0.2, sigma_s=0.5))
    params = parameters(dev, CAM, SKY)
    assert {"fog.sigma_a", "fog.sigma_s", "fog.g", "cloud.medium_sigma_a", "cloud.medium_sigma_s",
            "cloud.medium_g"} <= set(params.names())
    assert "cloud.medium_density_scale" not in params.names()       # a homogeneous medium has none
    params["cloud.medium_sigma_s"] = (0.9, 0.5, 0.2)
    np.testing.assert_allclose(params["cloud.medium_sigma_s"], (0.9, 0.5, 0.2), rtol=1e-6)
    rs = RenderSettings(width=4, height=4, spp=4, max_depth=4, seed=2, integrator="volpath", sky=SKY)
    fresh = _box_scene(scene_dir, "names2", Medium(sigma_a=0.2, sigma_s=(0.9, 0.5, 0.2)))
    assert np.array_equal(R.render_scene(dev, CAM, rs).image, R.render_scene(fresh, CAM, rs).image)
    with pytest.raises(ValueError, match="g"):
        params["cloud.medium_g"] = 1.0
    with pytest.raises(ValueError, match="sigma_a"):
        params["fog.sigma_a"] = (-0.1, 0.0, 0.0)


def test_unsupported_media_gradients_are_refused(scene_dir):
    dev = _box_scene(scene_dir, "refuse", Medium(sigma_a=(0.2, 0.2, 0.2), sigma_s=(0.5, 0.0, 0.5)))
    params = parameters(dev, CAM, SKY)
    rs = RenderSettings(width=4, height=4, spp=1, max_depth=4, integrator="volpath")
    ones = np.ones((4, 4, 3))
    with pytest.raises(ValueError, match="scattering is 0"):        # a channel without scattering
        render_gradients(params, rs, adjoint=ones, wrt=["cloud.medium_sigma_s"])
    with pytest.raises(ValueError, match="tape"):
        render_gradients(params, rs, adjoint=ones, wrt=["cloud.medium_g"], mode="tape")
    with pytest.raises(ValueError, match="volpath"):
        render_gradients(params, RenderSettings(width=4, height=4, spp=1, integrator="nee"), adjoint=ones,
                         wrt=["cloud.medium_g"], mode="prb")


def test_furnace_gradients_vanish(scene_dir):
    """Albedo 1 under a uniform sky: the image is 1 whatever g and sigma_s (test_volumes' furnace), so
    their gradients are 0: per seed, the mean over seeds within T_PAIRED standard errors, and the
    standard error small against the gradients of an absorbing ball (so the test can fail)."""
    from tests.media.test_volumes import BALL_CAM, UNIFORM, _ball
    dev = _ball(scene_dir, "furnace", (1.0, 3.0, 0.3), g=0.5)
    params = parameters(dev, BALL_CAM, UNIFORM)
    ones = np.ones((SIZE, SIZE, 3))
    names = ["m.medium_g", "m.medium_sigma_s", "m.medium_sigma_a"]
    runs = []
    for seed in range(1, SEEDS + 1):
        rs = RenderSettings(width=SIZE, height=SIZE, spp=64, max_depth=64, seed=seed, integrator="volpath", sky=UNIFORM)
        g = render_gradients(params, rs, adjoint=ones, wrt=names).grads
        runs.append(np.concatenate([[float(g[names[0]])], g[names[1]], g[names[2]]]))
    runs = np.asarray(runs)
    mean, se = runs.mean(0), runs.std(0, ddof=1) / math.sqrt(SEEDS)
    print("\nfurnace gradients (g, sigma_s, sigma_a):", mean, "+-", se)
    assert np.all(np.abs(mean[:4]) < T_PAIRED * se[:4]), (mean, se)
    # absorption darkens the ball: clearly negative, and the zero tests above are resolved against it
    assert np.all(mean[4:] < -T_PAIRED * se[4:]), (mean, se)
    assert np.all(se[:4] < 0.25 * np.abs(mean[4:]).min()), (mean, se)
