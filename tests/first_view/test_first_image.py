"""Your own model, right the first time (issue 22): upright, in frame and lit with no flags.

The models and the checks are in :mod:`tests.support.first_image` (shared with
``scripts/first_image_table.py``, which makes the closing note's before/after table). The seed's own
command lines keep rendering bit for bit as before: tests/first_view/test_models.py and tests/house/test_house_hashes.py.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np
import pytest

from tests.support.first_image import MODELS, SEED_LOOK, SIZE, printed_camera, run_case, write_case
from warp_spt.cli.main import run
from warp_spt.cli.options import parse_args


def cli(argv: list[str], out: Path) -> tuple[np.ndarray, str]:
    """Run the CLI in-process; the linear image and what it printed."""
    err = io.StringIO()
    assert run(parse_args([*argv, "-out", str(out)]), stderr=err) == 0, err.getvalue()
    return np.load(out), err.getvalue()


@pytest.mark.parametrize("name", list(MODELS))
def test_the_first_image_is_upright_in_frame_and_lit(tmp_path, name):
    v = run_case(tmp_path, name, cli)
    assert v.upright, f"{name}: {v.row()}"
    assert v.in_frame, f"{name}: {v.row()}"
    if name not in SEED_LOOK:         # its own materials under the seed's sky: the seed's look, kept
        assert v.lit, f"{name}: {v.row()}"


def test_the_framed_line_says_which_way_is_up_and_its_cam_reproduces_the_image(tmp_path):
    obj, _ = write_case(tmp_path, "cow, Y up")
    size = ["-res", "40", "30", "-sr", "2"]
    first, said = cli(["-obj", obj, *size], tmp_path / "a.npy")
    line = next(s for s in said.splitlines() if "framed the scene" in s)
    assert "Y up (a standard OBJ model; --up z to change)" in line
    assert "studio look: the scene has no light of its own" in said and "--no-studio" in said
    again = re.search(r"-cam (.*)$", line).group(1).split()
    second, said2 = cli(["-obj", obj, "-cam", *again, *size], tmp_path / "b.npy")
    assert "framed the scene" not in said2
    assert np.array_equal(second, first)          # the printed numbers are the camera's, exactly


def test_a_flat_cut_out_is_framed_face_on(tmp_path):
    obj, _ = write_case(tmp_path, "flat cut-out, Y up")
    _, said = cli(["-obj", obj, "-res", "24", "18", "-sr", "1"], tmp_path / "f.npy")
    cam, up, framed = printed_camera(said, "z")
    assert framed and up == "y" and "face-on" in said
    assert abs(np.dot(cam.direction, (0.0, 0.0, -1.0))) > 0.999        # along the plane's normal


@pytest.mark.parametrize("view, towards", [("front", (0, 0, 1)), ("back", (0, 0, -1)), ("right", (1, 0, 0)),
                                           ("left", (-1, 0, 0)), ("top", (0, 1, 0)), ("bottom", (0, -1, 0)),
                                           ("90,0", (1, 0, 0))])
def test_view_names_the_side_the_camera_stands_on(tmp_path, view, towards):
    obj, _ = write_case(tmp_path, "cow, Y up")
    _, said = cli(["-obj", obj, f"--view={view}", "-res", "16", "12", "-sr", "1"], tmp_path / "v.npy")
    cam, up, _ = printed_camera(said, "z")
    assert up == "y" and np.allclose(-np.asarray(cam.direction), towards, atol=1e-6)


def test_orbit_and_look_at_combine(tmp_path):
    obj, _ = write_case(tmp_path, "cow, Y up")
    _, said = cli(["-obj", obj, "--orbit", "-30", "10", "--look-at", "1.2", "1.3", "0", "--fov", "50",
                   "-res", "16", "12", "-sr", "1"], tmp_path / "o.npy")
    cam, _, _ = printed_camera(said, "z")
    assert cam.fov == 50
    target = np.asarray(cam.position) + cam.focus * np.asarray(cam.direction)
    assert np.allclose(target, (1.2, 1.3, 0.0), atol=1e-4)        # looks at --look-at, focused there


def test_a_bottom_view_sees_the_model_without_the_studio_ground(tmp_path):
    v = run_case(tmp_path, "cow, Y up", cli, extra=("--view", "bottom"))
    assert v.in_frame and v.lit, v.row()          # not hidden behind the ground's underside


def test_no_studio_and_a_sky_flag_turn_the_studio_off(tmp_path):
    obj, _ = write_case(tmp_path, "cow, Y up")
    for flags in (["--no-studio"], ["-sky", "1"], ["--sky-color", "0.5", "0.5", "0.5"]):
        _, said = cli(["-obj", obj, *flags, "-res", "8", "6", "-sr", "1"], tmp_path / "n.npy")
        assert "studio look" not in said, flags


def test_the_seeds_dialect_keeps_z_up_and_the_seeds_camera(tmp_path):
    """A Z-up model written in the seed's dialect (an MTL with its Roughness tag) that the seed's
    default camera sees whole keeps that camera: nothing framed, nothing added."""
    obj, _ = write_case(tmp_path, "cow, Z up, seed's MTL dialect")
    text = Path(obj).read_text().splitlines()
    moved = [(f"v {float(a) * 8 + 4:.6g} {float(b) * 8:.6g} {float(c) * 8 + 4:.6g}" if t == "v" else line)
             for line in text for t, a, b, c in [(line.split() + ["", "", "", ""])[:4]]]
    Path(obj).write_text("\n".join(moved) + "\n")
    _, said = cli(["-obj", obj, "-res", "16", "16", "-sr", "1"], tmp_path / "s.npy")
    assert "framed the scene" not in said and "studio look" not in said, said


def test_exposure_scales_the_tone_mapped_image_only(tmp_path):
    from PIL import Image

    obj, _ = write_case(tmp_path, "cow, Y up")
    base = ["-obj", obj, "-res", "16", "12", "-sr", "2", "--quiet"]
    err = io.StringIO()
    for ev, name in ((0, "a.png"), (-1, "b.png")):
        assert run(parse_args([*base, "--exposure", str(ev), "-out", str(tmp_path / name)]), stderr=err) == 0
    a, b = (np.asarray(Image.open(tmp_path / n), dtype=np.float64) for n in ("a.png", "b.png"))
    assert b.mean() < 0.85 * a.mean()
    from warp_spt.cli.common import UsageError
    with pytest.raises(UsageError, match="tone-mapped"):
        parse_args([*base, "--exposure", "1", "-out", "x.exr"])
    with pytest.raises(UsageError, match="exposure"):
        parse_args([*base, "--exposure", "99"])


def test_white_model_in_the_studio_is_not_washed_out(tmp_path):
    """A white (Kd 1) model under --studio: no pixel of it above 1 (the studio's levels), and the
    backdrop darker than the model."""
    from tests.support.first_image import judge  # noqa: F401  (same model files)
    obj, _ = write_case(tmp_path, "cow, Y up")
    (tmp_path / "white.mtl").write_text("newmtl white\nKd 1 1 1\n")
    Path(obj).write_text("mtllib white.mtl\nusemtl white\n" + Path(obj).read_text())
    img, said = cli(["-obj", obj, "--studio", "-res", str(SIZE[0]), str(SIZE[1]), "-sr", "16"], tmp_path / "w.npy")
    assert "studio look" not in said        # asked for, not announced as a default
    assert np.percentile(img, 99.5) < 1.0
    assert img[:5].mean() < 0.5 * np.percentile(img, 99)     # the sky behind: darker than the lit model
