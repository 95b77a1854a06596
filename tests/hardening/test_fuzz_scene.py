"""Fuzzing whole scenes (issue 11): mutated OBJ and MTL text and PNG bytes, through the API and the CLI.

For every generated scene:

* ``load_scene`` either returns a Scene or raises SceneError: no other exception escapes;
* when it fails, the command line prints exactly one line ``warp-spt: error: FILE[:LINE]: ...``
  naming one of the scene's files, and exits with 1;
* when it loads, a tiny render (8x8, 1 spp, depth 2, one shared general kernel) under a sky as
  bright as allowed is finite and the kernel's non-finite guard drops no sample.

Sizes are kept small so the whole module runs in about a minute on 2 cores.
"""

from __future__ import annotations

import io
import tempfile
import time
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warp_spt.cli.main import main
from warp_spt.io.loader import load_scene
from warp_spt.scene.camera import Camera
from warp_spt.scene.errors import SceneError
from warp_spt.scene.sky import Sky
from warp_spt.scene.validate import MAX_RADIANCE

from tests.hardening.test_parse_fuzz import MTL_SEED, OBJ_SEED, PIECES, mutated

# Pieces that push values to the bounds (float32 range, underflow, the coordinate limit) and line ends.
EXTREME = [b"1e38", b"3e38", b"1e-46", b"1e-40", b"1e15", b"1e16", b"1e30", b"1e31", b"0.999", b"1.0001",
           b"\r", b"\r\n", b"\n", b"-0", b"Kl", b"Kd", b"Kn", b"Ni", b"map_Kd", b"mtllib", b"b", b"f",
           # issue 21: a byte-order mark anywhere, invisible characters, integers of thousands of digits
           b"\xef\xbb\xbf", b"\xe2\x80\x8b", b"\xc2\xa0", b"9" * 5000, b"illum " + b"7" * 4400]
ALL_PIECES = PIECES + EXTREME
# A scene the camera sees: the OBJ seed's geometry lies within [0, 3] around the origin.
CAMERA = Camera(position=(0.5, 0.5, 6.0), direction=(0.0, 0.0, -1.0), fov=60.0, focus=6.0, aperture=0.0)




@st.composite
def png_bytes(draw) -> bytes:
    """A small or a thin (1 x n, n x 1) PNG in one of Pillow's modes, sometimes truncated or with
    bytes flipped. Thin ones exercise the flat atlas's addressing at extreme aspect ratios."""
    from PIL import Image

    w, h = draw(st.integers(1, 6)), draw(st.integers(1, 6))
    if draw(st.integers(0, 3)) == 0:
        n = draw(st.integers(7, 4000))
        w, h = (1, n) if draw(st.booleans()) else (n, 1)
    mode = draw(st.sampled_from(["L", "RGB", "RGBA", "LA", "P", "1", "I;16"]))
    seed = draw(st.integers(0, 2**32 - 1))
    rng = np.random.default_rng(seed)
    if mode == "I;16":
        img = Image.fromarray(rng.integers(0, 65536, (h, w), dtype=np.uint16))
    else:
        img = Image.fromarray(rng.integers(0, 256, (h, w, 3), dtype=np.uint8)).convert(mode)
    buf = io.BytesIO()
    img.save(buf, format="PNG")
    data = bytearray(buf.getvalue())
    damage = draw(st.sampled_from(["none", "none", "truncate", "flip"]))
    if damage == "truncate":
        del data[draw(st.integers(0, len(data) - 1)):]
    elif damage == "flip":
        for _ in range(draw(st.integers(1, 4))):
            at = draw(st.integers(0, len(data) - 1))
            data[at] ^= draw(st.integers(1, 255))
    return bytes(data)


def check_scene(obj: bytes, mtl: bytes, png: bytes, sky: float, capsys) -> str:
    """Write the scene, load it, then render it (loaded) or run the CLI on it (failed). Returns the outcome."""
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        (d / "f.obj").write_bytes(obj)
        (d / "a.mtl").write_bytes(mtl)
        (d / "t.png").write_bytes(png)
        (d / "x.png").write_bytes(png)
        files = [str(d / n) for n in ("f.obj", "a.mtl", "t.png", "x.png")]
        try:
            scene = load_scene([files[0]], warn=lambda m: None)
        except SceneError:
            capsys.readouterr()
            status = main(["-obj", files[0], "--quiet", "-res", "8", "8", "-sr", "1", "-depth", "2",
                           "-out", str(d / "o.png")])
            out, err = capsys.readouterr()
            assert status == 1 and out == "", err
            lines = err.splitlines()
            assert len(lines) == 1 and lines[0].startswith("warp-spt: error: "), err
            assert any(lines[0].startswith(f"warp-spt: error: {f}") for f in files), err
            return "error"
    from warp_spt.upload.device_scene import Features
    from warp_spt.rendering.settings import RenderSettings
    from warp_spt.rendering.tiles import render_scene

    res = render_scene(scene, CAMERA, RenderSettings(width=8, height=8, spp=1, max_depth=2,
                                                     sky=Sky.constant(sky, sky, sky), threads=1,
                                                     features=Features.general()))
    assert np.isfinite(res.image).all()
    assert res.stats.dropped_samples == 0
    return "rendered"


STATS: dict[str, int] = {}
SKIES = st.sampled_from([0.0, 1.0, 1e3, MAX_RADIANCE])


def record(outcome: str) -> None:
    STATS[outcome] = STATS.get(outcome, 0) + 1


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(obj=mutated(OBJ_SEED, ALL_PIECES), sky=SKIES)
def test_fuzzed_obj(obj, sky, capsys):
    record(check_scene(obj, MTL_SEED, _GOOD_PNG, sky, capsys))


@settings(max_examples=250, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(mtl=mutated(MTL_SEED, ALL_PIECES), sky=SKIES)
def test_fuzzed_mtl(mtl, sky, capsys):
    record(check_scene(OBJ_SEED, mtl, _GOOD_PNG, sky, capsys))


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                 HealthCheck.function_scoped_fixture])
@given(png=png_bytes(), sky=SKIES)
def test_fuzzed_png(png, sky, capsys):
    record(check_scene(OBJ_SEED, MTL_SEED, png, sky, capsys))


def _good_png() -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGB", (2, 2), (200, 100, 50)).save(buf, format="PNG")
    return buf.getvalue()


_GOOD_PNG = _good_png()


@pytest.fixture(scope="module", autouse=True)
def report_counts():
    start = time.monotonic()
    yield
    print(f"\nscene fuzz: {STATS} in {time.monotonic() - start:.1f} s")


def test_both_outcomes_were_exercised():
    """The fuzz is not vacuous: some scenes loaded and rendered, some were refused."""
    assert STATS.get("rendered", 0) > 20 and STATS.get("error", 0) > 20, STATS
