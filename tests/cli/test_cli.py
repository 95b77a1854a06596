"""The warp-spt command line: every flag, every error, exit codes, one-line messages (no rendering)."""

from __future__ import annotations

import io
import subprocess
import sys
from pathlib import Path

import pytest
import tomllib

from warp_spt.cli.common import UsageError
from warp_spt.cli.main import main
from warp_spt.cli.options import PRESETS, parse_args
from warp_spt.cli.render import ProgressBar
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

REPO = Path(__file__).resolve().parents[2]
SEED_DEMO_ARGS = ["-mtl", "testMiku.mtl", "-obj", "cornell_export.obj", "-obj", "baller.obj",
                  "-sky", "1", "-res", "512", "512", "-sr", "16", "-depth", "8", "-out", "512p16s.png"]


def run_main(argv, capsys):
    """(exit status, stdout, stderr) of an in-process run."""
    status = main(argv)
    out, err = capsys.readouterr()
    return status, out, err


# ---------------------------------------------------------------- defaults and the seed's flags

def test_no_arguments_is_the_builtin_demo_at_the_seeds_defaults():
    o = parse_args([])
    assert o.action == "render" and o.uses_demo_scene and o.demo is None
    assert (o.width, o.height, o.spp, o.depth) == (500, 500, 16, 6)
    assert o.sky == Sky(0, (0.3, 0.6, 0.8))          # the seed's blue 'BlackSky' (Q2)
    assert o.out == "output.png"                       # the Readme's name, not the code's Output.png (Q14)
    assert o.camera == Camera((4.0, -55.0, 16.0), (0.0, 1.0, 0.0), 38.0, 0.001, 27.0)
    assert (o.tonemap, o.texture_filter, o.seed, o.threads, o.quiet) == (None, "nearest", 0, None, False)


def test_the_seeds_demo_command_line_parses_unchanged():
    o = parse_args(SEED_DEMO_ARGS)
    assert o.objs == ("cornell_export.obj", "baller.obj") and o.mtls == ("testMiku.mtl",)
    assert (o.width, o.height, o.spp, o.depth, o.out) == (512, 512, 16, 8, "512p16s.png")
    assert o.sky == Sky(1, (0.0, 0.0, 0.0)) and not o.uses_demo_scene


def test_obj_and_mtl_repeat_in_any_order_and_keep_their_order():
    o = parse_args(["-obj", "a.obj", "-mtl", "m.mtl", "-obj", "b.obj", "-mtl", "n.mtl", "-obj", "c.obj"])
    assert o.objs == ("a.obj", "b.obj", "c.obj") and o.mtls == ("m.mtl", "n.mtl")


def test_cam_follows_the_design_documents_order_fov_focus_aperture():
    o = parse_args(["-cam", "1", "-2.5", "3", "0", "1", "-0.25", "40", "20", "0.5"])
    assert o.camera.position == (1.0, -2.5, 3.0) and o.camera.direction == (0.0, 1.0, -0.25)
    assert (o.camera.fov, o.camera.focus, o.camera.aperture) == (40.0, 20.0, 0.5)


@pytest.mark.parametrize("k, sky", [("0", Sky(0, (0.3, 0.6, 0.8))), ("1", Sky(1, (0.0, 0.0, 0.0))),
                                    ("2", Sky(0, (1.0, 0.431, 0.888)))])
def test_sky_index(k, sky):
    assert parse_args(["-sky", k]).sky == sky


def test_res_depth_sr_out():
    o = parse_args(["-res", "64", "32", "-depth", "3", "-sr", "5", "-out", "x.pfm"])
    assert (o.width, o.height, o.depth, o.spp, o.out) == (64, 32, 3, 5, "x.pfm")


def test_a_repeated_flag_keeps_its_last_value_like_the_seed():
    o = parse_args(["-sr", "4", "-res", "8", "8", "-sr", "7", "-res", "9", "10", "-out", "a.png", "-out", "b.npy"])
    assert (o.spp, o.width, o.height, o.out) == (7, 9, 10, "b.npy")


@pytest.mark.parametrize("suffix", [".png", ".npy", ".pfm", ".PNG", ".jpg", ".jpeg", ".exr"])
def test_output_formats(suffix):
    assert parse_args(["-out", "dir/img" + suffix]).out == "dir/img" + suffix


# ---------------------------------------------------------------- the new options

def test_modern_options():
    o = parse_args(["--threads", "3", "--seed", "42", "--sky-color", "0", "0.5", "1", "--tonemap", "srgb",
                    "--filter", "bilinear", "--quiet"])
    assert (o.threads, o.seed, o.tonemap, o.texture_filter, o.quiet) == (3, 42, "srgb", "bilinear", True)
    assert o.sky == Sky(0, (0.0, 0.5, 1.0))


def test_sky_color_black_is_a_truly_black_sky():
    assert parse_args(["--sky-color", "0", "0", "0"]).sky.color == (0.0, 0.0, 0.0)


def test_options_of_the_form_flag_equals_value():
    assert parse_args(["--seed=9", "--tonemap=srgb"]).seed == 9


