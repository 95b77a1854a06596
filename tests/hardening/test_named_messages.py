"""Bad values that ended in "internal error" or in messages naming nothing (issue 42, items 5 and 7):
each is one line naming the file and the JSON pointer (glTF), or the field, or the flag."""

from __future__ import annotations

import re

import numpy as np

import pytest

from warp_spt.cli.main import main
from warp_spt.io.loader import load_scene
from warp_spt.scene.errors import SceneError
from warp_spt.scene.model import Material

from tests.support.format_files import gltf_camera_and_light, gltf_textured_box

LIGHT = "/extensions/KHR_lights_punctual/lights/0"


@pytest.mark.parametrize("kind, field, value, where, says", [
    ("point", "intensity", -1, "/intensity", "must be at least 0"),
    ("point", "intensity", 1e39, "", "intensity must lie within"),
    ("point", "color", [2, -1, 0], "/color", r"each component must lie in \[0, 1\]"),
    ("point", "range", -5, "/range", "must be above 0"),
    ("spot", "spot", {"outerConeAngle": 10}, "/spot", "innerConeAngle < outerConeAngle <= pi/2"),
    ("spot", "spot", {"innerConeAngle": 0.5, "outerConeAngle": 0.2}, "/spot", "innerConeAngle < outerConeAngle"),
])
def test_punctual_lights_out_of_range_name_file_and_pointer(tmp_path, kind, field, value, where, says):
    g = gltf_camera_and_light()
    light = g.doc["extensions"]["KHR_lights_punctual"]["lights"][0]
    light["type"], light[field] = kind, value
    path = tmp_path / "lit.gltf"
    path.write_bytes(g.gltf()[0])
    with pytest.raises(SceneError, match=rf"lit\.gltf: {LIGHT}{where}: .*{says}"):
        load_scene([str(path)])


@pytest.mark.parametrize("extension, value, says", [
    ("KHR_materials_ior", {"ior": 1e-9}, r"ior must lie in \[0.001, 1000\], got 1e-09"),
    ("KHR_materials_specular", {"specularFactor": -3}, r"specular must lie in \[0, 1\], got -3"),
])
def test_a_gltf_material_out_of_range_names_file_material_and_field(tmp_path, extension, value, says):
    g = gltf_textured_box()
    g.doc["materials"][0]["extensions"][extension] = value
    path = tmp_path / "mat.gltf"
    path.write_bytes(g.gltf()[0])
    with pytest.raises(SceneError, match=rf"mat\.gltf: /materials/0: material 'checker': {says}"):
        load_scene([str(path)])


@pytest.mark.parametrize("fields, says", [
    (dict(base_color=(1, 1)), r"base_color must be 3 numbers, got \(1, 1\)"),
    (dict(base_color="red"), "base_color must be 3 numbers, got 'red'"),
    (dict(roughness=(1, 2)), "roughness must be a number"),
    (dict(roughness=5), r"roughness must lie in \[0, 1\], got 5"),
    (dict(ior=float("nan")), r"ior must lie in \[0.001, 1000\], got nan"),
])
def test_material_pbr_names_the_field(fields, says):
    with pytest.raises(ValueError, match=rf"Material.pbr\('m'\): {says}"):
        Material.pbr("m", **fields)
    assert Material.pbr("m", base_color=(0.5, 0.5, 0.5)).base_color == (0.5, 0.5, 0.5)


def _cameras(tmp_path, orthographic=False, one=False):
    g = gltf_camera_and_light()
    if orthographic:
        g.doc["cameras"][0] = {"type": "orthographic", "orthographic": {"xmag": 1, "ymag": 1, "znear": 0.1, "zfar": 9}}
    if one:
        del g.doc["cameras"][1]
        g.doc["nodes"] = [n for n in g.doc["nodes"] if n.get("camera") != 1]
        g.doc["scenes"][0]["nodes"] = list(range(len(g.doc["nodes"])))
        g.doc["cameras"][0].pop("name")
    path = tmp_path / "cams.gltf"
    path.write_bytes(g.gltf()[0])
    return str(path)


