"""The viewer's Session without a browser (issue 23): refining, cancelling, settings, materials,
picking, saving, scene errors, and the copied command line against the real command line.

The built-in demo at a few dozen pixels: its kernels are the command line's, compiled once.
"""

from __future__ import annotations

import math
import os
import shlex
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

import warp_spt
from warp_spt.demo import demo_files
from warp_spt.viewer import session as session_module
from warp_spt.viewer.session import Session, open_session

from tests.support.scenes import box_obj, material, write_scene_files
from tests.support.stability_scenes import block_means, t_quantile

W, H = 32, 24
TIMEOUT = 600          # seconds: a cold kernel cache compiles first (no timing is asserted)


@pytest.fixture(scope="module")
def demo_scene():
    objs, mtls = demo_files()
    return warp_spt.load_scene(objs, mtls, default_material="auto")


@pytest.fixture
def session(demo_scene):
    s = Session(demo_scene, width=W, height=H, max_spp=64)   # 64: a whole number of rounds
    yield s
    s.close()


class Inbox:
    """Collects the messages a session sends (as a front end would receive them)."""

    def __init__(self):
        self.messages: list[tuple[dict, list]] = []
        self.lock = threading.Lock()

    def __call__(self, message, buffers):
        with self.lock:
            self.messages.append((message, list(buffers)))

    def of(self, kind: str) -> list[tuple[dict, list]]:
        with self.lock:
            return [m for m in self.messages if m[0]["type"] == kind]


def assert_same_view(result, other: np.ndarray, other_spp: int, block: int = 4, alpha: float = 1e-4) -> None:
    """The viewer's refined image and ``other`` (one render of ``other_spp`` samples per pixel)
    agree block by block within a Student-t bound (Bonferroni over blocks and channels).

    The viewer's K batches are equal in size and independent, so the spread of their block means
    estimates the error of the viewer's image with K - 1 degrees of freedom. ``other``'s error is
    taken as a batch mean's scaled by batch size / ``other_spp`` (1/spp convergence), which
    over-states it for a low-discrepancy sampler: a conservative bound."""
    counts = result.counts[:, 0, 0]
    assert np.all(counts == counts[0]), f"unequal batches {counts}: compare after a whole round"
    k, per_batch = len(counts), int(counts[0])
    batch = block_means(result.sums / per_batch, block)                                 # (k, blocks, 3)
    mean = batch.mean(axis=0)
    var_batch = batch.var(axis=0, ddof=1)                                               # of one batch's mean
    se = np.sqrt(var_batch / k + var_batch * per_batch / other_spp)
    diff = mean - block_means(other[None].astype(np.float64), block)[0]
    exact = se <= 1e-12                         # constant blocks (sky): must agree to rounding
    assert np.all(np.abs(diff[exact]) <= 1e-5 * np.abs(mean[exact]) + 1e-6), "constant blocks differ"
    z = np.abs(diff[~exact]) / se[~exact]
    bound = t_quantile(alpha / (2 * max(z.size, 1)), k - 1)
    assert z.size == 0 or z.max() <= bound, f"worst block |t| = {z.max():.2f}, bound {bound:.2f} ({k} batches)"


def run_command(text: str, out: Path) -> np.ndarray:
    """Run a copied ``warp-spt ...`` command as ``python -m warp_spt ... -out out.npy``."""
    args = shlex.split(text)
    assert args[0] == "warp-spt"
    args[args.index("-out") + 1] = str(out)
    proc = subprocess.run([sys.executable, "-m", "warp_spt", *args[1:], "--quiet"], capture_output=True,
                          text=True, timeout=TIMEOUT, env=os.environ.copy())
    assert proc.returncode == 0, proc.stderr
    return np.load(out)


# ------------------------------------------------------------------ refining