@pytest.mark.parametrize("name, w, spp", [("512p16s", 512, 16), ("512p32s", 512, 32), ("1440p32s", 1440, 32),
                                          ("2560p32s", 2560, 32), ("2560p256s", 2560, 256)])
def test_demo_presets_mirror_the_seeds_scripts(name, w, spp):
    o = parse_args(["--demo", name], memory_bytes=1 << 40)
    assert (o.width, o.height, o.spp, o.depth) == (w, w, spp, 8)
    assert o.sky == Sky.gradient() and o.out == f"{name}.png" and o.uses_demo_scene
    assert name in PRESETS


def test_explicit_flags_override_a_preset():
    o = parse_args(["--demo", "512p16s", "-sr", "2", "-res", "16", "8", "-out", "t.npy", "--sky-color", "0", "0", "0"])
    assert (o.spp, o.width, o.height, o.out, o.depth, o.sky.color) == (2, 16, 8, "t.npy", 8, (0.0, 0.0, 0.0))


def test_help_lists_every_flag_and_examples(capsys):
    status, out, err = run_main(["--help"], capsys)
    assert status == 0 and err == ""
    for flag in ["-obj", "-mtl", "-cam", "-res", "-depth", "-sr", "-sky", "-out", "--version", "--threads",
                 "--seed", "--sky-color", "--tonemap", "--quiet", "--demo", "--filter", "examples:"]:
        assert flag in out
    assert main(["-h"]) == 0


def test_version_matches_the_package_metadata(capsys):
    expected = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["version"]
    status, out, _ = run_main(["--version"], capsys)
    assert status == 0 and out.strip() == f"warp-spt {expected}"


# ---------------------------------------------------------------- every bad argument: one line, exit 2

BAD = [
    (["-obj"], "-obj"), (["-mtl"], "-mtl"), (["-out"], "-out"), (["-res", "64"], "-res"),
    (["-cam", "1", "2", "3"], "-cam"), (["-depth"], "-depth"), (["-sr"], "-sr"), (["-sky"], "-sky"),
    (["-sr", "x"], "-sr"), (["-depth", "2.5"], "-depth"), (["-res", "a", "b"], "-res"),
    (["-cam", "0", "0", "0", "0", "1", "0", "x", "27", "0.001"], "-cam"),
    (["-cam", "0", "0", "0", "0", "1", "0", "nan", "27", "0.001"], "-cam"),
    (["-res", "0", "10"], "-res"), (["-res", "10", "-3"], "-res"), (["-sr", "0"], "-sr"),
    (["-sr", "-4"], "-sr"), (["-depth", "0"], "-depth"), (["-sky", "3"], "-sky"), (["-sky", "-1"], "-sky"),
    (["--threads", "0"], "--threads"), (["--seed", "-1"], "--seed"), (["--seed", "1.5"], "--seed"),
    (["--sky-color", "1", "1"], "--sky-color"), (["--sky-color", "-1", "0", "0"], "--sky-color"),
    (["--tonemap", "aces"], "--tonemap"), (["--filter", "cubic"], "--filter"), (["--demo", "4k"], "--demo"),
    (["--frobnicate"], "--frobnicate"), (["-ob", "x.obj"], "-ob"), (["-o", "x.png"], "-o"),
    (["-res", "8", "8", "8"], "unrecognized"), (["stray"], "unrecognized"),
    (["-cam", "0", "0", "0", "0", "0", "0", "38", "27", "0.001"], "direction"),
    (["-cam", "0", "0", "0", "0", "1", "0", "180", "27", "0.001"], "fov"),
    (["-cam", "0", "0", "0", "0", "1", "0", "38", "0", "0.001"], "focus"),
    (["-cam", "0", "0", "0", "0", "1", "0", "38", "27", "-1"], "aperture"),
    (["-out", "picture.gif"], ".png, .jpg, .npy, .pfm or .exr"), (["-out", "noext"], ".png, .jpg, .npy, .pfm or .exr"),
    (["-mtl", "a.mtl"], "-mtl given without"), (["--demo", "512p16s", "-obj", "a.obj"], "--demo"),
    (["-sky", "1", "--sky-color", "0", "0", "0"], "either -sky or --sky-color"),
    (["-res", "200000", "200000"], "GiB"), (["-sr", str(1 << 30)], "-sr"), (["-depth", "100000"], "-depth"),
]


@pytest.mark.parametrize("argv, mentions", BAD, ids=[" ".join(a) for a, _ in BAD])
def test_bad_arguments_give_one_line_and_exit_2(argv, mentions, capsys):
    status, out, err = run_main(argv, capsys)
    assert status == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("warp-spt: error: ")
    assert mentions in err and "Traceback" not in err


def test_parse_args_raises_usage_error():
    with pytest.raises(UsageError, match="-sr"):
        parse_args(["-sr", "0"])


def test_image_size_is_checked_against_the_memory_budget():
    with pytest.raises(UsageError, match="-res 100 100"):
        parse_args(["-res", "100", "100"], memory_bytes=100 * 100 * 8)
    assert parse_args(["-res", "100", "100"], memory_bytes=1 << 30).width == 100


# ---------------------------------------------------------------- files: exit 1, one line naming the file

