"""Issue 32, the fourth hardening round: giant triangles, integrator options, out of memory, usage
errors of the budgets, the viewer's messages, --fov, the API's arguments and the smaller ones.
One test per class; the fuzzers of this round are in tests/hardening/test_fuzz_api.py."""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import warp_spt
from warp_spt.cli.main import main
from warp_spt.cli.options import parse_args
from warp_spt.integrators import INTEGRATORS, get_integrator
from warp_spt.io.loader import load_scene
from warp_spt.rendering import tiles as R
from warp_spt.rendering.settings import RenderSettings, check_args
from warp_spt.scene import limits
from warp_spt.scene.camera import Camera
from warp_spt.scene.errors import SceneError

REPO = Path(__file__).resolve().parents[2]
TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def _tri_scene(tmp_path: Path):
    (tmp_path / "t.obj").write_text(TRI)
    return load_scene([str(tmp_path / "t.obj")])


def _one_line(capsys, argv, status) -> str:
    assert main(argv) == status
    err = capsys.readouterr().err
    lines = [ln for ln in err.splitlines() if ln.startswith("warp-spt: error")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# ---------------------------------------------------------------- 3: integrator options bound memory and time

@pytest.mark.parametrize("name", sorted(INTEGRATORS))
def test_every_numeric_integrator_option_has_both_bounds(name):
    for p in get_integrator(name).params:
        if p.kind is not bool:
            assert p.low is not None and p.high is not None, f"{name}.{p.name} is unbounded"


@pytest.mark.parametrize("integrator, option, value", [
    ("guided", "rho", 1e-4),            # 3.4 GB and 24 s at 64x64, 64 spp (measured)
    ("guided", "spatial_c", 0.1),       # 5.7 GB at 32x32, 16 spp
    ("guided", "spatial_c", 1e-9),
    ("guided", "stop_after", 10**9),
    ("guided", "min_hits", 2**40),
    ("ears", "train_fraction", 2**40),
    ("ears", "min_records", 2**40),
    ("ears", "q_max", 1e30),
    ("ears", "v_scale", 1e300),
])
def test_options_that_grow_memory_or_time_are_refused_before_any_upload(integrator, option, value):
    rs = RenderSettings(integrator=integrator, integrator_options={option: value})
    with pytest.raises(ValueError, match=option):
        check_args(rs)
    with pytest.raises(ValueError, match=option):       # no scene: nothing was looked at or uploaded
        R.render_scene(None, None, rs)


# ---------------------------------------------------------------- 7: --fov is bounded like -cam's

def test_a_vanishing_fov_is_a_usage_error(tmp_path, capsys):
    (tmp_path / "t.obj").write_text(TRI)
    base = ["-obj", str(tmp_path / "t.obj"), "-res", "8", "8", "-sr", "1", "-out", str(tmp_path / "o.png")]
    line = _one_line(capsys, base + ["--fov", "1e-300"], 2)
    assert "fov" in line and "internal error" not in line
    line = _one_line(capsys, base[:2] + ["-cam", "0", "0", "5", "0", "0", "-1", "1e-300", "5", "0"] + base[2:], 2)
    assert "fov" in line
    with pytest.raises(ValueError, match="fov"):
        Camera(fov=1e-300).validate(8, 8)


def test_the_narrowest_fov_zooms_from_where_the_default_lens_frames(tmp_path, capsys):
    # the narrowest fov allowed, on two small triangles 8e11 apart: framed at that fov the camera
    # would stand 9e17 away (refused); it stands where the default lens frames them and zooms (issue 43)
    far = 8e11
    (tmp_path / "t.obj").write_text(f"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
                                    f"v 0 0 {far}\nv 1 0 {far}\nv 0 1 {far}\nf 4 5 6\n")
    status = main(["-obj", str(tmp_path / "t.obj"), "--fov", "0.0001", "-res", "8", "8", "-sr", "1",
                   "-out", str(tmp_path / "o.png")])
    said = capsys.readouterr().err
    assert status == 0 and "framed the scene" in said and " 0.0001 " in said, said


# ---------------------------------------------------------------- 8: the API's arguments

@pytest.mark.parametrize("kw, words", [
    (dict(max_depth=2**31), ["max_depth", "[1, 4096]"]),
    (dict(max_depth=4097), ["max_depth"]),
    (dict(spp=(1 << 20) + 1), ["spp"]),
    (dict(roulette_depth=2**31), ["roulette_depth"]),
    (dict(tile_pixels=2**40), ["tile_pixels"]),
    (dict(threads=0), ["threads"]), (dict(threads=-1), ["threads"]), (dict(threads=8.5), ["threads"]),
    (dict(threads=math.nan), ["threads"]), (dict(threads=1e20), ["threads"]),
    (dict(threads=1025), ["threads"]),
    (dict(height=True), ["height"]), (dict(width=np.bool_(True)), ["width"]),
])
def test_render_settings_out_of_the_documented_bounds_are_value_errors(kw, words):
    with pytest.raises(ValueError) as err:
        check_args(RenderSettings(**{"width": 8, "height": 8, "spp": 1, **kw}))
    for w in words:
        assert w in str(err.value)


def test_render_arguments_are_checked_before_anything_renders(tmp_path):
    scene = _tri_scene(tmp_path)
    cam = Camera.look_at((0.3, 0.3, 3), (0.3, 0.3, 0))
    with pytest.raises(TypeError, match="sky must be a warp_spt.Sky"):
        warp_spt.render(scene, cam, width=8, height=8, spp=1, sky=5)
    with pytest.raises(ValueError, match=r"batches must be an integer in \[2, 64\]"):
        warp_spt.render_progressive(scene, cam, width=8, height=8, spp=8, batches=10**5)
    with pytest.raises(ValueError, match="batches"):
        warp_spt.render_progressive(scene, cam, width=8, height=8, spp=8, batches=True)


def test_the_command_line_and_the_viewer_take_the_apis_bounds(tmp_path, capsys):
    from warp_spt.viewer.session import ViewSettings, checked_settings

    for flag, value in (("-depth", limits.MAX_DEPTH + 1), ("-sr", limits.MAX_SPP + 1),
                        ("--threads", limits.MAX_THREADS + 1)):
        assert flag in _one_line(capsys, [flag, str(value)], 2)
        parse_args([flag, str(value - 1)])                  # the bound itself is allowed
    with pytest.raises(ValueError, match="max_depth"):
        checked_settings(ViewSettings(), "max_depth", limits.MAX_DEPTH + 1)
    with pytest.raises(ValueError, match="max_spp"):
        checked_settings(ViewSettings(), "max_spp", limits.MAX_SPP + 1)


def test_parameters_check_their_arguments(tmp_path):
    scene = _tri_scene(tmp_path)
    with pytest.raises(TypeError, match="sky"):
        warp_spt.parameters(scene, Camera(), 1)
    with pytest.raises(TypeError, match="camera"):
        warp_spt.parameters(scene, 1)
    p = warp_spt.parameters(scene, Camera())
    with pytest.raises(KeyError, match="no parameter 'nope'"):
        p["nope"] = 1.0
    colour = next(n for n in p.names() if n.endswith(".diffuse"))
    before = p[colour].copy()
    for bad in ([10**400, 0, 0], ["a", 0, 0], [[1, 2], 3, 4]):
        with pytest.raises(ValueError, match=colour):
            p[colour] = bad
    assert np.array_equal(p[colour], before)


@pytest.mark.parametrize("aspect", [0, -1.0, math.nan, math.inf, True, "wide"])
def test_frame_refuses_an_aspect_that_is_no_positive_number(tmp_path, aspect):
    with pytest.raises(ValueError, match="aspect"):
        Camera.frame(_tri_scene(tmp_path), aspect=aspect)


# ---------------------------------------------------------------- 5: guided/ears with batch flags: usage errors

@pytest.mark.parametrize("integrator", ["guided", "ears"])
@pytest.mark.parametrize("flags", [["--time-budget", "5"], ["--target-error", "2%"], ["--adaptive"],
                                   ["--save-partial"], ["--workers", "2"], ["--min-spp", "4"],
                                   ["--progressive", "p.png"], ["--error-map", "e.npy"], ["--spp-map", "s.npy"]])
def test_integrators_with_their_own_passes_refuse_batch_flags_before_loading(tmp_path, capsys, monkeypatch,
                                                                             integrator, flags):
    import warp_spt.io.loader as loader

    def no_loading(*a, **k):
        raise AssertionError("the scene was loaded")
    monkeypatch.setattr(loader, "load_scene", no_loading)
    monkeypatch.chdir(tmp_path)
    (tmp_path / "t.obj").write_text(TRI)
    line = _one_line(capsys, ["-obj", "t.obj", "--integrator", integrator, *flags, "-res", "8", "8", "-sr", "2",
                              "-out", "o.png"], 2)
    assert flags[0] in line and integrator in line
    assert "internal error" not in line and "render_scene" not in line


# ---------------------------------------------------------------- 4: out of memory is said as documented

@pytest.mark.skipif(shutil.which("prlimit") is None, reason="needs prlimit (util-linux)")
@pytest.mark.parametrize("extra", [[], ["--progressive", "p.png"]])
def test_out_of_memory_under_an_address_space_limit_is_the_documented_line(tmp_path, extra):
    (tmp_path / "t.obj").write_text(TRI)
    # a 12000 x 12000 film is 3.5 GB of float64 sums: Warp's allocation fails under a 3 GB address space
    run = subprocess.run(["prlimit", "--as=3000000000", sys.executable, "-m", "warp_spt", "-obj", "t.obj",
                          "-res", "12000", "12000", "-sr", "1", "-out", "o.png", "--quiet", *extra],
                         cwd=tmp_path, capture_output=True, text=True, timeout=300,
                         env={**os.environ, "PYTHONPATH": str(REPO)})
    assert run.returncode == 1, run.stderr
    lines = run.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("warp-spt: error: out of memory"), run.stderr
    assert "try a smaller -res or fewer --threads" in lines[0]


@pytest.mark.parametrize("error", [MemoryError(), RuntimeError("Failed to allocate 3456000000 bytes on device 'cpu'")])
def test_out_of_memory_while_rendering_a_device_scene_names_its_size(tmp_path, capsys, monkeypatch, error):
    import warp_spt.cli.render as cli_render
    import warp_spt.rendering.tiles as tiles
    from warp_spt.upload.device_scene import DeviceScene

    def no_memory(scene, *a, **k):
        assert isinstance(scene, DeviceScene)       # whose textures are a method: the reporter crashed
        raise error
    monkeypatch.setattr(tiles, "render_scene", no_memory)
    monkeypatch.setattr(cli_render, "warm_up", lambda *a, **k: None)
    (tmp_path / "t.obj").write_text(TRI)
    line = _one_line(capsys, ["-obj", str(tmp_path / "t.obj"), "-res", "8", "8", "-sr", "1", "--no-studio",
                              "-out", str(tmp_path / "o.png")], 1)
    assert "out of memory while uploading and rendering the scene (1 triangles, 0 texels) at 8x8" in line


# ---------------------------------------------------------------- 1: giant triangles

@pytest.mark.parametrize("half", [4e9, 4e12, 1e15])
def test_a_triangle_too_large_for_float32_is_refused_with_its_line(tmp_path, capsys, half):
    # a square of half-size 4e9 shaded black, one of 4e12 was missed, and the loader took +-1e15
    (tmp_path / "sq.obj").write_text(f"# a flat square\nv {-half} {-half} 0\nv {half} {-half} 0\nv {half} {half} 0\n"
                                     f"v {-half} {half} 0\nf 1 2 3 4\n")
    with pytest.raises(SceneError) as err:
        load_scene([str(tmp_path / "sq.obj")])
    assert err.value.line == 6 and "1e+09" in err.value.message
    line = _one_line(capsys, ["-obj", str(tmp_path / "sq.obj"), "-res", "8", "8", "-sr", "1",
                              "-out", str(tmp_path / "o.png")], 1)
    assert "sq.obj:6:" in line


def test_the_largest_accepted_triangle_loads_and_an_api_scene_is_checked_too(tmp_path):
    from dataclasses import replace

    from warp_spt.scene.validate import validate_scene

    e = limits.MAX_TRIANGLE_EDGE
    (tmp_path / "t.obj").write_text(f"v 0 0 0\nv {e} 0 0\nv {e / 2} {e / 4} 0\nf 1 2 3\n")   # longest edge: e
    scene = load_scene([str(tmp_path / "t.obj")])
    mesh = scene.meshes[0]
    big = replace(scene, meshes=[replace(mesh, positions=mesh.positions * 1.001)])
    with pytest.raises(SceneError, match="meshes.0. .*edge of 1e\\+09 is longer"):
        validate_scene(big)


def test_the_room_at_the_largest_accepted_size_renders_as_the_room_at_unit_size(scene_dir):
    from tests.support.stability_scenes import assert_same_image, cornell_camera, cornell_files, load, render_batches, sky

    # the room's longest triangle edge is a wall's diagonal, 32 sqrt(2): scaled to the bound
    scale = limits.MAX_TRIANGLE_EDGE / (32 * math.sqrt(2)) * 0.999
    kw = dict(width=24, height=24, max_depth=6, sky=sky(50.0))
    reference = render_batches(load(*cornell_files(scene_dir)), cornell_camera(), 32, 16, seed=1, **kw)
    big = render_batches(load(*cornell_files(scene_dir, scale)), cornell_camera(scale), 32, 16, seed=2, **kw)
    assert_same_image(reference, big, f"scale {scale:g}")


# ---------------------------------------------------------------- 6 and 9: the viewer's messages, memory, shutdown

class _Inbox:
    def __init__(self):
        self.messages: list[dict] = []

    def __call__(self, message, buffers):
        self.messages.append(message)

    push = __call__                 # as the server's client


@pytest.fixture(scope="module")
def live_session(tmp_path_factory):
    from warp_spt.viewer.session import Session

    d = tmp_path_factory.mktemp("view")
    (d / "t.obj").write_text(TRI)
    session = Session(load_scene([str(d / "t.obj")]), width=16, height=12, max_spp=8)
    session.wait_for(1, timeout=300)          # the rig exists: navigation messages reach it
    yield session
    session.close()


@pytest.mark.parametrize("message, field", [
    ({"type": "dolly", "steps": 1e308}, "steps"),
    ({"type": "zoom", "steps": -1e308}, "steps"),
    ({"type": "dolly", "steps": math.inf}, "steps"),
    ({"type": "pan", "dx": math.nan, "dy": 0}, "dx"),
    ({"type": "orbit", "dx": 0, "dy": "up"}, "dy"),
    ({"type": "pick", "x": 0.5}, "y"),
    ({"type": "set", "key": "width", "value": math.inf}, "width"),
    ({"type": "set", "key": "height", "value": 10**400}, "height"),
    ({"type": "set", "key": "max_spp", "value": 8.5}, "max_spp"),
    ({"type": "set", "key": "sky_color", "value": [1, 2]}, "sky_color"),
    ({"type": "set", "key": "fov", "value": [1]}, "fov"),
    ({"type": "param", "name": "x", "value": 10**400}, "value"),
    ({"type": "param", "name": "x", "value": [[1, 2], 3]}, "value"),
    ({"type": "command", "width": -5, "height": 1}, "width"),      # the copied command carried -res -5 1
    ({"type": "command", "spp": 0}, "spp"),
    ({"type": "up", "axis": ["x"]}, "axis"),
    ({"type": "interact", "active": "yes"}, "active"),
    ({"type": "save", "format": "x" * 100_000}, "format"),
])
def test_a_bad_page_message_is_one_notice_naming_its_field_and_changes_nothing(live_session, message, field):
    import warnings

    before = (live_session.camera, live_session.settings, dict(live_session._pending))
    inbox = _Inbox()
    with warnings.catch_warnings():
        warnings.simplefilter("error")       # NaN pans printed raw RuntimeWarning lines
        live_session.handle(message, reply=inbox)
    assert [m["type"] for m in inbox.messages] == ["notice"], inbox.messages
    text = inbox.messages[0]["text"]
    assert field in text and "Error" not in text, text
    assert (live_session.camera, live_session.settings, dict(live_session._pending)) == before


def test_a_view_is_bounded_to_a_pixel_budget(live_session):
    inbox = _Inbox()
    live_session.handle({"type": "set", "key": "width", "value": 4096}, reply=inbox)
    live_session.handle({"type": "set", "key": "height", "value": 4096}, reply=inbox)  # 6-7.4 GB before
    notices = [m["text"] for m in inbox.messages if m["type"] == "notice"]
    assert len(notices) == 1 and "2,097,152 pixels" in notices[0]
    assert live_session.settings.width * live_session.settings.height <= limits.MAX_VIEW_PIXELS
    live_session.handle({"type": "set", "key": "width", "value": 16}, reply=inbox)


def test_the_statistics_of_a_view_copy_no_batches_and_match_the_batch_formula():
    import tracemalloc

    from warp_spt.viewer.session import Accumulator

    rng = np.random.default_rng(5)
    acc = Accumulator(0, 5, 7)
    for b in range(8):
        acc.add(b, rng.random((5, 7, 3)) * 3, 3, 0.0)
    mean, se = acc.statistics()
    batch_means = acc.sums / 3.0
    expected = np.sqrt(3.0 * batch_means.var(axis=0, ddof=1) / 24.0)     # between-batch variance / n
    assert np.allclose(se, expected, rtol=1e-6) and np.allclose(mean, batch_means.mean(axis=0), rtol=1e-6)

    big = Accumulator(0, 540, 960)
    big.counts[:] = 1
    image = 540 * 960 * 3 * 8
    tracemalloc.start()
    big.statistics()
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 6 * image, f"statistics allocated {peak / image:.1f} images (8 batches: a copy is 8 or more)"


def test_messages_nested_deeply_or_with_constants_are_notices(live_session, capfd):
    from warp_spt.viewer.server import ViewerServer

    server = ViewerServer(live_session)
    inbox = _Inbox()
    for text in ["[" * 5000 + "]" * 5000, '{"a":' * 5000 + "1" + "}" * 5000, '{"type": "pan", "dx": NaN, "dy": 0}',
                 '{"type": "dolly", "steps": Infinity}', "[1, 2]", "not json"]:
        server._receive(text, inbox)
    assert [m["type"] for m in inbox.messages] == ["notice"] * 6
    assert "Traceback" not in capfd.readouterr().err


def test_shutdown_with_a_page_connected_is_prompt(tmp_path):
    aiohttp = pytest.importorskip("aiohttp")
    import asyncio
    import threading
    import time

    from warp_spt.viewer.server import ViewerServer
    from warp_spt.viewer.session import open_session

    (tmp_path / "t.obj").write_text(TRI)
    session = open_session(objs=[str(tmp_path / "t.obj")], width=16, height=12)
    server = ViewerServer(session)
    url = server.start_thread()
    connected = threading.Event()

    async def page():
        async with aiohttp.ClientSession() as http:
            async with http.ws_connect(url.replace("http", "ws") + "ws", origin=url.rstrip("/")) as ws:
                await ws.send_str('{"type": "hello"}')
                connected.set()
                async for _ in ws:
                    pass
    browser = threading.Thread(target=lambda: asyncio.run(page()), daemon=True)
    browser.start()
    assert connected.wait(60)
    time.sleep(0.5)
    t0 = time.monotonic()
    server.stop_thread(timeout=30)        # what SIGTERM does: _stopped is set, the server closes
    seconds = time.monotonic() - t0
    session.close()
    assert not server._thread.is_alive() and seconds < 5, f"stopping took {seconds:.1f} s"


def test_a_second_viewer_on_a_busy_port_says_so(tmp_path):
    import socket

    pytest.importorskip("aiohttp")
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        run = subprocess.run([sys.executable, "-m", "warp_spt", "view", "--port", str(port), "--no-browser"],
                             capture_output=True, text=True, timeout=300, env={**os.environ, "PYTHONPATH": str(REPO)})
    assert run.returncode == 1
    assert run.stderr.splitlines() == [f"warp-spt: error: port {port} is in use (another viewer?): choose another "
                                       "--port, or leave --port out for a free one"]


# ---------------------------------------------------------------- 9: the smaller ones

@pytest.mark.parametrize("value", ["1_0", "inf", "nan", "\u0661", "1e5_0"])
def test_procedural_numbers_take_the_one_number_syntax(tmp_path, value):
    (tmp_path / "m.mtl").write_text(f"newmtl m\nKd 0.5 0.5 0.5\nmap_Kd proc:marble scale={value}\n")
    (tmp_path / "t.obj").write_text("mtllib m.mtl\nusemtl m\n" + TRI)
    with pytest.raises(SceneError) as err:
        load_scene([str(tmp_path / "t.obj")], [str(tmp_path / "m.mtl")])
    assert err.value.line == 3 and "scale" in err.value.message
    (tmp_path / "m.mtl").write_text("newmtl m\nKd 0.5 0.5 0.5\nmap_Kd proc:marble scale=10\n")
    load_scene([str(tmp_path / "t.obj")], [str(tmp_path / "m.mtl")])          # a plain number is taken


@pytest.mark.parametrize("flags", [["-out", "a.npy", "--error-map", "a.npy"],
                                   ["-out", "a.png", "--progressive", "./a.png"],
                                   ["-out", "x.png", "--error-map", "e.npy", "--spp-map", "sub/../e.npy"]])
def test_two_outputs_naming_one_file_are_a_usage_error(tmp_path, capsys, monkeypatch, flags):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "t.obj").write_text(TRI)
    (tmp_path / "sub").mkdir()
    line = _one_line(capsys, ["-obj", "t.obj", "-res", "8", "8", "-sr", "2", *flags], 2)
    assert "name the same file" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == ["sub", "t.obj"]