def test_the_view_refines_with_an_error_estimate(session):
    res = session.wait_for(16, timeout=TIMEOUT)
    assert res.image.shape == (H, W, 3) and res.spp_total >= 16
    assert res.sums.shape[0] == session_module.BATCHES
    assert int(res.counts[:, 0, 0].sum()) == res.spp_total
    assert np.allclose(res.sums.sum(axis=0) / res.spp_total, res.image, rtol=1e-5, atol=1e-7)
    assert np.isfinite(res.std_error).all()
    assert 0 < res.relative_error < 1
    later = session.wait_for(res.spp_total + 16, timeout=TIMEOUT)
    assert later.relative_error < res.relative_error * 1.2     # more samples, no worse (noisy estimate)


def test_the_views_batches_draw_the_progressive_renderers_streams():
    """Batch b of the view is seeded as ``render_progressive``'s batch b (one ``batch_seed``, the
    renderer's), so the two estimate the same per-batch streams."""
    from warp_spt.rendering.schedule import batch_seed

    acc = session_module.Accumulator(0, 2, 3, seed=5)
    assert acc.seeds == [batch_seed(5, b) for b in range(session_module.BATCHES)]


def test_a_camera_change_restarts_the_refinement(session):
    first = session.wait_for(8, timeout=TIMEOUT)
    before = session.camera
    session.handle({"type": "orbit", "dx": 0.15, "dy": -0.05})
    after = session.camera
    assert after.position != before.position
    res = session.wait_for(8, timeout=TIMEOUT)
    assert not np.allclose(res.image, first.image, atol=0.05)


def test_a_new_interaction_abandons_the_pass_between_bands(demo_scene, monkeypatch):
    """Each render call of a pass renders a band of rows; a change arriving during one makes the
    pass stop before the next (it is never interrupted inside a call, and no thread is killed)."""
    monkeypatch.setattr(session_module, "BAND_SECONDS", 1e-9)       # one row per band
    monkeypatch.setattr(session_module, "SETTLE_SECONDS", 0.0)      # refine at once
    calls: list[tuple[tuple, int]] = []
    state = {"moved_at": None}
    real = warp_spt.render_scene
    ready = threading.Event()

    def spy(scene, camera, settings, *, rows=None, **kw):
        calls.append((camera.position, rows))
        if rows is not None and rows[0] == 3 and state["moved_at"] is None:
            state["moved_at"] = len(calls)           # the user drags while band 3 renders
            ready.wait(TIMEOUT)
            s.handle({"type": "orbit", "dx": 0.05, "dy": 0.0})
        return real(scene, camera, settings, rows=rows, **kw)

    monkeypatch.setattr(warp_spt, "render_scene", spy)
    s = Session(demo_scene, width=W, height=H, max_spp=4)
    ready.set()
    try:
        s.wait_for(4, timeout=TIMEOUT)
        moved = state["moved_at"]
        assert moved is not None
        old = calls[moved - 1][0]
        assert all(cam != old for cam, _ in calls[moved:]), "bands of the old view were rendered after the change"
        assert s.result().spp_total == 4
    finally:
        s.close()


def test_previews_while_dragging_then_refines(session):
    inbox = Inbox()
    session.add_listener(inbox)
    session.wait_for(1, timeout=TIMEOUT)
    session.handle({"type": "interact", "active": True})
    for _ in range(3):
        session.handle({"type": "orbit", "dx": 0.01, "dy": 0.0})
    session.handle({"type": "interact", "active": False})
    session.wait_for(4, timeout=TIMEOUT)
    frames = [m for m, _ in inbox.of("frame")]
    modes = [f["mode"] for f in frames]
    assert "preview" in modes and modes[-1] == "refine"
    preview = next(f for f in frames if f["mode"] == "preview")
    pw, ph = preview["size"]
    assert preview["spp"] == 1 and pw < W and min(pw, ph) == 8 and abs(pw / ph - W / H) < 0.1
    assert all(buffers[0][:2] == b"\xff\xd8" for _, buffers in inbox.of("frame"))     # JPEG


# ------------------------------------------------------------------ controls

