"""Issue 21, the third hardening round: the inputs that still got through. One test per class;
the generators at the end fuzz camera paths and frame templates so the classes stay closed."""

from __future__ import annotations

import json
import os
import resource
import threading
import time
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from warp_spt.animation import CameraPath
from warp_spt.cli.main import main
from warp_spt.io.loader import load_scene
from warp_spt.io.mtl import load_mtl
from warp_spt.io.obj import load_obj
from warp_spt.io.templates import frame_path, parse_frames
from warp_spt.scene.errors import SceneError

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"
KEY = {"frame": 0, "position": [0, -5, 1], "direction": [0, 1, 0]}


def _error(fn, *args) -> SceneError:
    with pytest.raises(SceneError) as info:
        fn(*args)
    return info.value


def _one_line_usage(capsys, argv, status=2) -> str:
    assert main(argv) == status
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and err.startswith("warp-spt: error: "), err
    return err


# ---------------------------------------------------------------- readers that were missed

def test_a_camera_path_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "path.json"
    os.mkfifo(fifo)
    result: list = []
    reader = threading.Thread(target=lambda: result.append(_error(CameraPath.load, fifo)), daemon=True)
    reader.start()
    reader.join(5.0)
    assert not reader.is_alive(), "reading a FIFO blocked"
    assert "FIFO" in result[0].message


def test_a_camera_path_device_or_directory_is_refused(tmp_path):
    assert "character device" in _error(CameraPath.load, "/dev/zero").message
    assert "directory" in _error(CameraPath.load, tmp_path).message


def test_a_file_over_the_limit_is_refused_from_its_size_without_reading_it(tmp_path):
    big = tmp_path / "sparse.obj"
    with open(big, "wb") as f:
        f.truncate(3 << 30)                                   # 3 GB of holes: no disk, no reading
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    t0 = time.perf_counter()
    err = _error(load_obj, big)
    assert "larger than" in err.message and err.path == str(big)
    assert time.perf_counter() - t0 < 2.0
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 200_000      # KiB: nothing read


def test_binary_data_is_refused_from_its_first_bytes(tmp_path):
    nul = tmp_path / "zeros.obj"
    with open(nul, "wb") as f:
        f.truncate(1 << 30)                                   # 1 GiB of NUL bytes, under the size limit
    before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    err = _error(load_obj, nul)
    assert "binary data" in err.message and err.line == 1
    assert resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before < 200_000


@pytest.mark.parametrize("loader", [load_obj, load_mtl, lambda p: load_scene([str(p)])])
def test_a_directory_is_a_scene_error_naming_its_path(tmp_path, loader):
    err = _error(loader, tmp_path)
    assert err.path == str(tmp_path) and "directory" in err.message


def test_a_utf8_byte_order_mark_is_stripped(tmp_path):
    (tmp_path / "bom.obj").write_bytes(b"\xef\xbb\xbf" + TRI.encode())
    assert len(load_obj(tmp_path / "bom.obj").positions) == 3          # the first vertex was lost
    (tmp_path / "bom.mtl").write_bytes(b"\xef\xbb\xbfnewmtl first\nKd 1 0 0\nnewmtl second\n")
    assert list(load_mtl(tmp_path / "bom.mtl")) == ["first", "second"]


@pytest.mark.parametrize("junk", ["\u200b", "\ufeff", "\u00a0", "\u2060"])
def test_other_invisible_characters_are_refused_with_their_line(tmp_path, junk):
    (tmp_path / "j.obj").write_text("v 0 0 0\n" + junk + "v 1 0 0\nv 0 1 0\nf 1 2 3\n", encoding="utf-8")
    err = _error(load_obj, tmp_path / "j.obj")
    assert err.line == 2 and "invisible" in err.message


# ---------------------------------------------------------------- templates are not code

@pytest.mark.parametrize("template", ["f_{frame:999999999d}.obj", "x{frame.__class__.__mro__}.npy",
                                      "{frame!r}.obj", "{frame:4d}.obj", "{frame:013d}.obj", "a{0}{frame}.obj"])
