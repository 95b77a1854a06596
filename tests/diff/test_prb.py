"""Path-replay backpropagation (warp_spt.diff.prb) against independent references.

* The tape (Warp's adjoint of the step unrolled to the depth) computes the same derivative another
  way: the two agree to float32 rounding for every replayable kind, including roughness (score
  term), except roughness under NEE: the tape differentiates the MIS weights (through the diffuse
  density), path replay holds them constant, and the two agree in expectation (over seeds, within
  4 standard errors of their paired difference).
* Depth 12 (beyond the tape's 8): central finite differences of the fast renderer with common random
  numbers, for colours, emission and the sky colour.
* NEE runs with the independent sampler, the default (tests/diff/test_param_gradients.py has NEE + Sobol).
* NEE: emission and sky colour re-weight the light table, so finite differences move the light
  samples; with the table frozen they measure the derivative path replay computes (detached sampling).
* Memory (array sizes, not wall time) does not grow with spp or depth; 1 and 2 threads agree bit for bit.
* Russian roulette: the mean over seeds against finite differences of the roulette-free renderer.
* A colour channel at exactly 0: the documented limit (no gradient from later bounces), shown
  against one-sided finite differences.

Parameters with a pathwise derivative (fuzz) take path replay's pathwise kernel (``mode="auto"`` too),
checked against the tape here and in tests/diff/test_replay_pathwise.py.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import warp as wp

from warp_spt.emitters import alias_parameters, light_table, table_key
from warp_spt.diff.gradients import render_gradients
from warp_spt.diff.params import parameters
from warp_spt.scene.sky import Sky

from tests.diff.test_gradients import CAM as ROOM_CAM
from tests.diff.test_gradients import room  # noqa: F401  (fixture)
from tests.diff.test_param_gradients import (
    QUAD_CAM,
    QUAD_RS,
    ROOM_RS,
    ROOM_SKY,
    _fd,
    _image_sum,
    _ones,
    quad_scene,  # noqa: F401  (fixture)
)

COLOURS = ["wall.diffuse", "ball.diffuse", "wall.reflect"]
SEED_NAMES = COLOURS + ["lamp.emission", "sky.color", "wall.roughness", "ball.roughness"]
NEE = dict(integrator="nee", sampler="independent")     # the default estimator


@pytest.mark.parametrize("estimator", [{}, NEE, dict(NEE, roulette_depth=1)], ids=["seed", "nee", "nee-roulette"])
def test_path_replay_equals_the_tape(room, estimator):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    rs = replace(ROOM_RS, **estimator)
    prb = render_gradients(p, rs, adjoint=_ones(rs), wrt=SEED_NAMES, mode="prb")
    tape = render_gradients(p, rs, adjoint=_ones(rs), wrt=SEED_NAMES, mode="tape")
    assert (prb.mode, tape.mode) == ("prb", "tape")
    # path replay's first pass gives the image (no forward render), the tape takes the fast renderer's:
    # the same sums, bit for bit, also where the adjoint is 0 (no replay there, the image still summed)
    assert prb.forward_seconds == 0.0 and tape.forward_seconds > 0.0
    assert np.array_equal(prb.image, tape.image)
    half = _ones(rs)
    half[: rs.height // 2] = 0.0
    assert np.array_equal(render_gradients(p, rs, adjoint=half, wrt=COLOURS, mode="prb").image, tape.image)
    exact = [n for n in SEED_NAMES if "roughness" not in n or not estimator]
    for n in SEED_NAMES:
        assert np.any(np.abs(tape.grads[n]) > 1e-2), n
    for n in exact:
        np.testing.assert_allclose(prb.grads[n], tape.grads[n], rtol=2e-4, atol=1e-4, err_msg=n)
    if len(exact) < len(SEED_NAMES):
        _assert_same_expectation(p, rs, [n for n in SEED_NAMES if n not in exact])


def _assert_same_expectation(p, rs, names, seeds: int = 16):
    """Path replay and the tape, with the same seeds, differ by the MIS weights' derivative terms,
    whose expectation is 0: the mean paired difference is within 4 of its standard errors, which are
    small against the gradient (so that a missing or doubled term would fail)."""
    diff = {n: [] for n in names}
    tape = {n: [] for n in names}
    for s in range(seeds):
        r = replace(rs, seed=1000 + s)
        a = render_gradients(p, r, adjoint=_ones(r), wrt=names, mode="prb").grads
        b = render_gradients(p, r, adjoint=_ones(r), wrt=names, mode="tape").grads
        for n in names:
            diff[n].append(float(a[n]) - float(b[n]))
            tape[n].append(float(b[n]))
    for n in names:
        d = np.array(diff[n])
        se = d.std(ddof=1) / np.sqrt(seeds)
        assert np.any(d != 0.0), n                       # the weights' terms were there to drop
        assert abs(d.mean()) < 4 * se, (n, d.mean(), se)
        assert abs(np.mean(tape[n])) > 10 * se, (n, np.mean(tape[n]), se)


@pytest.mark.parametrize("estimator,names", [({}, COLOURS + ["lamp.emission", "sky.color"]), (NEE, COLOURS)],
                         ids=["seed", "nee"])
def test_depth_beyond_the_tape_matches_finite_differences(room, estimator, names):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    rs = replace(ROOM_RS, max_depth=12, **estimator)
    r = render_gradients(p, rs, adjoint=_ones(rs), wrt=names)
    assert r.mode == "prb"
    shallow = render_gradients(p, replace(rs, max_depth=3), adjoint=_ones(rs), wrt=names)
    for n in names:
        assert np.all(r.grads[n] > shallow.grads[n]), n     # the deeper bounces count
        for c in range(3):
            fd = _fd(p, rs, n, c, 1e-2)
            assert r.grads[n][c] == pytest.approx(fd, rel=2e-3, abs=1e-3), (n, c)


def _frozen_fd(p, rs, name: str, c: int, h: float) -> float:
    """Central difference with the light table (choice probabilities, sky sampling) of the current
    values: the light samples stay where they are, as path replay assumes."""
    dev = p.scene
    base = light_table(dev, p.sky, p.camera.up)
    v0 = p[name].copy()
    out = []
    for s in (h, -h):
        v = v0.copy()
        v[c] += s
        p[name] = v                     # clears the cached tables and the Features
        # the sky's colours (its array, vec3d; other kinds' parameter arrays stay as they are)
        colors = ((lambda a: wp.array(np.array([p.sky.color]), dtype=wp.vec3d) if a.dtype == wp.vec3d else a)
                  if name == "sky.color" else None)
        frozen = alias_parameters(base, colors or (lambda a: a))     # the sky's colours as they are now
        dev.light_cache(table_key(p.sky, p.camera.up), lambda: frozen)   # the cache was cleared above
        out.append(_image_sum(p, rs))
    p[name] = v0
    return (out[0] - out[1]) / (2 * h)


def test_nee_emission_and_sky_gradients_with_the_light_table_frozen(room):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    rs = replace(ROOM_RS, **NEE)
    names = ["lamp.emission", "sky.color"]
    r = render_gradients(p, rs, adjoint=_ones(rs), wrt=names)
    for n in names:
        for c in range(3):
            fd = _frozen_fd(p, rs, n, c, 1e-2)
            assert abs(fd) > 1e-2
            assert r.grads[n][c] == pytest.approx(fd, rel=2e-3, abs=1e-3), (n, c)


def test_backward_memory_grows_with_neither_spp_nor_depth(room):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    sizes = {(spp, depth): render_gradients(p, replace(ROOM_RS, spp=spp, max_depth=depth), adjoint=_ones(ROOM_RS),
                                            wrt=["wall.diffuse"], mode="prb").backward_bytes
             for spp in (1, 16) for depth in (2, 12)}
    assert len(set(sizes.values())) == 1 and sizes[(1, 2)] > 0, sizes


def test_deep_gradients_are_identical_on_one_and_two_threads(room):
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    rs = replace(ROOM_RS, max_depth=12)
    one = render_gradients(p, replace(rs, threads=1), adjoint=_ones(rs), wrt=SEED_NAMES)
    two = render_gradients(p, replace(rs, threads=2), adjoint=_ones(rs), wrt=SEED_NAMES)
    assert one.threads == 1 and two.threads == 2 and one.mode == two.mode == "prb"
    for n in SEED_NAMES:
        assert np.array_equal(one.grads[n], two.grads[n]), n


def test_mode_selection(quad_scene):
    p = parameters(quad_scene, QUAD_CAM, Sky.gradient())
    adj = _ones(QUAD_RS)
    assert render_gradients(p, QUAD_RS, adjoint=adj, wrt=["quad.diffuse_map"]).mode == "prb"
    assert render_gradients(p, QUAD_RS, adjoint=adj, wrt=["quad.fuzz", "quad.diffuse"]).mode == "prb"
    # fuzz bends the sampled direction: path replay takes it with its pathwise kernel, the tape's values
    tape = render_gradients(p, QUAD_RS, adjoint=adj, wrt=["quad.fuzz"], mode="tape")
    pw = render_gradients(p, QUAD_RS, adjoint=adj, wrt=["quad.fuzz"], mode="prb")
    assert pw.mode == "prb" and abs(float(tape.grads["quad.fuzz"])) > 1e-4
    np.testing.assert_allclose(pw.grads["quad.fuzz"], tape.grads["quad.fuzz"], rtol=1e-3, atol=1e-6)
    with pytest.raises(ValueError, match="unknown gradient mode"):
        render_gradients(p, QUAD_RS, adjoint=adj, wrt=["quad.diffuse"], mode="fast")
    with pytest.raises(ValueError, match="tape"):
        render_gradients(p, replace(QUAD_RS, max_depth=9), adjoint=adj, wrt=["quad.diffuse"], mode="tape")


def test_russian_roulette_is_replayed_with_an_unbiased_gradient(room):
    """Roulette from the first hit (nee, depth 6). Path replay redraws the same survival decisions and
    holds the survival probability ``q`` constant: on survival the sample is ``X / q``, so its
    derivative ``X' / q`` has expectation ``X'``, the derivative of the expected image (differentiating
    ``1 / q`` as well would add ``-X q' / q`` on average). Roulette leaves the expected image as it is,
    so the reference is central finite differences of the fast renderer *without* roulette (CRN: the
    difference is smooth); finite differences with roulette flip survival decisions as the throughput
    moves, far noisier. Over 24 seeds, the mean of (gradient - difference) must be within 4 standard
    errors of 0, and the derivative large against that error."""
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    rs = replace(ROOM_RS, max_depth=6, roulette_depth=1, **NEE)
    name = "wall.diffuse"
    diffs, grads = [], []
    for seed in range(24):
        r = replace(rs, seed=100 + seed)
        g = render_gradients(p, r, adjoint=_ones(r), wrt=[name]).grads[name]
        fd = np.array([_fd(p, replace(r, roulette_depth=0), name, c, 1e-2) for c in range(3)])
        grads.append(g)
        diffs.append(g - fd)
    diffs, grads = np.array(diffs), np.array(grads)
    mean, se = diffs.mean(0), diffs.std(0, ddof=1) / np.sqrt(len(diffs))
    print("roulette: gradient", grads.mean(0), "gradient - FD", mean, "+-", se)
    assert np.all(np.abs(mean) < 4 * se), (mean, se)
    assert np.all(grads.mean(0) > 20 * se), (grads.mean(0), se)


def test_a_colour_channel_at_zero_misses_the_gradient_of_later_bounces(room):
    """A documented limit (docs/gradients.md, Limits): ``wall.diffuse`` green at exactly 0, seed
    integrator, so every contribution of a path through the wall comes from a later bounce. Its
    derivative (the light arriving at the wall) is nonzero by a second-order one-sided difference of
    the fast renderer (CRN; the colour cannot go negative), but path replay's Lo = (L - R) / T is
    unknown where T's channel is 0 and it gives exactly 0; a channel just above 0 is exact."""
    p = parameters(room, ROOM_CAM, ROOM_SKY)
    name = "wall.diffuse"
    v0 = p[name].copy()
    try:
        grads = {}
        for g0 in (0.0, 1e-3):
            p[name] = np.array([v0[0], g0, v0[2]])
            grads[g0] = render_gradients(p, ROOM_RS, adjoint=_ones(ROOM_RS), wrt=[name]).grads[name][1]
        h, sums = 1e-2, []
        for s in (0.0, 1e-2, 2e-2):
            p[name] = np.array([v0[0], s, v0[2]])
            sums.append(_image_sum(p, ROOM_RS))
    finally:
        p[name] = v0
    fd = (-3 * sums[0] + 4 * sums[1] - sums[2]) / (2 * h)
    assert fd > 1.0
    assert grads[0.0] == 0.0
    assert grads[1e-3] == pytest.approx(fd, rel=2e-2)