def test_settings_change_the_render_and_bad_values_are_reported(session):
    inbox = Inbox()
    session.add_listener(inbox)
    for key, value in [("integrator", "seed"), ("sampler", "independent"), ("max_depth", 3), ("sky", "pink")]:
        session.handle({"type": "set", "key": key, "value": value})
    res = session.wait_for(4, timeout=TIMEOUT)
    rs = res.settings
    assert (rs.integrator, rs.sampler, rs.max_depth, rs.sky) == ("seed", "independent", 3, warp_spt.Sky.pink())
    assert inbox.of("state")[-1][0]["settings"]["integrator"] == "seed"
    replies = Inbox()
    session.handle({"type": "set", "key": "integrator", "value": "magic"}, reply=replies)
    session.handle({"type": "set", "key": "max_depth", "value": 0}, reply=replies)
    session.handle({"type": "set", "key": "sky_color", "value": [1, -1, 0]}, reply=replies)
    session.handle({"type": "no such thing"}, reply=replies)
    notices = [m["text"] for m, _ in replies.of("notice")]
    assert len(notices) == 4 and "magic" in notices[0]
    assert session.settings.integrator == "seed" and session.settings.max_depth == 3


def test_display_settings_do_not_restart_the_render(session):
    res = session.wait_for(8, timeout=TIMEOUT)
    inbox = Inbox()
    session.add_listener(inbox)
    session.handle({"type": "set", "key": "exposure", "value": 1.5})
    session.handle({"type": "set", "key": "error_map", "value": True})
    assert session.result().spp_total >= res.spp_total
    frame = inbox.of("frame")[-1][0]
    assert frame["error_map"] is True and frame["mode"] == "refine"


def test_a_material_edit_changes_the_image(session, demo_scene):
    wall = demo_scene.materials.diffuse.copy()
    before = session.wait_for(16, timeout=TIMEOUT).image.mean()
    names = {p["name"] for p in session.state()["params"]}
    assert "BackWall.diffuse" in names and "Vase.diffuse_map" not in names   # texels are not edited here
    session.handle({"type": "param", "name": "BackWall.diffuse", "value": [0, 0, 0]})
    session.handle({"type": "param", "name": "white.diffuse", "value": [0, 0, 0]})
    after = session.wait_for(16, timeout=TIMEOUT).image.mean()
    assert after < 0.9 * before
    assert np.array_equal(demo_scene.materials.diffuse, wall)      # the caller's scene is not edited
    replies = Inbox()
    session.handle({"type": "command", "spp": 8}, reply=replies)
    assert "material" in " ".join(replies.of("command")[0][0]["notes"])
    session.handle({"type": "param", "name": "nope.diffuse", "value": [0, 0, 0]}, reply=replies)
    assert replies.of("notice")


def test_double_click_sets_the_orbit_target_and_focus(session):
    session.wait_for(1, timeout=TIMEOUT)
    before = session.camera
    session.handle({"type": "pick", "x": 0.5, "y": 0.5})
    cam = session.camera
    assert np.allclose(cam.direction, before.direction, atol=1e-9)     # the centre ray is the view direction
    assert cam.focus != before.focus
    hit = np.asarray(cam.position) + cam.focus * np.asarray(cam.direction)
    lo, hi = warp_spt.load_scene(*demo_files()).bounds
    assert np.all(hit >= lo - 1e-6) and np.all(hit <= hi + 1e-6)
    replies = Inbox()
    session.handle({"type": "dolly", "steps": -20})                 # far away: the corner sees only sky
    far = session.camera
    session.handle({"type": "pick", "x": 0.01, "y": 0.01}, reply=replies)
    assert "nothing there" in replies.of("notice")[0][0]["text"] and session.camera == far


def test_frame_up_axis_and_reset(session):
    session.wait_for(1, timeout=TIMEOUT)
    home = session.camera
    session.handle({"type": "frame"})
    framed = session.camera
    assert framed.position != home.position and framed.aperture == 0.0
    replies = Inbox()
    session.handle({"type": "up", "axis": "y"}, reply=replies)
    assert session.camera.up == (0.0, 1.0, 0.0) and replies.of("state")[0][0]["up"] == "y"
    assert "--up y" in session.command_line()
    session.handle({"type": "reset"})
    assert session.camera == home and "--up" not in session.command_line()


