"""The up axis of scans and other formats (issue 43, item 3).

A PLY file has no up convention: its header's comments (an axis named with "up", or the writer:
Blender writes Z up, the Stanford repository's zippered scans are Y up) decide, "sure"; else its
shape: a flat base or floor in the XY plane, or the axis it stands on without tipping over,
"likely"; else Y, "a guess". glTF (and USD, turned Y up when read) is Y up by its specification:
its line never suggests --up. Each line names the file's format. A standard OBJ's cut base is
found when it is tilted a little (a scan's, not quite a plane of the file's axes), and the
project's own Z-up smoke scenes (scripts/make_smoke.py) stand on their floor. A standard OBJ
stays Y up unless it stands only with Z up (a bust whose base is open, a horse).

The models are tests/support/models.py's; whether an image is upright is judged by
tests/support/first_image.judge, which shares no shading or framing code with the renderer.
"""

from __future__ import annotations

import importlib.util
import io
from pathlib import Path

import numpy as np
import pytest

from tests.support.first_image import SIZE, judge
from tests.support.format_files import GltfBuilder
from tests.support.models import SHAPES, write_model
from warp_spt.io.loader import load_scene
from warp_spt.rendering.first_view import choose_up
from warp_spt.scene.conventions import up_axis

ROOT = Path(__file__).resolve().parents[2]


def _up(path: Path, mtls=()):
    return choose_up(load_scene([str(path)], [str(m) for m in mtls], warn=lambda m: None))


@pytest.mark.parametrize("shape, up, comments, axis, words", [
    ("bust", "z", (), "z", "a PLY model standing on a flat base or floor in the XY plane; likely"),
    # a horse on its hooves
    ("cow", "z", (), "z", "a PLY model that stands on its lowest points with Z up; likely"),
    ("cow", "y", (), "y", "a PLY model that stands on its lowest points with Y up; likely"),
    ("bust", "y", (), "y", "likely"),
    ("plaque", "y", (), "y", "likely"),             # a relief lying on its back stands too: not Z
    ("teapot", "z", ("Created by Blender 3.6.0 - www.blender.org",), "z",
     "written by Blender, which exports Z up; sure"),
    ("bunny", "y", ("zipper output",), "y", "a Stanford zippered scan, which are Y up; sure"),
    ("bunny", "z", ("up_axis: Z",), "z", "its header says 'up_axis: Z'; sure"),
    ("teapot", "z", ("VCGLIB generated",), "y",
     "PLY has no up convention and neither its header nor its shape tells; a guess"),
])
def test_a_ply_files_up_axis_comes_from_its_header_or_its_shape(tmp_path, shape, up, comments, axis, words):
    choice = _up(write_model(tmp_path / "scan.ply", shape, up=up, ply_comments=comments))
    assert choice.axis == axis and words in choice.note and "a PLY model" in choice.note, choice.note
    assert choice.note.endswith(f"; --up {'y' if axis == 'z' else 'z'} to change)")


def test_each_format_is_named_and_gltf_never_suggests_up(tmp_path):
    # the Z-up bust, written as glTF: before, its flat base made it Z up ("a scan standing..."), against glTF's Y
    pts, faces, base = [], [], 0
    for p, f in SHAPES["bust"]():
        pts.append(p)
        faces.append(f + base)
        base += len(p)
    g = GltfBuilder()
    g.node(mesh=g.mesh(np.concatenate(pts), np.concatenate(faces)))
    (tmp_path / "bust.gltf").write_bytes(g.gltf()[0])
    choice = _up(tmp_path / "bust.gltf")
    assert (choice.axis, choice.definite, choice.note) == ("y", True, "Y up (glTF is Y up by definition)")
    assert "--up" not in choice.note and "OBJ" not in choice.note
    obj = _up(write_model(tmp_path / "cow.obj", "cow", up="y"))
    assert obj.note == "Y up (a standard OBJ model; --up z to change)"
    # the rule itself, per format and mixed
    assert up_axis(None, demo=False, seed_dialect=False, cam_given=False, formats=("USD",)).note == \
        "Y up (a USD stage, turned Y up from its upAxis when read)"
    mixed = up_axis(None, demo=False, seed_dialect=False, cam_given=False, formats=("OBJ", "PLY", "OBJ"))
    assert "OBJ and PLY models" in mixed.note and "--up z" in mixed.note
    assert up_axis(None, demo=False, seed_dialect=False, cam_given=False, formats=("glTF", "OBJ")).note == \
        "Y up (glTF and OBJ models; --up z to change)"
    assert up_axis("z", demo=False, seed_dialect=False, cam_given=False, formats=("glTF",)).note == ""   # --up wins


