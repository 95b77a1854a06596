"""Efficiency-aware roulette and splitting (issue 24, part 3): the ``ears`` integrator.

* Converges to the same image as ``nee`` (per-block Student t over seeds, the house style of
  tests/integrators/test_light_transport.py) on the Cornell box with its glass and glossy balls: with the
  learnt factors, and with them scaled so that nearly every decision splits (up to the stack's
  cap) or nearly every one is roulette: both halves of the estimator are unbiased.
* Determinism: the same image bit for bit on 1 and 2 threads and other tile sizes; the spp budget
  (training included) is respected; renderers that cannot learn over the whole image refuse it.
* The host's table: cells without enough records make no decision; absolute mode ignores the pixels.
"""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.integrators import ears
from warp_spt.rendering.settings import RenderSettings

from tests.support.stability_scenes import R, assert_same_image, cornell_camera, cornell_files, load, sky

SIZE, SPP, SEEDS = 16, 16, 10


@pytest.fixture(scope="module")
def cornell(scene_dir):
    return load(*cornell_files(scene_dir))


def _options(factor: float = 1.0) -> dict:
    """Options that let cells with few records decide (a 16x16 image trains on few paths) and
    multiply every learnt factor by ``factor`` (the factors go as 1 / sqrt(V): ``v_scale``)."""
    return {"min_records": 2, "v_scale": 1.0 / factor ** 2}


def _render(dev, **kw) -> "R.RenderResult":
    kw = {"width": SIZE, "height": SIZE, "spp": SPP, "max_depth": 5, "sky": sky(0.0), **kw}
    res = R.render_scene(dev, cornell_camera(), RenderSettings(**kw))
    assert res.stats.dropped_samples == 0
    return res


@pytest.fixture(scope="module")
def nee_images(cornell):
    return np.stack([_render(cornell, integrator="nee", seed=500 + k).image for k in range(SEEDS)])


@pytest.mark.parametrize("factor", [1.0, 50.0, 0.02], ids=["learnt", "split", "roulette"])
def test_ears_converges_to_the_same_image_as_nee(cornell, nee_images, factor):
    out = [_render(cornell, integrator="ears", seed=700 + k, integrator_options=_options(factor)) for k in range(SEEDS)]
    assert_same_image(nee_images, np.stack([r.image for r in out]), f"ears x{factor} vs nee")
    rays = np.mean([r.stats.rays for r in out])
    base = _render(cornell, integrator="nee", seed=700).stats.rays
    if factor > 1:
        assert rays > 1.5 * base          # it did split
    elif factor < 1:
        assert rays < 0.9 * base          # it did roulette


def test_ears_is_deterministic_and_keeps_the_budget(cornell):
    opts = _options(3.0)                  # splits and roulette both
    one = _render(cornell, integrator="ears", threads=1, spp=12, integrator_options=opts)
    two = _render(cornell, integrator="ears", threads=2, spp=12, tile_pixels=40, integrator_options=opts)
    assert np.array_equal(one.film.sum, two.film.sum)
    assert one.stats.rays == two.stats.rays
    assert one.film.spp == 12 and one.stats.pixel_samples == SIZE * SIZE * 12
    # the decisions are used: the training samples alone are nee's, the rest differ
    nee = _render(cornell, integrator="nee", threads=1, spp=12)
    assert not np.array_equal(one.film.sum, nee.film.sum)
    # below 2 x train_fraction spp nothing is learnt: nee's image
    assert np.array_equal(_render(cornell, integrator="ears", spp=7).film.sum,
                          _render(cornell, integrator="nee", spp=7).film.sum)


def test_schedule_and_table():
    assert ears.schedule(7) == (0, 0, 7) and ears.schedule(16) == (2, 2, 12) and ears.schedule(64) == (8, 8, 48)
    assert all(sum(ears.schedule(n)) == n for n in range(1, 200))
    assert ears.schedule(64, {"train_fraction": 8}) == (4, 4, 56)
    # five bounces of one cell each (grid 1)
    counts = np.array([0, 1, 100, 100, 100], np.int64)
    m2 = (np.array([0.0, 1.0, 0.0, 1.0, 4.0]) * counts * ears.S2).astype(np.int64)
    cost = np.array([0, 1, 200, 200, 800], np.int64)
    a, b = np.full((4, 3), 2.0 * 2), np.full((4, 3), 3.0 * 2)     # halves of 2 samples: means 2 and 3
    for rel in (False, True):
        opts = {"grid": 1, "global_floor": 0.0, "relative": rel}
        s, pix_inv, info = ears.learn(counts, m2, cost, a, b, 2, 2, 6.0 * 4 * 4, (2, 2), opts)
        assert (s[:2] == -1).all() and s[2] == 0          # too few records: no decision; no light: roulette
        assert info["C"] == 6.0 and s[3] > 0 and np.isclose(s[4], s[3])     # 4x the moment at 4x the cost
        assert np.isclose(info["V"], 1.0 / (6.25 if rel else 1.0))         # (3 - 2)^2 x 2 x 2 / 4, over P^2
        assert np.allclose(pix_inv, 0.4 if rel else 1.0)
    # the floor: a cell's moment at least its bounce's mean over all cells (one bounce of 2^3 cells)
    counts, cost = np.full(8, 100, np.int64), np.full(8, 200, np.int64)
    m2 = (np.array([0.0] + [1.0] * 7) * counts * ears.S2).astype(np.int64)
    args = (m2, cost, a, b, 2, 2, 96.0, (2, 2))
    assert ears.learn(counts, *args, {"grid": 2, "global_floor": 0.0})[0][0] == 0
    s, _, _ = ears.learn(counts, *args, {"grid": 2})                  # the default floor, 1
    assert np.isclose(s[0], np.sqrt(7 / 8) * s[1])


def test_renderers_that_split_the_image_refuse_ears(cornell):
    with pytest.raises(ValueError, match="whole image"):
        R.render_scene(cornell, cornell_camera(), RenderSettings(width=8, height=8, spp=4, integrator="ears"),
                       rows=(0, 4))
