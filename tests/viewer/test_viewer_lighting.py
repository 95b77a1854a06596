"""The viewer's light and fog controls through the session's message protocol (issues 34 and 35).

A "set" message with a light or fog key must reach the kernel (the image changes, in the
direction physics says where it says one: a brighter light brightens, a fog darkens), a bad value
must be refused with a notice naming the key and change nothing, turning everything off must give
back the first image, and the copied command line (--sun, --light, --fog) must render the same view.
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest

import warp_spt
from warp_spt.demo import demo_files
from warp_spt.viewer.session import Session

from tests.viewer.test_viewer_session import TIMEOUT, Inbox, assert_same_view, run_command

W, H, SPP = 32, 24, 16


@pytest.fixture(scope="module")
def demo_scene():
    return warp_spt.load_scene(*demo_files(), default_material="auto")


@pytest.fixture
def session(demo_scene):
    s = Session(demo_scene, width=W, height=H, max_spp=64)
    yield s
    s.close()


def _mean(res) -> tuple[float, float]:
    """(the image's mean, its standard error from the spread of the session's independent batches:
    sum_b n_b (m_b - m)^2 / (k - 1) / n, as the session's own per-pixel estimate)."""
    n = res.counts[:, 0, 0].astype(np.float64)
    used = n > 0
    sums = res.sums.reshape(len(n), -1).mean(axis=1)[used]
    n = n[used]
    m = sums.sum() / n.sum()
    var = (n * (sums / n - m) ** 2).sum() / (len(n) - 1) / n.sum()
    return float(m), float(math.sqrt(var))


def _after(session, key, value, spp=SPP):
    """Send a set message and wait for the new view refined to ``spp`` (the version changes first)."""
    version = session.version
    replies = Inbox()
    session.handle({"type": "set", "key": key, "value": value}, reply=replies)
    assert not replies.of("notice"), replies.of("notice")
    deadline = time.monotonic() + TIMEOUT
    while session.version == version and time.monotonic() < deadline:      # the re-upload bumps it
        time.sleep(0.05)
    return session.wait_for(spp, timeout=TIMEOUT)


def _brighter(a, b, factor: float = 1.0) -> bool:
    """b's mean exceeds factor x a's by more than 5 standard errors of the difference."""
    (ma, sa), (mb, sb) = _mean(a), _mean(b)
    return mb - factor * ma > 5 * math.hypot(factor * sa, sb)


def test_light_and_fog_messages_change_the_image(session):
    base = session.wait_for(SPP, timeout=TIMEOUT)
    s = session.settings
    assert not s.sun and s.lamp == "off" and not s.fog and s.integrator == "nee"
    assert s.sun_direction != (0.0, 0.0, 0.0) and s.lamp_direction != (0.0, 0.0, 0.0)   # placed on load

    sun = _after(session, "sun", True)
    assert _brighter(base, sun), "a sun lights the scene"
    strong = _after(session, "sun_color", [3.0, 3.0, 3.0])
    assert _brighter(sun, strong), "a brighter sun"
    low = _after(session, "sun_direction", [0.2, -1.0, 0.3])
    assert not np.array_equal(low.image, strong.image)
    soft = _after(session, "sun_radius", 10.0)
    assert not np.array_equal(soft.image, low.image)
    off = _after(session, "sun", False)

    lamp = _after(session, "lamp", "point")
    assert _brighter(off, lamp), "a lamp lights the scene"
    bright = _after(session, "lamp_intensity", [4 * v for v in session.settings.lamp_intensity])
    assert _brighter(lamp, bright, 1.5), "four times the intensity"
    spot = _after(session, "lamp", "spot")
    assert _brighter(spot, bright), "a spot's cone lights less than the same point light"
    narrow = _after(session, "lamp_angle", 10.0)
    assert not np.array_equal(narrow.image, spot.image)
    moved = _after(session, "lamp_position", [v + 1.0 for v in session.settings.lamp_position])
    assert not np.array_equal(moved.image, narrow.image)
    dark = _after(session, "lamp", "off")

    fog = _after(session, "fog", True)
    assert session.settings.integrator == "volpath", "a fog renders with volpath"
    assert _brighter(fog, dark), "a fog takes light away"
    dense = _after(session, "fog_sigma_a", [10 * v for v in session.settings.fog_sigma_a])
    assert _brighter(dense, fog), "a more absorbing fog takes more"
    forward = _after(session, "fog_g", 0.8)
    assert not np.array_equal(forward.image, dense.image)
    clear = _after(session, "fog", False)
    assert session.settings.integrator == "nee"
    # everything off: the first scene again, with the same seeds (the sums' order may differ)
    assert np.allclose(clear.image, base.image, rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("key, value, mentions", [
    ("sun_radius", 60.0, "sun_radius must be in [0, 45]"),
    ("sun_color", [1.0, -1.0, 0.0], "sun_color"),
    ("sun_direction", [0, 0, 0], "sun_direction must not be zero"),
    ("sun_direction", [1, 2], "sun_direction must be a list of 3 numbers"),
    ("sun", "yes", "sun must be true or false"),
    ("lamp", "bulb", "lamp must be one of off, point, spot"),
    ("lamp_position", [1e20, 0, 0], "lamp_position must lie within"),
    ("lamp_intensity", [1e31, 0, 0], "lamp_intensity"),
    ("lamp_angle", 95.0, "lamp_angle must be in [0, 90]"),
    ("lamp_angle", 0.0, "lamp_angle must be above 0"),
    ("fog_g", 1.0, "g (Henyey-Greenstein asymmetry) must lie in [-0.999999, 0.999999]"),
    ("fog_sigma_s", [1.0, math.nan, 1.0], "fog_sigma_s[1] must be a finite number"),
    ("fog_sigma_a", [-0.1, 0.0, 0.0], "sigma_a must be finite numbers in [0"),
    ("env_background", [1.0, -1.0, 0.0], "env_background colour values must lie in [0, 1e+30]"),
])
def test_a_bad_light_or_fog_value_is_refused_naming_its_key(key, value, mentions):
    s = Session(warp_spt.load_scene(*demo_files(), default_material="auto"), width=W, height=H, start=False)
    before, version = s.settings, s.version
    replies = Inbox()
    s.handle({"type": "set", "key": key, "value": value}, reply=replies)
    notices = [m["text"] for m, _ in replies.of("notice")]
    assert len(notices) == 1 and mentions in notices[0], notices
    assert s.settings == before and s.version == version


def test_the_copied_command_renders_the_lit_and_foggy_view(session, tmp_path):
    session.wait_for(1, timeout=TIMEOUT)
    for key, value in [("sun", True), ("sun_color", [2.0, 1.8, 1.5]), ("lamp", "spot"), ("lamp_angle", 40.0),
                       ("fog", True), ("fog_g", 0.4)]:
        session.handle({"type": "set", "key": key, "value": value})
    time.sleep(0.5)
    res = session.wait_for(64, timeout=TIMEOUT)
    text = session.command_line(spp=64, out="x.npy")
    for flag in ("--sun ", "--sun-color 2 1.8 1.5", "--light spot position", "outer 40", "--fog sigma_s=",
                 "--fog g=0.4", "--integrator volpath"):
        assert flag in text, (flag, text)
    other = run_command(text, tmp_path / "x.npy")
    assert_same_view(res, other, 64)


def test_the_environment_background_is_set_by_message(tmp_path):
    from warp_spt.images.hdr import write_hdr

    from tests.support.scenes import box_obj, material, write_scene_files

    write_hdr(tmp_path / "sky.hdr", np.full((8, 16, 3), 0.5, dtype=np.float32))
    objs, mtls = write_scene_files(tmp_path, "box", box_obj(material="m"), material("m", Kd=(0.5, 0.5, 0.5)))
    # no studio: its ground under the map would hide the background this test sets
    s = Session(warp_spt.load_scene(objs, mtls), width=16, height=16, max_spp=4, sky="environment",
                env_path=str(tmp_path / "sky.hdr"), studio=False)
    try:
        plain = s.wait_for(4, timeout=TIMEOUT)
        grey = warp_spt.load_environment(str(tmp_path / "sky.hdr")).env.image[0, 0]   # 0.5 as RGBE stores it
        missed = np.all(plain.image == grey, axis=2)     # camera rays that miss see the map's grey
        assert 0 < missed.sum() < missed.size
        backdrop = _after(s, "env_background", [1.0, 0.0, 0.0], spp=4)
        assert np.array_equal(backdrop.image[missed], np.tile([1.0, 0.0, 0.0], (int(missed.sum()), 1)))
        assert "--env-background 1 0 0" in s.command_line(spp=4)
        again = _after(s, "env_background", None, spp=4)
        assert np.array_equal(again.image[missed], plain.image[missed])
    finally:
        s.close()


# ---------------------------------------------------------------- warp-spt view's flags

def test_the_view_commands_light_fog_and_environment_flags_become_the_pages_settings():
    from warp_spt.cli.view import build_parser, lighting_settings

    ns = build_parser().parse_args(["--sun", "0", "1", "0", "--sun-color", "2", "2", "2", "--sun-radius", "0.5",
                                    "--light", "spot", "position", "0", "2", "0", "intensity", "5", "outer", "20",
                                    "--fog", "sigma_s=0.1", "--fog", "sigma_a=0.01,0.02,0.03", "--fog", "g=0.2",
                                    "--env", "sky.hdr", "--env-rotate", "30", "--env-background", "0", "0", "0"])
    assert lighting_settings(ns) == dict(
        sky="environment", env_path="sky.hdr", env_rotate=30.0, env_background=(0.0, 0.0, 0.0),
        sun=True, sun_direction=(0.0, 1.0, 0.0), sun_color=(2.0, 2.0, 2.0), sun_radius=0.5,
        lamp="spot", lamp_position=(0.0, 2.0, 0.0), lamp_intensity=(5.0, 5.0, 5.0), lamp_direction=(0.0, 0.0, -1.0),
        lamp_angle=20.0, fog=True, fog_sigma_a=(0.01, 0.02, 0.03), fog_sigma_s=(0.1, 0.1, 0.1), fog_g=0.2)
    assert lighting_settings(build_parser().parse_args([])) == {}


@pytest.mark.parametrize("argv, mentions", [
    (["--light", "point", "--light", "point", "position", "1", "1", "1"], "one sun and one point or spot light"),
    (["--light", "spot", "inner", "5"], "no inner cone"),
    (["--fog", "emission=1"], "sigma_a, sigma_s and g"),
    (["--fog", "g=1"], "g (Henyey-Greenstein asymmetry) must lie in [-0.999999, 0.999999]"),
    (["--env-rotate", "30"], "--env-rotate needs --env FILE"),
    (["--sun-radius", "2"], "need --sun"),
])
def test_the_view_command_refuses_what_the_page_cannot_hold_in_one_line(argv, mentions, capsys):
    from warp_spt.cli.view import main

    assert main([*argv, "--no-browser"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and mentions in err and "Traceback" not in err


def test_a_light_from_the_start_lights_the_studio_as_on_the_command_line(tmp_path):
    """A bare model gets the studio look; with a sun from the start the sun is its key, as
    ``warp-spt --sun`` makes it (issue 43): the ground and the fill sky stay, the key sphere is left
    out, and the copied command (--sun, --studio) says the same."""
    from tests.support.models import write_model

    write_model(tmp_path / "cow.obj", "cow", up="y")
    looks = {}
    for name, kw in (("bare", {}), ("sun", dict(sun=True, sun_direction=(0.3, 1.0, 0.4)))):
        s = Session(loader=lambda: warp_spt.load_scene([str(tmp_path / "cow.obj")], default_material="auto"),
                    objs=[str(tmp_path / "cow.obj")], width=16, height=12, max_spp=1, **kw)
        try:
            s.wait_for(1, timeout=TIMEOUT)
            looks[name] = (s.settings.sky, s.command_line(spp=1), len(s._params.scene.scene.spheres))
        finally:
            s.close()
    assert looks["bare"][0] == "studio" and looks["sun"][0] == "studio"
    assert looks["bare"][2] == 1 and looks["sun"][2] == 0           # the key sphere, then none
    assert "--sun 0.3 1 0.4" in looks["sun"][1] and "--studio" in looks["sun"][1]


def test_the_pages_sun_replaces_the_studios_key_and_gives_it_back(tmp_path):
    """Turned on after the first view, the page's sun takes the key sphere out (and dims the sky to
    the fill), as the command line's rule does for --sun; turned off, the key is back."""
    from tests.support.models import write_model
    from warp_spt.images.hdr import write_hdr
    from warp_spt.scene.studio import FILL_SKY, SKY

    write_model(tmp_path / "cow.obj", "cow", up="y")
    s = Session(loader=lambda: warp_spt.load_scene([str(tmp_path / "cow.obj")], default_material="auto"),
                objs=[str(tmp_path / "cow.obj")], width=16, height=12, max_spp=1)
    try:
        s.wait_for(1, timeout=TIMEOUT)
        key = s._params.scene.scene.spheres.copy()
        assert len(key) == 1 and s._make_sky(s.settings).color == SKY
        _after(s, "sun", True, spp=1)
        assert len(s._params.scene.scene.spheres) == 0 and s._make_sky(s.settings).color == FILL_SKY
        _after(s, "sun", False, spp=1)
        assert np.array_equal(s._params.scene.scene.spheres, key) and s._make_sky(s.settings).color == SKY
        write_hdr(tmp_path / "sky.hdr", np.full((8, 16, 3), 0.5, dtype=np.float32))
        s.handle({"type": "set", "key": "env_path", "value": str(tmp_path / "sky.hdr")})
        _after(s, "sky", "environment", spp=1)          # an environment map is a light of the user's too
        assert len(s._params.scene.scene.spheres) == 0
    finally:
        s.close()
