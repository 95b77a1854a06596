"""Named parameters and render_gradients: every parameter kind against an independent reference.

* Colours, emission, texels, sky colour: with common random numbers (CRN) the sampled paths do not
  depend on them, so the image is a low-degree polynomial in them and central finite differences of
  the fast renderer agree with the gradient to float32 rounding.
* Fuzz: a continuous (pathwise) derivative, checked against CRN finite differences in a scene with
  no silhouette and no absorbed direction.
* Roughness: the lobe choice is discrete, so the check is against the derivative of the *expected*
  image, with a tolerance from the estimated standard errors of both sides.
* Threads: gradients bit-identical with 1 and 2 threads. Memory: what the backward pass allocates
  does not depend on spp.

Kernels compile once per (features, depth): the room (depth 3) and the quad (depth 2).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from PIL import Image

from warp_spt import losses
from warp_spt.diff.check import check_gradients
from warp_spt.diff.gradients import render_gradients
from warp_spt.diff.params import parameters
from warp_spt.io.loader import load_scene
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

from tests.support.scenes import material, quad_obj, write_scene_files
from tests.diff.test_gradients import CAM as ROOM_CAM
from tests.diff.test_gradients import room  # noqa: F401  (fixture)

ROOM_SKY = Sky.constant(0.4, 0.5, 0.6)
ROOM_RS = RenderSettings(width=10, height=8, spp=4, max_depth=3, seed=11, tile_pixels=16,
                         integrator="seed")
QUAD_CAM = Camera(position=(0.1, -0.2, 2.0), direction=(0.05, 0.1, -1.0), fov=60.0, aperture=0.0, focus=2.0)
QUAD_RS = RenderSettings(width=8, height=8, spp=8, max_depth=2, seed=3, texture_filter="bilinear",
                         integrator="seed")


@pytest.fixture(scope="module")
def quad_scene(scene_dir):
    """A 4x4-textured glossy quad filling the view under the gradient sky (no silhouettes)."""
    rng = np.random.default_rng(5)
    tex = (rng.uniform(0.2, 0.9, (4, 4, 3)) * 255).astype(np.uint8)
    folder = scene_dir / "quadgrad"
    folder.mkdir(exist_ok=True)
    Image.fromarray(tex).save(folder / "tex.png")
    mtl = material("quad", Kd=(1, 1, 1), map_Kd="tex.png", Roughness=0.5, Fuzz=0.2)
    obj = quad_obj([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)])
    return load_scene(*write_scene_files(folder, "quad", obj, mtl))


def _image_sum(params, rs) -> float:
    return float(render_scene(params.scene, params.camera, replace(rs, sky=params.sky)).film.image()
                 .astype(np.float64).sum())


def _fd(params, rs, name: str, index, h: float) -> float:
    """Central difference of the image sum in one component of a named parameter (CRN)."""
    v0 = params[name].copy()
    out = []
    try:
        for s in (h, -h):
            v = v0.copy()
            v[index] += s
            params[name] = v
            out.append(_image_sum(params, rs))
    finally:
        params[name] = v0
    return (out[0] - out[1]) / (2 * h)


def _assert_colours_match_fd(params, rs, names, least: float, abs_tol: float) -> None:
    """Each colour channel of each parameter in ``names``: a gradient of at least ``least`` in
    magnitude (not vacuous) that equals the central difference (step 1e-2, the render's own seed:
    the same paths, check_gradients) within rel 2e-3 + ``abs_tol``."""
    r = check_gradients(params, rs, adjoint=_ones(rs), wrt=names, seeds=[rs.seed], step=1e-2, rtol=2e-3,
                        atol=abs_tol, print_table=False)
    assert [row.direction for row in r.rows] == ["[0]", "[1]", "[2]"] * len(names)
    for row in r.rows:
        assert abs(row.gradient) > least, row
        assert row.verdict == "agree", r.table()


def _ones(rs):
    return np.ones((rs.height, rs.width, 3))


# --- names, values, losses --------------------------------------------------------------------

def test_parameter_names_and_validation(room, quad_scene):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    for n in ("wall.diffuse", "ball.roughness", "wall.fuzz", "lamp.emission", "sky.color", "camera.position",
              "camera.direction"):
        assert n in p
    assert p["wall.diffuse"] == pytest.approx([0.6, 0.5, 0.4])
    q = parameters(quad_scene, QUAD_CAM, Sky.gradient())
    assert q["quad.diffuse_map"].shape == (4, 4, 3) and "sky.color" not in q
    for name, bad in [("wall.roughness", 1.5), ("wall.diffuse", (-0.1, 0, 0)), ("wall.diffuse", (np.nan, 0, 0)),
                      ("wall.diffuse", (1, 2)), ("camera.direction", (0, 0, 0))]:
        with pytest.raises(ValueError):
            p[name] = bad
    with pytest.raises(KeyError, match="no parameter"):
        p["nope.diffuse"]


def test_setting_a_value_changes_the_render(room):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    before = _image_sum(p, ROOM_RS)
    p["wall.diffuse"] = (0.9, 0.5, 0.4)
    after = _image_sum(p, ROOM_RS)
    p["wall.diffuse"] = (0.6, 0.5, 0.4)
    assert after > before and _image_sum(p, ROOM_RS) == before


@pytest.mark.parametrize("make", [losses.l1, losses.l2])
def test_loss_adjoints_match_finite_differences(make):
    rng = np.random.default_rng(0)
    target, image = rng.uniform(size=(2, 3, 4, 3))
    loss = make(target)
    value, adj = loss(image)
    assert value == pytest.approx(np.mean(np.abs(image - target)) if make is losses.l1
                                  else np.mean((image - target) ** 2))
    e = np.zeros_like(image)
    e[1, 2, 0] = 1e-6
    assert adj[1, 2, 0] == pytest.approx((loss(image + e)[0] - loss(image - e)[0]) / 2e-6, rel=1e-4)
    with pytest.raises(ValueError):
        loss(image[:2])


# --- the room: colours, emission, sky, both integrators, threads, memory ----------------------------

@pytest.mark.parametrize("integrator,sampler,names", [
    ("seed", "independent", ["wall.diffuse", "ball.diffuse", "wall.reflect", "lamp.emission", "sky.color"]),
    # NEE: the light table's choice weights follow emission and sky power, so CRN differences of those
    # would also move the sampling; the colours below leave the table unchanged.
    ("nee", "sobol", ["wall.diffuse", "ball.diffuse", "wall.reflect"]),
    # refused until the in-place write of p.sampler after light sampling was found (nee vertex copy)
    ("nee", "independent", ["wall.diffuse", "ball.diffuse", "wall.reflect"]),
])
def test_colour_gradients_match_finite_differences(room, integrator, sampler, names):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    rs = replace(ROOM_RS, integrator=integrator, sampler=sampler)
    _assert_colours_match_fd(p, rs, names, least=1e-3, abs_tol=1e-3)


def test_loss_gradient_is_the_adjoint_weighted_one(room):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    target = np.full((ROOM_RS.height, ROOM_RS.width, 3), 0.3)
    r = render_gradients(p, ROOM_RS, loss=losses.l2(target), wrt=["wall.diffuse"])
    v = p["wall.diffuse"].copy()
    h = 1e-2
    vals = []
    for s in (h, -h):
        p["wall.diffuse"] = v + np.array([s, 0, 0])
        vals.append(losses.l2(target)(render_scene(p.scene, p.camera, replace(ROOM_RS, sky=p.sky)).image)[0])
    p["wall.diffuse"] = v
    assert r.loss == pytest.approx(losses.l2(target)(r.image)[0])
    assert r.grads["wall.diffuse"][0] == pytest.approx((vals[0] - vals[1]) / (2 * h), rel=1e-2)


def test_gradients_are_identical_on_one_and_two_threads(room):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    names = ["wall.diffuse", "wall.roughness", "lamp.emission", "sky.color", "camera.position"]
    one = render_gradients(p, replace(ROOM_RS, threads=1), adjoint=_ones(ROOM_RS), wrt=names)
    two = render_gradients(p, replace(ROOM_RS, threads=2), adjoint=_ones(ROOM_RS), wrt=names)
    assert one.tiles == 5 and one.threads == 1 and two.threads == 2
    for n in names:
        assert np.array_equal(one.grads[n], two.grads[n]), n


def test_backward_memory_does_not_grow_with_spp(room):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    sizes = {spp: render_gradients(p, replace(ROOM_RS, spp=spp), adjoint=_ones(ROOM_RS),
                                   wrt=["wall.diffuse"]).backward_bytes for spp in (1, 16)}
    assert sizes[1] == sizes[16] > 0


# --- the quad: texels, fuzz, roughness (camera: test_param_gradients2.py) -------------------------------------------------

@pytest.mark.parametrize("texture_filter", ["nearest", "bilinear"])
def test_texel_gradients_match_finite_differences(quad_scene, texture_filter):
    p = parameters(quad_scene, QUAD_CAM, Sky.gradient())
    rs = replace(QUAD_RS, texture_filter=texture_filter)
    g = render_gradients(p, rs, adjoint=_ones(rs), wrt=["quad.diffuse_map"]).grads["quad.diffuse_map"]
    assert g.shape == (4, 4, 3)
    seen = np.argwhere(np.abs(g[..., 0]) > 1e-3)
    assert len(seen) >= 4           # the view covers several texels
    for (i, j) in seen[:3]:
        fd = _fd(p, rs, "quad.diffuse_map", (i, j, 0), 1e-2)
        assert g[i, j, 0] == pytest.approx(fd, rel=2e-3, abs=1e-3)


def test_fuzz_gradient_matches_finite_differences(quad_scene):
    """Pathwise, through the fuzzed mirror direction into the gradient sky; the view is steep, so no
    fuzzed direction dips below the quad (absorption would be a step). FD with the render's seed (the
    same paths: CRN), h = 1e-3, within 2%."""
    p = parameters(quad_scene, QUAD_CAM, Sky.gradient())
    (row,) = check_gradients(p, QUAD_RS, adjoint=_ones(QUAD_RS), wrt=["quad.fuzz"], seeds=[QUAD_RS.seed], step=1e-3,
                             rtol=0.02, print_table=False).rows
    assert abs(row.gradient) > 0.1 and row.scheme == "central"
    assert row.verdict == "agree", row


def test_roughness_gradient_is_the_derivative_of_the_expected_image(quad_scene):
    """On this quad (one bounce, then the sky) E[image] = r D + (1 - r) S exactly, so d E / d r =
    E[image | r=1] - E[image | r=0], estimated with independent seeds. The gradient (score-weighted
    lobe choice) is averaged over seeds too; both standard errors set the tolerance (4 sigma)."""
    p = parameters(quad_scene, QUAD_CAM, Sky.gradient())
    feats = p.scene.features
    rs = replace(QUAD_RS, spp=1024)       # the score term is noisy: about 12x the variance of the image
    ad = np.array([render_gradients(p, replace(rs, seed=s), adjoint=_ones(rs), wrt=["quad.roughness"])
                   .grads["quad.roughness"] for s in range(8)], dtype=np.float64)
    ref = []
    for s in range(8):
        ends = []
        for r in (1.0, 0.0):
            p["quad.roughness"] = r
            ends.append(_image_sum(p, replace(rs, seed=100 + s, spp=64, features=feats)))
        ref.append(ends[0] - ends[1])
    p["quad.roughness"] = 0.5
    ref = np.array(ref)
    se = np.sqrt(ad.var(ddof=1) / len(ad) + ref.var(ddof=1) / len(ref))
    assert abs(ref.mean()) > 8 * se           # the derivative is resolved: the test can fail
    assert abs(ad.mean() - ref.mean()) < 4 * se, (ad, ref)