def test_only_frame_fields_may_stand_in_a_template(tmp_path, capsys, template):
    with pytest.raises(ValueError):
        frame_path(template, 1)
    err = _one_line_usage(capsys, ["-obj", str(tmp_path / template), "--frames", "0:2", "-out",
                                   str(tmp_path / "f_{frame}.png")])
    assert "{frame}" in err or "at most 12 digits" in err


def test_frame_fields_format_as_documented():
    assert frame_path("a_{frame}_{frame:04d}.obj", 7) == "a_7_0007.obj"
    assert frame_path("{frame:012d}", 3) == "0" * 11 + "3"


# ---------------------------------------------------------------- numbers: one parser, with a length limit

@pytest.mark.parametrize("flag,value", [("--time-budget", "1_0"), ("--time-budget", "\u0661\u0660"),
                                        ("--target-error", "1_0%"), ("--target-error", "\uff11%"),
                                        ("--frames", "1_0:20"), ("--frames", "\u0660:\u0662"),
                                        ("--frames", "0:99999999999999999999"), ("-sr", "9" * 5000)])
def test_every_numeric_flag_takes_plain_ascii_decimals_only(tmp_path, capsys, flag, value):
    _one_line_usage(capsys, [flag, value, "-out", str(tmp_path / "o.png")])


def test_frame_ranges_are_bounded():
    with pytest.raises(ValueError, match="at most"):
        parse_frames("0:99999999999")


@pytest.mark.parametrize("text,kind", [("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 " + "9" * 5000 + "\n", "obj"),
                                       ("newmtl m\nillum " + "3" * 5000 + "\n", "mtl")])
def test_integers_of_thousands_of_digits_are_scene_errors_with_their_line(tmp_path, text, kind):
    path = tmp_path / f"long.{kind}"
    path.write_text(text)
    err = _error(load_obj if kind == "obj" else load_mtl, path)
    assert err.line in (2, 4) and "digits" in err.message


def test_a_camera_path_frame_of_thousands_of_digits_is_a_scene_error(tmp_path):
    path = tmp_path / "p.json"
    path.write_text('{"keyframes": [{"frame": ' + "9" * 5000 + ', "position": [0, 0, 0], "direction": [0, 1, 0]}]}')
    assert "invalid JSON" in _error(CameraPath.load, path).message


def test_a_camera_path_nested_deeply_is_a_scene_error(tmp_path):
    path = tmp_path / "deep.json"
    path.write_text("[" * 100_000 + "]" * 100_000)
    assert "nested" in _error(CameraPath.load, path).message


# ---------------------------------------------------------------- generators: camera paths and templates

JSON_VALUES = st.recursive(st.none() | st.booleans() | st.integers() | st.floats(allow_nan=True)
                           | st.text(max_size=5), lambda kids: st.lists(kids, max_size=4)
                           | st.dictionaries(st.sampled_from(["frame", "position", "direction", "fov", "focus",
                                                              "aperture", "keyframes", "x"]), kids, max_size=5),
                           max_leaves=20)


@settings(max_examples=300, deadline=None)
@given(doc=st.one_of(JSON_VALUES, st.builds(lambda ks: {"keyframes": ks},
                                            st.lists(st.fixed_dictionaries({}, optional={
                                                "frame": st.integers() | st.floats(), "position": JSON_VALUES,
                                                "direction": JSON_VALUES, "fov": JSON_VALUES}), max_size=4))))
def test_fuzzed_camera_paths_load_or_fail_with_a_scene_error(tmp_path_factory, doc):
    path = tmp_path_factory.mktemp("cp") / "p.json"
    path.write_text(json.dumps(doc))
    try:
        CameraPath.load(path)
    except SceneError:
        pass


@settings(max_examples=300, deadline=None)
@given(template=st.text(alphabet=st.sampled_from(list("{}frame:0123456789d._!r[]x")), max_size=24))
def test_fuzzed_templates_format_or_fail_with_a_value_error(template):
    try:
        name = frame_path(template, 42)
    except ValueError:
        return
    assert len(name) <= len(template) + 12