def test_a_gif_that_cannot_be_written_fails_before_the_first_frame(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "t.obj").write_text(TRI)
    line = _one_line(capsys, ["-obj", "t.obj", "-res", "8", "8", "-sr", "1", "--frames", "0:2",
                              "-out", "f_{frame}.png", "--gif", "missing/a.gif"], 1)
    assert line == "warp-spt: error: cannot write --gif 'missing/a.gif': directory 'missing' does not exist"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["t.obj"]        # no frame was rendered


def test_sigterm_with_save_partial_exits_143(tmp_path, capsys, monkeypatch):
    import signal

    from warp_spt.rendering import progressive

    launched, real = [], progressive._Driver._launch

    def launch(self, *args, **kw):
        real(self, *args, **kw)
        launched.append(args)
        if len(launched) == 3:
            os.kill(os.getpid(), signal.SIGTERM)

    monkeypatch.setattr(progressive._Driver, "_launch", launch)
    (tmp_path / "t.obj").write_text(TRI)
    out = tmp_path / "partial.png"
    assert main(["-obj", str(tmp_path / "t.obj"), "-res", "128", "128", "--threads", "1", "--save-partial",
                 "-out", str(out)]) == 143
    assert "terminated: saved the partial image" in capsys.readouterr().err and out.exists()


