"""Fuzzing the API's arguments, the integrators' options and the viewer's messages (issue 32).

* Integrator options: any mapping of names (the declared ones and others) to values (numbers at and
  beyond every bound, huge integers, NaN, bools, strings, None, lists) is either taken by
  ``check_args`` (and then every value lies in its declared range) or refused with a ValueError
  naming the option; taken ones render a tiny image that is finite, in bounded time.
* API arguments: ``render`` with any mix of settings (sizes, spp, depths, threads, tile size, seed,
  sky, filter, sample offset; ints, floats, bools, huge and negative values, strings, None) either
  returns a finite (height, width, 3) image or raises TypeError/ValueError naming an argument.
* Viewer messages: any JSON text, and any object of a known or unknown type with fields of any JSON
  value, is answered by notices that name a field (never the "a bug" branch's exception names) or
  acted on; afterwards the view is within its pixel budget and its camera renders.

Outcomes are counted with hypothesis' ``event``: ``python -m pytest tests/hardening/test_fuzz_api.py
--hypothesis-show-statistics`` prints the cases by outcome.
"""

from __future__ import annotations

import json
import math
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

import warp_spt
from warp_spt.integrators import get_integrator
from warp_spt.io.loader import load_scene
from warp_spt.rendering.settings import RenderSettings, check_args
from warp_spt.scene import limits
from warp_spt.scene.camera import Camera

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
CAMERA = Camera.look_at((0.3, 0.3, 3.0), (0.3, 0.3, 0.0))
SLOW = settings(deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow])

# Numbers at and around every bound the settings and options have, and beyond float64 and int64.
EDGES = [0, 1, 2, -1, 3, 8, 64, 100, 1000, 1024, 1025, 4096, 4097, 1 << 20, (1 << 20) + 1, 2**31 - 1, 2**31,
         2**63, 10**400, 0.0, 1e-300, 1e-4, 0.001, 0.03, 0.5, 0.999, 1.0, 1.5, 99.9, 100.0, 1e3, 1e6, 1e9, 1e30,
         1e38, 1e308, -0.5, -1e308, math.inf, -math.inf, math.nan]
ODD = [True, False, None, "1", "0.5", "", "1_0", [1], {"a": 1}, (2, 3)]
VALUES = st.one_of(st.sampled_from(EDGES), st.sampled_from(ODD), st.integers(), st.floats(allow_nan=True),
                   st.text(max_size=5), st.floats(0.0, 1.0), st.integers(0, 64))


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    d = tmp_path_factory.mktemp("fuzz_api")
    (d / "t.obj").write_text(TRI)
    return load_scene([str(d / "t.obj")])


# ---------------------------------------------------------------- integrator options

@st.composite
def option_sets(draw):
    integrator = draw(st.sampled_from(["guided", "ears", "nee"]))
    declared = [p.name for p in get_integrator(integrator).params]
    names = draw(st.lists(st.sampled_from(declared + ["beta", "", "rho "]) if declared else st.just("beta"),
                          max_size=3, unique=True))
    return integrator, {n: draw(VALUES) for n in names}


def _check_options(integrator: str, options: dict) -> str:
    try:
        check_args(RenderSettings(width=8, height=8, spp=2, integrator=integrator, integrator_options=options))
    except ValueError as err:
        assert any(repr(n) in str(err) or n in str(err) for n in options) or "takes no options" in str(err), err
        return "refused"
    taken = get_integrator(integrator).options(options)
    for p in get_integrator(integrator).params:
        v = taken[p.name]
        if p.kind is not bool and v is not None:
            assert p.low <= v <= p.high, (p.name, v)
    return "taken"


@settings(SLOW, max_examples=400)
@given(case=option_sets())
def test_fuzzed_integrator_options_are_taken_within_their_bounds_or_refused(case):
    integrator, options = case
    event(f"options: {_check_options(integrator, options)}")


