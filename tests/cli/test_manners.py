"""The command line's manners (issue 43, item 7): a typo gets a suggestion, usage errors and the
flags of ``--help`` come before Warp is imported, a missing --env map is reported before the scene is
read, --fov zooms a framed model, and the integrators' internal options are listed last."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from warp_spt.cli.common import UsageError
from warp_spt.cli.options import parse_args

REPO = Path(__file__).resolve().parents[2]


def in_a_fresh_process(code: str) -> str:
    done = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    return done.stdout


@pytest.mark.parametrize("typo, meant", [("--fvo", "--fov"), ("-ob", "-obj"), ("--envv", "--env"),
                                         ("--smooth-angel", "--smooth-angle")])
def test_a_typo_gets_did_you_mean(typo, meant):
    with pytest.raises(UsageError, match=f"unknown flag '{typo}'; did you mean {meant}\\?"):
        parse_args([typo, "1"])


def test_a_flag_like_no_other_gets_no_suggestion():
    with pytest.raises(UsageError) as err:
        parse_args(["--zzzzzzzz"])
    assert "did you mean" not in str(err.value)


def test_usage_errors_and_parsing_import_no_warp(tmp_path):
    """What makes them instant: Warp's import and start (seconds on a loaded machine) come after parsing."""
    code = f"""
import contextlib, io, sys
from warp_spt.cli.main import main
from warp_spt.cli.options import build_parser, parse_args
err = io.StringIO()
with contextlib.redirect_stderr(err):
    status = main(["--fvo", "30"])
build_parser().format_help()
parse_args(["-obj", "model.obj", "--fov", "20", "--sun", "0", "-1", "-1", "-out", {str(tmp_path / 'a.png')!r}])
print(status, "warp" in sys.modules, err.getvalue().strip())
"""
    status, warp_loaded, line = in_a_fresh_process(code).split(" ", 2)
    assert (status, warp_loaded) == ("2", "False"), line
    assert "did you mean --fov?" in line


def test_a_missing_env_map_is_reported_before_the_scene_is_read(tmp_path):
    model = tmp_path / "m.obj"
    model.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    code = f"""
import contextlib, io, sys
import warp_spt.io.loader as loader
from warp_spt.cli.main import main
def refuse(*a, **k):
    raise AssertionError("the scene was read")
loader.load_scene = refuse
err = io.StringIO()
with contextlib.redirect_stderr(err):
    status = main(["-obj", {str(model)!r}, "--env", {str(tmp_path / 'missing.hdr')!r}, "-out", {str(tmp_path / 'o.png')!r}])
print(status, "warp" in sys.modules, err.getvalue().strip())
"""
    status, warp_loaded, line = in_a_fresh_process(code).split(" ", 2)
    assert (status, warp_loaded) == ("1", "False"), line
    assert line.startswith("warp-spt: error: cannot read --env file") and "missing.hdr" in line


def test_help_lists_the_users_flags_first_and_the_integrators_options_last(capsys):
    from warp_spt.cli.main import main

    assert main(["--help"]) == 0
    text = capsys.readouterr().out
    flags, examples = text.index("your own models:"), text.index("examples:")
    internal = text.index("integrator parameters (--integrator-option")
    assert flags < examples < internal
    assert "q_min" in text[internal:] and "q_min" not in text[:internal]     # ears' internals, at the end


def test_helps_first_screen_shows_the_users_flags_in_order(capsys):
    """A 24-line terminal's first screen: a one-line usage, then the seed's flags in the parser's
    order (argparse's own usage listed every flag, 23 lines); every flag of the parser appears, in
    order, before the integrators' internal parameters."""
    from warp_spt.cli.main import main
    from warp_spt.cli.options import build_parser

    assert main(["--help"]) == 0
    text = capsys.readouterr().out
    lines = text.splitlines()
    assert lines[0].startswith("usage: warp-spt ") and lines[1] == "", lines[:3]
    first_screen = "\n".join(lines[:24])
    for flag in ("-obj", "-mtl", "-cam", "-res", "-depth", "-sr", "-sky", "-out"):
        assert f"\n  {flag} " in first_screen, flag
    import argparse
    flags = [a.option_strings[0] for a in build_parser()._actions if a.option_strings and a.help != argparse.SUPPRESS]
    where = [text.index(f"\n  {f}") for f in flags]
    internal = text.index("integrator parameters (--integrator-option")
    assert where == sorted(where) and where[-1] < internal
    assert not any(q in text[:internal] for q in ("q_min", "spatial_c", "train_fraction"))


def test_fov_zooms_a_framed_model(tmp_path):
    """The framing places the camera as the default lens frames the model; --fov then narrows or
    widens the view from there (framing at the given fov moved the camera back: the same picture)."""
    from tests.support.models import write_model
    from warp_spt.io.loader import load_scene
    from warp_spt.rendering.first_view import first_view
    from warp_spt.scene.camera import Camera

    scene = load_scene([str(write_model(tmp_path / "b.obj", shape="bunny"))])
    views = {fov: first_view(scene, Camera().with_(fov=fov), width=16, height=16, keep_camera=False,
                             seed_camera=False, fixed=False, studio=False) for fov in (38.0, 15.0)}
    default, zoomed = views[38.0].camera, views[15.0].camera
    assert views[15.0].framed and zoomed.fov == 15.0
    assert np.allclose(zoomed.position, default.position) and np.allclose(zoomed.direction, default.direction)
