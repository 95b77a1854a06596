"""Issue 21, the third hardening round: the inputs that still got through. One test per class;
the generators at the end fuzz camera paths and frame templates so the classes stay closed."""

from __future__ import annotations

import json
import os
import resource
import threading
import time

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
