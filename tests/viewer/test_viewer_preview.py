"""The moving preview (issue 43, item 8): at the samples (the time) the 1/4-size 1-spp preview took,
the session renders fewer pixels with more samples, and the picture the page draws is closer to the
converged view. The full measurement: scripts/measure_viewer_preview.py (docs/viewer.md)."""

from __future__ import annotations

import threading
from dataclasses import replace

import numpy as np
import pytest

from warp_spt.viewer.session import PREVIEW_PIXELS_PER_SAMPLE, ViewSettings, preview_plan

from tests.support.preview_error import Reference, plan_error


def test_the_default_preview_spends_the_samples_of_the_old_one_on_fewer_pixels():
    s = ViewSettings(width=384, height=288)
    assert preview_plan(s) == (48, 36, 4)
    assert preview_plan(replace(s, preview_scale=4)) == (96, 72, 1)        # the old preview, same samples
    for scale in (4, 8, 16):
        w, h, spp = preview_plan(replace(s, preview_scale=scale))
        assert w * h * spp == s.width * s.height // PREVIEW_PIXELS_PER_SAMPLE


def test_a_slow_machine_shrinks_the_preview_and_keeps_its_spp():
    s = ViewSettings(width=384, height=288)
    budget = s.width * s.height / PREVIEW_PIXELS_PER_SAMPLE / 3           # a third of the samples render in time
    w, h, spp = preview_plan(s, budget)
    assert spp == 4 and w * h * spp <= budget * 1.05 and (w, h) == (28, 21)
    assert preview_plan(s, 1.0)[:2] == (24, 18)                            # at most half the size per side
    assert preview_plan(ViewSettings(width=32, height=24)) == (11, 8, 1)   # no side below 8 pixels


@pytest.mark.slow
def test_the_default_preview_is_closer_to_the_converged_view_at_equal_samples():
    """The demo at 128 x 96 (a small view favours the finer preview: each of its pixels covers more of
    the scene), 6 seeds per plan; the RMS error of the shown picture with the reference's noise taken
    off. The default's size and spp must beat the 1/4-size 1-spp preview, and the 3x3 median the page's
preview is drawn through must lower it further, each by over 4 standard errors."""
    import warp_spt
    from warp_spt.demo import demo_files
    from warp_spt.scene.camera import Camera
    from warp_spt.upload.device_scene import DeviceScene

    objs, mtls = demo_files()
    dev = DeviceScene(warp_spt.load_scene(objs, mtls, default_material="auto"))
    s = ViewSettings(width=128, height=96)
    common = dict(max_depth=s.max_depth, sky=warp_spt.Sky.black(), integrator=s.integrator, sampler=s.sampler)
    reference = Reference(dev, Camera(), (s.width, s.height), 32, s.tonemap, **common)
    rows = {}
    for scale in (4, s.preview_scale):
        w, h, spp = preview_plan(replace(s, preview_scale=scale))
        rows[scale] = plan_error(dev, Camera(), reference, (w, h), spp, 6, **common)
    old, new = rows[4], rows[s.preview_scale]
    assert old["samples"] == new["samples"]
    assert old["raw"] - new["raw"] > 4 * np.hypot(old["raw_se"], new["raw_se"]), rows      # the size and spp
    assert new["raw"] - new["shown"] > 4 * new["raw_se"], rows                               # the filter


def test_the_preview_filter_takes_out_lone_pixels_and_keeps_edges():
    from warp_spt.viewer.display import despeckled

    rgb = np.zeros((12, 16, 3), np.uint8)
    rgb[:, 8:] = 200                         # an edge
    rgb[3, 3] = 255                          # a path that found the light
    rgb[6, 12] = 0                           # one that found nothing
    out = despeckled(rgb)
    want = np.zeros_like(rgb)
    want[:, 8:] = 200
    assert np.array_equal(out, want)


def test_the_session_draws_previews_through_the_filter_and_refined_images_without_it(monkeypatch):
    from warp_spt.viewer import display
    from warp_spt.viewer import session as session_module

    seen = []
    monkeypatch.setattr(display, "despeckled", lambda rgb: seen.append(rgb.shape) or rgb)
    s = session_module.Session.__new__(session_module.Session)     # no scene, no render thread: _redraw only
    s._settings, s._listeners, s._cond = ViewSettings(), [], threading.Condition()
    for mode in ("preview", "refine"):
        s._shown = session_module._Shown(np.full((6, 8, 3), 0.5, np.float32), None, {"mode": mode})
        s._redraw()
    assert seen == [(6, 8, 3)]