@pytest.mark.parametrize("tilt", [1.5, -2.0])
def test_a_scans_slightly_tilted_cut_base_is_found(tmp_path, tilt):
    """A bust whose cut base is turned 1.5-2 degrees off the XY plane (as a scanner's frame leaves
    it): before, only faces exactly in the lowest plane counted, and it lay on its back."""
    choice = _up(write_model(tmp_path / "bust.obj", "bust", tilt=tilt))
    assert choice.axis == "z" and "flat base" in choice.note, choice.note
    assert _up(write_model(tmp_path / "bust_y.obj", "bust", up="y", tilt=tilt)).axis == "y"


@pytest.mark.parametrize("shape, up, axis", [("bust_open", "z", "z"), ("cow", "z", "z"), ("bust_open", "y", "y"),
                                             ("cow", "y", "y"), ("teapot", "z", "y"), ("bunny", "z", "y")])
def test_a_standard_obj_that_stands_only_z_up_is_z_up(tmp_path, shape, up, axis):
    """OBJ's convention is Y up: a model turns Z up only when it stands with Z up and tips over with
    Y up (a bust whose cut base is left open, no faces across it; a horse on its hooves); a shape
    that does not tell (the teapot, the blob) keeps the convention, as any Y-up model does."""
    choice = _up(write_model(tmp_path / f"{shape}.obj", shape, up=up))
    assert choice.axis == axis, choice.note
    if axis == "z":
        assert "a standard OBJ model that stands on its lowest points only with Z up" in choice.note
        assert "likely; --up y to change" in choice.note
    else:
        assert choice.note == "Y up (a standard OBJ model; --up z to change)"


def test_the_projects_own_smoke_scenes_are_z_up(tmp_path):
    spec = importlib.util.spec_from_file_location("make_smoke", ROOT / "scripts" / "make_smoke.py")
    make_smoke = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(make_smoke)
    make_smoke.write_scenes(tmp_path, 8)
    for name in ("smoke", "shafts", "liquid"):
        choice = _up(tmp_path / f"{name}.obj", [tmp_path / f"{name}.mtl"])
        assert choice.axis == "z" and "floor in the XY plane" in choice.note, (name, choice.note)


def test_a_z_up_ply_horse_stands_upright_in_the_first_image(tmp_path):
    """The whole command: ``-obj horse.ply`` (the cow stand-in, Z up, no header comment), judged
    upright by the probe of tests/support/first_image (before: Y up, on its side)."""
    from warp_spt.cli.main import run
    from warp_spt.cli.options import parse_args

    ply = str(write_model(tmp_path / "horse.ply", "cow", up="z", ply_comments=()))
    err = io.StringIO()
    out = tmp_path / "first.npy"
    argv = ["-obj", ply, "-res", str(SIZE[0]), str(SIZE[1]), "-sr", "4", "-out", str(out)]
    assert run(parse_args(argv), stderr=err) == 0, err.getvalue()
    said = err.getvalue()
    assert "Z up (a PLY model that stands on its lowest points with Z up; likely; --up y to change)" in said, said
    v = judge(ply, "z", np.load(out), said, "z")
    assert v.up == "z" and v.upright and v.in_frame, v.row()


def test_each_reader_records_its_format_for_the_api_too(tmp_path):
    """``ObjData.format`` comes from the reader itself, so load_scene of parsed files (the API, OBJ
    sequences) names the format as ``-obj`` does; a PLY file under an .obj name is a PLY model."""
    from warp_spt.gltf import load_gltf
    from warp_spt.io.obj import load_obj
    from warp_spt.io.ply import load_ply

    ply = write_model(tmp_path / "scan.ply", "cow", ply_comments=())
    obj = write_model(tmp_path / "cow.obj", "cow", up="y")
    g = GltfBuilder()
    g.node(mesh=g.mesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], float), np.array([[0, 1, 2]])))
    (tmp_path / "t.gltf").write_bytes(g.gltf()[0])
    assert [load_ply(ply).format, load_obj(obj).format, load_gltf(tmp_path / "t.gltf").format] == ["PLY", "OBJ", "glTF"]
    (tmp_path / "scan_as.obj").write_bytes(ply.read_bytes())
    scene = load_scene([load_gltf(tmp_path / "t.gltf"), str(tmp_path / "scan_as.obj")], warn=lambda m: None)
    assert scene.formats == ("glTF", "PLY")