def test_save_and_download(session, tmp_path):
    res = session.wait_for(4, timeout=TIMEOUT)
    replies = Inbox()
    session.handle({"type": "save", "format": "npy"}, reply=replies)
    message, buffers = replies.of("file")[0]
    (tmp_path / message["name"]).write_bytes(buffers[0])
    saved = np.load(tmp_path / message["name"])
    assert saved.shape == (H, W, 3) and saved.dtype == np.float32
    assert message["name"].startswith("view_") and message["name"].endswith("spp.npy")
    assert session.result().spp_total >= res.spp_total
    session.handle({"type": "save", "format": "png"}, reply=replies)
    assert replies.of("file")[1][1][0][:8] == b"\x89PNG\r\n\x1a\n"
    session.save(tmp_path / "v.png")
    assert (tmp_path / "v.png").stat().st_size > 0


# ------------------------------------------------------------------ scene errors

def test_a_scene_error_is_shown_and_a_reload_recovers(tmp_path):
    objs, mtls = write_scene_files(tmp_path, "room", box_obj(material="wall"), "newmtl wall\nKd 0.5 oops 0.5\n")
    inbox = Inbox()
    s = open_session(objs=objs, mtls=mtls, width=16, height=12, max_spp=4, start=False)
    s.add_listener(inbox)        # before the render thread loads (and fails): no message is missed
    s.start()
    try:
        with pytest.raises(RuntimeError, match=r"room\.mtl:2"):
            s.wait_for(1, timeout=TIMEOUT)
        assert "room.mtl:2" in s.state()["error"] and s.state()["can_reload"]
        Path(mtls[0]).write_text(material("wall", Kd=(0.5, 0.5, 0.5)))
        s.handle({"type": "reload"})
        assert s.wait_for(1, timeout=TIMEOUT).image.shape == (12, 16, 3)
        assert s.error is None and s.state()["error"] is None
        assert any(m["error"] and "room.mtl:2" in m["error"] for m, _ in inbox.of("state"))
    finally:
        s.close()


def test_a_model_is_y_up_by_the_command_lines_rule(tmp_path):
    """A standard OBJ model with no --up is Y up in the viewer, as in warp-spt (warp_spt.up_axis);
    the built-in demo stays Z up (test_frame_up_axis_and_reset)."""
    from tests.support.models import write_model

    obj = write_model(tmp_path / "cow.obj", "cow", up="y")
    s = open_session(objs=[str(obj)], width=16, height=12, max_spp=1)
    try:
        s.wait_for(1, timeout=TIMEOUT)
        assert s.state()["up"] == "y" and s.camera.up == (0.0, 1.0, 0.0)
    finally:
        s.close()


# ------------------------------------------------------------------ the copied command line

def test_the_copied_command_renders_the_same_view(session, tmp_path):
    session.wait_for(1, timeout=TIMEOUT)          # loaded: the orbit below applies
    session.handle({"type": "orbit", "dx": 0.08, "dy": 0.03})
    session.handle({"type": "set", "key": "sky", "value": "gradient"})
    res = session.wait_for(64, timeout=TIMEOUT)
    replies = Inbox()
    session.handle({"type": "command", "spp": 64, "out": "x.npy"}, reply=replies)
    text = replies.of("command")[0][0]["text"]
    assert "-sky 1" in text and f"-res {W} {H}" in text
    other = run_command(text, tmp_path / "x.npy")
    assert other.shape == res.image.shape
    assert_same_view(res, other, 64)


def test_the_comparison_can_fail(session, tmp_path):
    """The same check catches a command whose camera is a little off (a swing of 2 degrees)."""
    res = session.wait_for(64, timeout=TIMEOUT)
    text = session.command_line(spp=64, out="x.npy")
    args = shlex.split(text)
    i = args.index("-cam")
    d = np.array([float(v) for v in args[i + 4:i + 7]])
    turn = math.radians(2.0)
    d = np.array([d[0] * math.cos(turn) - d[1] * math.sin(turn), d[0] * math.sin(turn) + d[1] * math.cos(turn), d[2]])
    args[i + 4:i + 7] = [f"{v:.9g}" for v in d]
    other = run_command(shlex.join(args), tmp_path / "x.npy")
    with pytest.raises(AssertionError, match="block"):
        assert_same_view(res, other, 64)