def one_error_line(err: str) -> str:
    assert err.count("\n") == 1 and err.startswith("warp-spt: error: ") and "Traceback" not in err
    return err


def test_missing_obj_file(tmp_path, capsys):
    missing = str(tmp_path / "nope.obj")
    status, _, err = run_main(["-obj", missing, "-out", str(tmp_path / "o.png")], capsys)
    assert status == 1 and missing in one_error_line(err) and "-obj" in err
    assert not (tmp_path / "o.png").exists()


def test_missing_mtl_file(tmp_path, capsys):
    obj = tmp_path / "a.obj"
    obj.write_text("b 0 0 0 1\n")
    status, _, err = run_main(["-obj", str(obj), "-mtl", str(tmp_path / "m.mtl"), "-out", str(tmp_path / "o.png")],
                              capsys)
    assert status == 1 and "m.mtl" in one_error_line(err) and "-mtl" in err


def test_a_directory_given_as_obj(tmp_path, capsys):
    status, _, err = run_main(["-obj", str(tmp_path), "-out", str(tmp_path / "o.png")], capsys)
    assert status == 1 and str(tmp_path) in one_error_line(err)


def test_output_directory_missing(tmp_path, capsys):
    obj = tmp_path / "a.obj"
    obj.write_text("b 0 0 0 1\n")
    out = tmp_path / "no" / "such" / "o.png"
    status, _, err = run_main(["-obj", str(obj), "-out", str(out)], capsys)
    assert status == 1 and "does not exist" in one_error_line(err)


# ---------------------------------------------------------------- progress bar

def test_progress_bar_counts_samples_and_shows_a_rate():
    sink = io.StringIO()
    bar = ProgressBar(16 * 16 * 4, file=sink, delay=0.0)
    for done in range(1, 9):
        bar(done, 8)
    assert bar._bar.n == 16 * 16 * 4
    bar.close()
    text = sink.getvalue()
    assert "1.02k/1.02k" in text and "sample/s" in text


# ---------------------------------------------------------------- as a real process: no traceback ever

def run_process(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "warp_spt", *args], cwd=REPO, capture_output=True, text=True,
                          timeout=120)


def test_process_help_and_version():
    helped = run_process("--help")
    assert helped.returncode == 0 and "-cam" in helped.stdout and helped.stderr == ""
    version = run_process("--version")
    assert version.returncode == 0 and version.stdout.startswith("warp-spt ")


@pytest.mark.parametrize("args", [("--nope",), ("-res", "0", "0"), ("-obj", "/nonexistent/x.obj")])
def test_process_bad_input_is_one_line_without_traceback(args):
    done = run_process(*args)
    assert done.returncode in (1, 2) and done.stdout == ""
    assert done.stderr.count("\n") == 1 and done.stderr.startswith("warp-spt: error: ")


def test_help_lists_the_registries_plugins_with_their_summaries(capsys):
    """--integrator and --sampler help is generated from the registries (a new plugin shows up)."""
    from warp_spt.cli.main import main as cli_main
    from warp_spt.integrators import INTEGRATORS
    from warp_spt.samplers import SAMPLERS, get_sampler

    assert cli_main(["--help"]) == 0
    text = " ".join(capsys.readouterr().out.split())
    for name, record in INTEGRATORS.items():
        assert f"{name} {' '.join(record.summary.split())}" in text
    for name in SAMPLERS:
        assert f"{name} {' '.join(get_sampler(name).summary.split())}" in text


def test_view_without_its_extra_says_how_to_install_it(monkeypatch, capsys):
    import importlib.util

    from warp_spt.cli.main import main as cli_main

    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda name, *a: None if name == "aiohttp" else real(name, *a))
    assert cli_main(["view", "--no-browser"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and 'pip install ".[view]" in the warp_spt clone' in err and "internal error" not in err


# ---------------------------------------------------------------- --workers on a small machine

def test_workers_as_many_as_the_cores_warn_once(tmp_path, monkeypatch, capsys):
    """Each worker renders on every core: --workers 2 on a 2-core machine was slower than one process."""
    from contextlib import contextmanager

    from warp_spt.cli import animation
    from warp_spt.cli.common import RunError
    from warp_spt.runtime import threads

    @contextmanager
    def no_cluster(opts):                     # the warning comes before any worker starts: stop there
        raise RunError("no cluster in this test")
        yield

    monkeypatch.setattr(threads, "cores", lambda: 2)
    monkeypatch.setattr(animation, "cluster_client", no_cluster)
    obj = tmp_path / "a.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    base = ["-obj", str(obj), "-res", "8", "8", "-cam", "0.3", "0.3", "3", "0", "0", "-1", "40", "3", "0",
            "-out", str(tmp_path / "o.png")]
    status, _, err = run_main(base + ["--workers", "2"], capsys)
    assert status == 1 and err.count("warning: --workers") == 1
    assert ("warning: --workers 2 on a 2-core machine: each worker already uses every core; one process is "
            "usually faster") in err
    status, _, err = run_main(base + ["--workers", "1"], capsys)
    assert status == 1 and "warning: --workers" not in err