# ---------------------------------------------------------------- front-end edges

@pytest.mark.parametrize("address,message", [("tls://127.0.0.1:1", "tls:// protocol is not supported"),
                                             ("ucx://127.0.0.1:1", "ucx:// protocol is not supported"),
                                             ("", "expected tcp://HOST:PORT"),
                                             ("tcp://127.0.0.1:70000", "expected tcp://HOST:PORT")])
def test_cluster_addresses_are_checked_while_parsing(tmp_path, capsys, address, message):
    assert message in _one_line_usage(capsys, ["--cluster", address, "-out", str(tmp_path / "o.png")])


def test_an_unreachable_scheduler_fails_within_seconds(tmp_path, capsys):
    pytest.importorskip("dask.distributed")
    t0 = time.perf_counter()
    assert main(["--cluster", "tcp://127.0.0.1:1", "-res", "4", "4", "-sr", "1", "--quiet",
                 "-out", str(tmp_path / "o.png")]) == 1
    err = capsys.readouterr().err
    assert time.perf_counter() - t0 < 20 and "within 5 s" in err and len(err.splitlines()) == 1


@pytest.mark.parametrize("source,message", [(b"\x89PNG\r\n\x1a\n\x00\x00", "cannot import texture module"),
                                            (b"import sys\nsys.exit(0)\n", "called sys.exit(0)")])
def test_a_texture_module_that_is_not_python_or_exits_is_one_error_line(tmp_path, capsys, source, message):
    module = tmp_path / "tex.txt"
    module.write_bytes(source)
    assert main(["--textures", str(module), "-res", "4", "4", "-sr", "1", "-out", str(tmp_path / "o.png")]) == 1
    err = capsys.readouterr().err
    assert len(err.splitlines()) == 1 and message in err and not (tmp_path / "o.png").exists()


def test_a_side_output_that_fails_warns_and_the_render_goes_on(tmp_path, capsys, monkeypatch):
    import errno

    import warp_spt.images.files as images

    real = images.atomic_write

    def full_disk(path, write):                   # the side outputs' disk is full, the image's is not
        if Path(path).name.startswith("side_"):
            raise OSError(errno.ENOSPC, f"cannot write {path}: no space left on device")
        real(path, write)

    monkeypatch.setattr(images, "atomic_write", full_disk)
    status = main(["-res", "8", "8", "-sr", "4", "--target-error", "0.9", "--quiet", "--progressive",
                   str(tmp_path / "side_p.png"), "--error-map", str(tmp_path / "side_e.npy"),
                   "-out", str(tmp_path / "o.png")])
    err = capsys.readouterr().err
    assert status == 0 and (tmp_path / "o.png").exists(), err
    assert "warning: --progressive" in err and "warning: --error-map" in err and ".tmp" not in err


@pytest.mark.parametrize("call,message", [
    (lambda w, s: w.render(None), "scene must be"), (lambda w, s: w.render(s, 5), "camera must be"),
    (lambda w, s: w.parameters(None), "scene must be"), (lambda w, s: w.load_scene("a.obj"), "list of files"),
    (lambda w, s: w.render_scene(s, None, 5), "settings must be")])
def test_api_type_misuse_is_a_type_error_naming_the_expected_type(call, message):
    import warp_spt
    from warp_spt.demo import demo_files

    with pytest.raises(TypeError, match=message):
        call(warp_spt, warp_spt.load_scene(*demo_files()))


# ---------------------------------------------------------------- values that skipped the limits

from warp_spt.device import proctex  # noqa: E402


@pytest.mark.parametrize("line,message", [("map_Kd proc:noise scale=1e39", "must lie in"),
                                          ("map_Kd proc:wood scale=1e20", "must lie in"),
                                          ("map_Kd proc:noise color1=2,2,2", "fills 'map_Kd'"),
                                          ("map_Kd proc:noise color1=-1,0,0", "colour"),
                                          ("map_Ke proc:noise color1=1e38,0,0", "colour"),
                                          ("map_Kd proc:grid width=2", "must lie in")])