def test_gradients_take_a_list_of_names(tmp_path):
    scene = _tri_scene(tmp_path)
    p = warp_spt.parameters(scene, Camera.look_at((0.3, 0.3, 3), (0.3, 0.3, 0)))
    settings = RenderSettings(width=4, height=4, spp=1)
    with pytest.raises(TypeError, match="wrt must be a list of parameter names"):     # was: no parameter 'c'
        warp_spt.render_gradients(p, settings, loss=lambda img: (img ** 2).sum(), wrt="camera.position")
    with pytest.raises(KeyError, match="no parameter 'nope'"):
        warp_spt.render_gradients(p, settings, loss=lambda img: (img ** 2).sum(), wrt=["nope"])


def test_sigterm_stops_the_viewer_promptly_while_a_page_is_connected(tmp_path):
    aiohttp = pytest.importorskip("aiohttp")
    import asyncio
    import signal
    import threading
    import time

    from tests.viewer.test_viewer_server import read_line

    (tmp_path / "t.obj").write_text(TRI)
    proc = subprocess.Popen([sys.executable, "-m", "warp_spt", "view", "--no-browser", "-res", "16", "12",
                             "-obj", str(tmp_path / "t.obj")], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env={**os.environ, "PYTHONPATH": str(REPO)})
    connected = threading.Event()
    try:
        line = read_line(proc.stdout, 300)
        assert line.startswith("warp-spt view: serving http://127.0.0.1:"), (line, proc.poll())
        url = line.split()[3]

        async def page():
            async with aiohttp.ClientSession() as http:
                async with http.ws_connect(url.replace("http", "ws") + "ws", origin=url.rstrip("/")) as ws:
                    await ws.send_str('{"type": "hello"}')
                    connected.set()
                    async for _ in ws:
                        pass
        threading.Thread(target=lambda: asyncio.run(page()), daemon=True).start()
        assert connected.wait(60)
        time.sleep(0.5)
        t0 = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=120)
        seconds = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 143 and err == "warp-spt view: terminated\n", err
    assert seconds < 10, f"SIGTERM took {seconds:.1f} s with a page connected"