@settings(SLOW, max_examples=25)
@given(case=option_sets())
def test_fuzzed_integrator_options_that_are_taken_render_finite_in_bounded_time(scene, case):
    integrator, options = case
    if _check_options(integrator, options) == "refused":
        event("render options: refused")
        return
    t0 = time.perf_counter()
    image = warp_spt.render(scene, CAMERA, width=8, height=8, spp=4, max_depth=3, integrator=integrator,
                            integrator_options=options, sky=warp_spt.Sky.constant(1.0, 1.0, 1.0), threads=1)
    event("render options: rendered")
    assert np.isfinite(image).all() and image.shape == (8, 8, 3)
    assert time.perf_counter() - t0 < 120


# ---------------------------------------------------------------- API arguments

SETTING_VALUES = {
    "width": st.one_of(st.integers(1, 12), st.sampled_from(EDGES + ODD)),
    "height": st.one_of(st.integers(1, 12), st.sampled_from(EDGES + ODD)),
    "spp": st.one_of(st.integers(1, 4), st.sampled_from(EDGES + ODD)),
    "max_depth": st.one_of(st.integers(1, 4), st.sampled_from(EDGES + ODD)),
    "roulette_depth": st.one_of(st.integers(0, 4), st.sampled_from(EDGES + ODD)),
    "threads": st.one_of(st.none(), st.integers(1, 2), st.sampled_from(EDGES + ODD)),
    "tile_pixels": st.one_of(st.integers(1, 4096), st.sampled_from(EDGES + ODD)),
    "seed": st.one_of(st.integers(0, 2**32), st.sampled_from(EDGES + ODD)),
    "sample_offset": st.one_of(st.integers(0, 100), st.sampled_from(EDGES + ODD)),
    "texture_filter": st.sampled_from(["nearest", "bilinear", "cubic", None, 1]),
    "sky": st.sampled_from([None, 5, "blue", warp_spt.Sky.black(), warp_spt.Sky.constant(1e30, 0, 0)]),
}


@settings(SLOW, max_examples=150)
@given(kw=st.fixed_dictionaries({}, optional=SETTING_VALUES))
def test_fuzzed_render_arguments_render_or_name_the_argument(scene, kw):
    small = all(not isinstance(kw.get(k), (int, float)) or isinstance(kw.get(k), bool) or kw[k] <= 12
                for k in ("width", "height"))
    cheap = not isinstance(kw.get("spp"), int) or isinstance(kw.get("spp"), bool) or kw["spp"] <= 64
    if not (small and cheap):          # a legal but large render: checked, not rendered
        try:
            check_args(RenderSettings(**kw))
        except (TypeError, ValueError) as err:
            assert any(k in str(err) for k in kw) or "sample indices" in str(err), err
            event(f"render arguments: refused ({type(err).__name__})")
            return
        event("render arguments: taken, too large to render here")
        return
    try:
        image = warp_spt.render(scene, CAMERA, **kw)
    except (TypeError, ValueError) as err:
        assert any(k in str(err) for k in kw) or "sample indices" in str(err), err
        event(f"render arguments: refused ({type(err).__name__})")
        return
    event("render arguments: rendered")
    assert np.isfinite(image).all() and image.ndim == 3 and image.shape[2] == 3


@settings(SLOW, max_examples=100)
@given(batches=st.sampled_from(EDGES + ODD), aspect=st.sampled_from(EDGES + ODD))
def test_fuzzed_progressive_batches_and_framing_aspects(scene, batches, aspect):
    try:
        warp_spt.render_progressive(scene, CAMERA, width=4, height=4, spp=8, batches=batches, threads=1)
        event("batches: rendered")
    except ValueError as err:
        assert "batches" in str(err)
        event("batches: refused")
    try:
        Camera.frame(scene, aspect=aspect).validate(8, 8)
        event("aspect: framed")
    except ValueError as err:
        assert "aspect" in str(err) or "camera" in str(err), err
        event("aspect: refused")


# ---------------------------------------------------------------- viewer messages

KINDS = ["hello", "interact", "orbit", "pan", "dolly", "zoom", "pick", "frame", "reset", "up", "set", "param",
         "command", "save", "reload", "bogus", 5, None]