def test_procedural_parameters_meet_the_mtl_limits(tmp_path, line, message):
    (tmp_path / "p.mtl").write_text(f"newmtl m\n{line}\n")
    err = _error(load_mtl, tmp_path / "p.mtl")
    assert err.line == 2 and message in err.message


def test_an_emitted_procedural_colour_may_be_bright():
    assert proctex.parse_proc_map([b"proc:noise", b"color2=5,5,5"], "p.mtl", 2, "map_Ke") is not None


@settings(max_examples=60, deadline=None)
@given(name=st.sampled_from(["noise", "marble", "wood", "grid"]), data=st.data())
def test_builtin_textures_are_finite_for_every_accepted_parameter(name, data):
    import numpy as np

    tex = proctex.get_texture(name)
    values = {}
    for (key, default), (low, high) in zip(tex.params, tex.ranges):
        if len(default) == 1:
            values[key] = data.draw(st.sampled_from([low, high, 0.0, default[0]]) | st.floats(low, high))
    ref = proctex.proc_texture(name, **values)
    rng = np.random.default_rng(0)
    p = np.concatenate([rng.normal(size=(60, 3)) * 10.0 ** rng.integers(-3, 15, (60, 1)), [[1e15, -1e15, 3.0]]])
    out = proctex.evaluate([ref], rng.random((len(p), 2)), p, np.tile([0.0, 0.0, 1.0], (len(p), 1)))
    assert np.isfinite(out).all(), (name, values)


@pytest.fixture(scope="module")
def lit_params(tmp_path_factory):
    import warp_spt

    d = tmp_path_factory.mktemp("params")
    (d / "a.obj").write_text("mtllib a.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nusemtl lamp\nb 0 0 2 0.5\n")
    # the seed's dialect (Kl): its reflect slot takes the procedural texture
    (d / "a.mtl").write_text("newmtl m\nKd 0.5 0.5 0.5\nmap_Ks proc:noise\nnewmtl lamp\nKl 4 4 4\n")
    return warp_spt.parameters(warp_spt.load_scene([str(d / "a.obj")]), sky=warp_spt.Sky.gradient())


@pytest.mark.parametrize("name,value", [("m.diffuse", (2.0, 0.5, 0.5)), ("m.diffuse", (1e38, 0, 0)),
                                        ("m.diffuse", (1e39, 0, 0)), ("lamp.emission", (2e30, 0, 0)),
                                        ("m.roughness", 1.5), ("m.fuzz", 1e39), ("sky.zenith", (1e39, 0, 0)),
                                        ("camera.position", (1e39, 0, 0)), ("camera.direction", (0, 0, 0))])
def test_parameter_setters_refuse_what_the_loader_refuses_and_change_nothing(lit_params, name, value):
    from warp_spt.scene.validate import validate_scene

    before = lit_params[name].copy()
    with pytest.raises(ValueError):
        lit_params[name] = value
    assert (lit_params[name] == before).all()
    validate_scene(lit_params.scene.scene)          # the caller's scene is still one the loader accepts


def test_procedural_parameter_setters_follow_the_texture_and_its_slot(lit_params):
    names = [n for n in lit_params.names() if n.startswith("m.reflect_map") or "proc" in n or "noise" in n]
    scale = next(n for n in names if n.endswith(".scale"))
    colour = next(n for n in names if n.endswith(".color1"))
    with pytest.raises(ValueError, match="must lie in"):
        lit_params[scale] = 1e20
    with pytest.raises(ValueError):
        lit_params[colour] = (2.0, 2.0, 2.0)          # it fills a reflectance slot: at most 1
    lit_params[scale] = 8.0


# ---------------------------------------------------------------- every loadable scene can be framed

@settings(max_examples=120, deadline=None)
@given(size=st.sampled_from([1e-12, 1e-10, 1e-9, 1e-6, 1.0, 1e6, 1e12, 1e14, 9e14]),
       offset=st.sampled_from([0.0, 0.3, -0.9]), fov=st.sampled_from([1.0, 38.0, 120.0]),
       up=st.sampled_from(["x", "y", "z", "-y"]))