def test_the_studio_ground_of_a_huge_bare_model_stays_within_the_triangle_bound():
    """A bare model 1e8 across: its studio ground (57 x its size) used to exceed MAX_TRIANGLE_EDGE,
    which validate_scene refuses; the ground is capped to the bound and the scene validates."""
    import numpy as np

    from warp_spt.scene.limits import MAX_TRIANGLE_EDGE
    from warp_spt.scene.model import MaterialTable, MeshData, Scene
    from warp_spt.scene.studio import add_studio
    from warp_spt.scene.validate import validate_scene
    from warp_spt.io.mtl import builtin_clay

    s = 5e7
    mesh = MeshData(name="big", positions=np.array([[-s, -s, 0], [s, -s, 0], [0, s, s]], np.float64),
                    indices=np.array([[0, 1, 2]], np.int32), corner_uv=np.zeros((1, 3, 2), np.float32),
                    corner_normal=None, face_material=np.zeros(1, np.int32))
    scene = Scene(meshes=[mesh], spheres=np.zeros((0, 4)), sphere_material=np.zeros(0, np.int32),
                  materials=MaterialTable.from_rows([builtin_clay()]), textures=[], bare=True, seed_dialect=False)
    studio = add_studio(scene, up="z")
    ground = studio.meshes[-1].positions
    assert np.linalg.norm(ground[2] - ground[0]) <= MAX_TRIANGLE_EDGE
    validate_scene(studio.rounded())