FIELDS = ["dx", "dy", "steps", "x", "y", "axis", "key", "value", "name", "width", "height", "spp", "out",
          "format", "active", "extra"]
SET_KEYS = ["width", "height", "max_depth", "max_spp", "preview_scale", "integrator", "sampler", "sky", "tonemap",
            "exposure", "fov", "aperture", "sky_color", "error_map", "nope"]
JSON_VALUES = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(), st.floats(allow_nan=True), st.text(max_size=6),
              st.sampled_from([e for e in EDGES] + ["x", "srgb", "nee", "guided", "gradient", "y", "-z", "png"])),
    lambda inner: st.one_of(st.lists(inner, max_size=4), st.dictionaries(st.text(max_size=3), inner, max_size=3)),
    max_leaves=8)


@st.composite
def page_messages(draw):
    message = {"type": draw(st.sampled_from(KINDS))}
    for name in draw(st.lists(st.sampled_from(FIELDS), max_size=4, unique=True)):
        message[name] = draw(JSON_VALUES)
    if message["type"] == "set" and draw(st.booleans()):
        message["key"] = draw(st.sampled_from(SET_KEYS))
    return message


@pytest.fixture(scope="module")
def session(scene):
    from warp_spt.viewer.session import Session

    s = Session(scene, width=16, height=12, max_spp=4)
    s.wait_for(1, timeout=300)
    yield s
    s.close()


class _Inbox:
    def __init__(self):
        self.messages: list[dict] = []

    def __call__(self, message, buffers):
        self.messages.append(message)

    push = __call__


BUG_WORDS = ("Error:", "Exception", "Traceback", "Warning")


@settings(SLOW, max_examples=400)
@given(message=page_messages())
def test_fuzzed_page_messages_are_acted_on_or_refused_naming_a_field(session, message):
    inbox = _Inbox()
    session.handle(message, reply=inbox)
    notices = [m["text"] for m in inbox.messages if m.get("type") == "notice" and m.get("level") == "error"]
    for text in notices:
        assert not any(w in text for w in BUG_WORDS), (message, text)
    event("message: refused" if notices else "message: acted on")
    s = session.settings
    assert s.width * s.height <= limits.MAX_VIEW_PIXELS
    cam = session.camera
    if cam is not None:
        cam.validate(s.width, s.height)
    if s.width * s.height > 64 * 64:             # keep the render thread's work small for the next case
        session.handle({"type": "set", "key": "width", "value": 16}, reply=inbox)
        session.handle({"type": "set", "key": "height", "value": 12}, reply=inbox)


@settings(SLOW, max_examples=300)
@given(text=st.one_of(st.text(max_size=40), JSON_VALUES.map(json.dumps),
                      st.integers(1, 6000).map(lambda n: "[" * n + "]" * n),
                      st.integers(1, 6000).map(lambda n: '{"a":' * n + "0" + "}" * n),
                      page_messages().map(lambda m: json.dumps(m, allow_nan=True))))
def test_fuzzed_socket_text_is_parsed_or_refused(session, text):
    from warp_spt.viewer.server import ViewerServer

    inbox = _Inbox()
    ViewerServer(session)._receive(text, inbox)
    notices = [m["text"] for m in inbox.messages if m.get("type") == "notice" and m.get("level") == "error"]
    for t in notices:
        assert not any(w in t for w in BUG_WORDS), (text[:80], t)
    event("socket text: refused" if notices else "socket text: acted on")
    s = session.settings
    if s.width * s.height > 64 * 64:
        session.handle({"type": "set", "key": "width", "value": 16}, reply=inbox)
        session.handle({"type": "set", "key": "height", "value": 12}, reply=inbox)


def test_the_fuzzers_reach_both_outcomes():
    """The strategies are not vacuous: each has cases taken and cases refused (checked directly)."""
    assert _check_options("guided", {"rho": 0.5}) == "taken"
    assert _check_options("guided", {"rho": 1e-9}) == "refused"