def test_every_loadable_scene_can_be_framed(tmp_path_factory, size, offset, fov, up):
    import warp_spt

    d = tmp_path_factory.mktemp("frame")
    lo = offset * 1e15 if abs(offset * 1e15) + size <= 1e15 else 0.0
    pts = [(lo, lo, lo), (lo + size, lo, lo), (lo, lo + size, lo), (lo, lo, lo + size)]
    (d / "t.obj").write_text("".join(f"v {x!r} {y!r} {z!r}\n" for x, y, z in pts) + "f 1 2 3\nf 1 2 4\nf 1 3 4\n")
    try:
        scene = warp_spt.load_scene([str(d / "t.obj")])
    except SceneError:
        return                                        # not loadable: nothing to frame
    camera = warp_spt.Camera.frame(scene, up=up, fov=fov)
    camera.validate(64, 48)


@pytest.mark.parametrize("delay", [1.5, 3.0, 6.0])
def test_ctrl_c_to_the_process_group_with_local_workers_is_one_line(tmp_path, delay):
    """A terminal's Ctrl-C reaches the whole process group: the local Dask workers (starting up or
    rendering) stay quiet, the command prints its one line and exits with 130."""
    import signal
    import subprocess
    import sys

    pytest.importorskip("dask.distributed")
    cmd = [sys.executable, "-m", "warp_spt", "--demo", "512p16s", "-res", "128", "128", "-sr", "4096",
           "--workers", "2", "-out", str(tmp_path / "w.png")]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True, start_new_session=True)
    time.sleep(delay)
    os.killpg(proc.pid, signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    # the start-up lines (and, on a machine of 2 cores or fewer, --workers 2's warning; from a cold
    # kernel cache, the compile notice) before it
    lines = [line for line in err.splitlines()
             if not line.startswith(("warp-spt: loaded", "warp-spt: warning: --workers", "warp-spt: compiling"))]
    assert proc.returncode == 130 and lines == ["warp-spt: interrupted"], err


@pytest.mark.parametrize("quiet", [True, False])
def test_library_warnings_are_one_line_and_none_with_quiet(tmp_path, capsys, quiet):
    module = tmp_path / "warns.py"
    module.write_text("import warnings\nwarnings.warn('overflow somewhere', RuntimeWarning)\n")
    argv = ["--textures", str(module), "-res", "4", "4", "-sr", "1", "-out", str(tmp_path / "o.png")]
    assert main(argv + (["--quiet"] if quiet else [])) == 0
    err = capsys.readouterr().err
    warned = [line for line in err.splitlines() if "overflow somewhere" in line]
    assert warned == ([] if quiet else ["warp-spt: warning: overflow somewhere"]), err
    assert "warnings.warn" not in err                 # no source line


@settings(max_examples=150, deadline=None)
@given(data=st.data())
def test_fuzzed_parameter_values_are_taken_or_refused_leaving_a_valid_scene(lit_params, data):
    import numpy as np

    from warp_spt.scene.validate import validate_scene

    name = data.draw(st.sampled_from(lit_params.names()))
    shape = lit_params.info(name).shape
    num = st.sampled_from([0.0, 0.5, 1.0, 1.5, -1.0, 1e30, 2e30, 1e38, 1e39, -1e39, 3.4e38]) | st.floats(-1e40, 1e40)
    value = np.array([data.draw(num) for _ in range(int(np.prod(shape)) or 1)]).reshape(shape)
    before = lit_params[name].copy()
    try:
        lit_params[name] = value
    except ValueError:
        assert np.array_equal(lit_params[name], before, equal_nan=True)
    validate_scene(lit_params.scene.scene)
    lit_params.camera.validate(8, 8)
    lit_params[name] = before                          # the next example starts from the same scene


@pytest.mark.parametrize("entry", ["render_scene", "render_progressive"])
def test_cluster_entry_points_check_the_scene_type_before_the_client(entry):
    pytest.importorskip("dask.distributed")
    from warp_spt import cluster

    with pytest.raises(TypeError, match="scene must be"):
        getattr(cluster, entry)(None, None)