@pytest.mark.parametrize("case, camera, says", [
    # before: no file name
    ("orthographic", "0", r"--camera 0: \S*cams\.gltf: /cameras/0: camera '0' is orthographic; only perspective cameras"),
    ("one", "1", r"--camera 1: no camera '1'; the files have 1 camera: 0 \(unnamed\)"),
])
def test_the_camera_flag_refuses_what_it_cannot_look_through(tmp_path, capsys, case, camera, says):
    path = _cameras(tmp_path, orthographic=case == "orthographic", one=case == "one")
    assert main(["-obj", path, "--camera", camera, "-res", "8", "8", "-sr", "1", "-out", str(tmp_path / "o.png")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("warp-spt: error: ") and re.search(says, err[-1]), err
    assert not (tmp_path / "o.png").exists()


def test_env_strength_beyond_the_sky_bound_is_a_usage_error(tmp_path, capsys):
    assert main(["--env", str(tmp_path / "sky.hdr"), "--env-strength", "1e308", "-out", str(tmp_path / "o.png")]) == 2
    assert "--env-strength must lie in [0, 1e+30], got 1e+308" in capsys.readouterr().err


@pytest.mark.parametrize("damage, says", [
    ("truncated", r"\(EXR_ERR_BAD_CHUNK_LEADER\) Preparing to read scanline"),
    ("offsets", r"\(EXR_ERR_BAD_CHUNK_LEADER\) Invalid chunk size"),
    ("junk", r"Unable to open '.*junk\.exr' for read"),
])
def test_a_damaged_exr_is_one_line_and_nothing_else_on_stdout_or_stderr(tmp_path, capfd, damage, says):
    OpenEXR = pytest.importorskip("OpenEXR")
    good = tmp_path / "good.exr"
    rgb = np.random.default_rng(1).random((64, 128, 3)).astype(np.float32)
    with OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"RGB": rgb}) as f:
        f.write(str(good))
    data = good.read_bytes()
    at = data.index(b"dataWindow") + 200                 # into the chunk offset table
    bad = tmp_path / f"{damage}.exr"
    bad.write_bytes({"truncated": data[:-1000], "offsets": data[:at] + b"\xff" * 100 + data[at + 100:],
                     "junk": b"not an exr file " * 10}[damage])
    obj = tmp_path / "t.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    capfd.readouterr()
    assert main(["-obj", str(obj), "--env", str(bad), "--quiet", "-res", "4", "4", "-sr", "1",
                 "-out", str(tmp_path / "o.png")]) == 1
    out, err = capfd.readouterr()
    # before: OpenEXR's core printed its own lines to stderr and a "Warning: Exception raised..." to stdout
    assert out == "" and len(err.splitlines()) == 1, (out, err)
    assert re.match(rf"warp-spt: error: .*{damage}\.exr: cannot read the environment map: {says}", err), err


@pytest.mark.parametrize("flags, says", [
    (["--env-strength", "1e308"], r"--env-strength must lie in \[0, 1e\+30\], got 1e\+308"),
    (["--env-strength", "-1"], r"--env-strength must lie in \[0, 1e\+30\], got -1"),
    (["--env-rotate", "1e300"], r"--env-rotate must lie in \[-1e\+06, 1e\+06\] degrees, got 1e\+300"),
    (["--env-background", "1e38", "0", "0"], r"--env-background colour values must lie in \[0, 1e\+30\], got 1e\+38 0 0"),
    (["--env-background", "0", "-1", "0"], r"--env-background colour values must lie in \[0, 1e\+30\]"),
])
def test_the_viewer_and_the_renderer_share_the_environment_flags_bounds(tmp_path, capsys, flags, says):
    from warp_spt.cli import view
    from warp_spt.scene.limits import MAX_ENV_ROTATE, MAX_RADIANCE
    from warp_spt.scene.sky import Sky
    from warp_spt.viewer.session import ViewSettings, checked_settings

    env = ["--env", str(tmp_path / "sky.hdr")]
    # before: the viewer took 1e308 and 1e38 (exit 1 after loading the scene) and the renderer 1e300
    for run in (main, view.main):
        assert run([*env, *flags, "-out", str(tmp_path / "o.png")] if run is main else [*env, *flags]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and re.search(says, err[0]), (run, err)
    at_bound = [*env, "--env-strength", f"{MAX_RADIANCE:g}", "--env-rotate", f"{-MAX_ENV_ROTATE:g}",
                "--env-background", f"{MAX_RADIANCE:g}", "0", "0"]
    assert view.lighting_settings(view.build_parser().parse_args(at_bound))["env_strength"] == MAX_RADIANCE
    # the API and the page refuse what the flags refuse
    with pytest.raises(ValueError, match="environment rotation must be a number of degrees in"):
        Sky.environment(np.ones((2, 4, 3), np.float32), rotate=2 * MAX_ENV_ROTATE)
    with pytest.raises(ValueError, match="env_rotate must lie in"):
        checked_settings(ViewSettings(), "env_rotate", 2 * MAX_ENV_ROTATE)


def test_an_environment_png_past_pillows_bomb_guard_names_the_texel_budget(tmp_path, capsys):
    from PIL import Image

    from warp_spt.scene.atlas_layout import TEXEL_BUDGET

    Image.new("1", (30000, 30000)).save(tmp_path / "huge.png")           # 110 KB, 900 million texels
    obj = tmp_path / "t.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert main(["-obj", str(obj), "--env", str(tmp_path / "huge.png"), "--quiet", "-out", str(tmp_path / "o.png")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    # before: Pillow's words alone ("cannot read the environment map: Image size (900000000 pixels) exceeds ...")
    assert len(err) == 1 and f"huge.png: more texels than the texel budget of {TEXEL_BUDGET:,} (Image size" in err[0], err
