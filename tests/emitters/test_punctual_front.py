"""The front ends of sun, point and spot lights: the light file and ``--light`` (one syntax), the
``--sun`` flags, the API's ``Scene.add_light``, parameters by name and errors naming file and line."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from warp_spt.cli.common import UsageError
from warp_spt.cli.main import main
from warp_spt.cli.options import parse_args
from warp_spt.io.light_file import load_lights, parse_light
from warp_spt.scene.errors import SceneError
from warp_spt.scene.lights import (
    ANGLE,
    COLOUR,
    PUNCTUAL_KINDS,
    VECTOR,
    WORD,
    LightField,
    PointLight,
    PunctualKind,
    SpotLight,
    SunLight,
    check_fields,
)


def test_light_file_reads_every_kind(tmp_path):
    f = tmp_path / "lights.txt"
    f.write_text("# key and fill\n\nsun direction 0.4 -0.3 1 color 3 3 2.8 radius 0.27\n"
                 "point position 0 2 0 intensity 50   # a bulb\n"
                 "spot position 0 3 0 direction 0 -1 0 intensity 200 180 160 inner 15 outer 30 name key\n")
    sun, point, spot = load_lights(str(f))
    assert sun == SunLight(direction=(0.4, -0.3, 1.0), color=(3.0, 3.0, 2.8), radius_deg=0.27)
    assert point == PointLight(position=(0.0, 2.0, 0.0), intensity=(50.0, 50.0, 50.0))
    assert spot == SpotLight(position=(0, 3, 0), direction=(0, -1, 0), intensity=(200, 180, 160),
                             inner_deg=15, outer_deg=30, name="key")


@pytest.mark.parametrize("line, mentions", [
    ("lamp position 0 0 0", "kind of light"),
    ("point position 1 2", "position needs 3 numbers"),
    ("point color 1", "takes position, intensity, name"),
    ("sun radius 90", "radius must be in [0, 45]"),
    ("spot inner 40 outer 30", "inner (40) must not be above outer (30)"),
    ("point intensity -1", "intensity must be in"),
    ("sun direction 0 0 0", "direction must not be zero"),
    ("point position 1 2 3 position 1 2 3", "position given twice"),
    ("point position 1 2 nan", "position needs 3 numbers"),
    # a direction is normalised in float32: 1e20 squared overflowed and the sun shone from below
    ("sun direction 1e20 1e20 1e20", "direction must not be huge or tiny"),
    ("sun direction 1e308 0 1", "direction must not be huge or tiny"),
    ("spot position 0 0 1 direction 1e-40 0 0", "direction must not be huge or tiny"),
    ("point position 1e16 0 0", "position must lie within +-1e+15"),
])
def test_light_file_errors_name_file_and_line(tmp_path, line, mentions):
    f = tmp_path / "bad.lights"
    f.write_text(f"point position 0 0 1\n{line}\n")
    with pytest.raises(SceneError) as info:
        load_lights(str(f))
    assert str(info.value).startswith(f"{f}:2: ") and mentions in str(info.value)


def test_sun_and_light_flags():
    opts = parse_args(["--sun", "1", "-1", "2", "--sun-color", "2", "2", "2", "--sun-radius", "0.5",
                       "--light", "point", "position", "0", "-2", "1", "intensity", "5",
                       "--light", "spot", "position", "0", "0", "3", "outer", "20"])
    sun, point, spot = opts.lights
    assert sun == SunLight(direction=(1, -1, 2), color=(2, 2, 2), radius_deg=0.5)
    assert point == PointLight(position=(0, -2, 1), intensity=(5, 5, 5), name="light0")
    assert spot.outer_deg == 20 and spot.name == "light1"
    assert parse_args([]).lights == ()


@pytest.mark.parametrize("argv, mentions", [
    (["--sun-color", "1", "1", "1"], "need --sun"),
    (["--sun", "0", "0", "0"], "must not be zero"),
    (["--sun", "0", "0", "1", "--sun-radius", "60"], "radius"),
    (["--light", "point", "position", "1"], "--light point position 1: position needs 3 numbers"),
    (["--sun", "1e20", "1e20", "1e20"], "direction must not be huge or tiny"),
])
def test_bad_light_flags_are_one_line_and_exit_2(argv, mentions, capsys):
    with pytest.raises(UsageError, match=mentions.replace("(", r"\(")):
        parse_args(argv)
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and mentions in err and "Traceback" not in err


def test_negative_numbers_in_exponent_form_are_numbers_not_flags():
    """argparse read ``-1e-3`` as a flag; the framing line prints such numbers in its -cam."""
    opts = parse_args(["--sun", "0.3", "-1e-3", "1", "--light", "point", "position", "-1e1", "2", "-.5E+1"])
    assert opts.lights[0].direction == (0.3, -1e-3, 1.0) and opts.lights[1].position == (-10.0, 2.0, -5.0)
    cam = parse_args(["-cam", "0", "-1.2246467991473532e-16", "5", "-0.0", "1", "-2e-3", "40", "5", "0"]).camera
    assert cam.position == (0.0, -1.2246467991473532e-16, 5.0)
    with pytest.raises(UsageError):            # a word that is neither stays an unknown flag
        parse_args(["--sun", "0", "-1e", "1"])


def test_directions_and_positions_at_the_bounds_are_taken():
    from warp_spt.scene.lights import SpotLight
    assert SunLight(direction=(1e15, -1e15, 2e14)).direction == (1e15, -1e15, 2e14)
    assert SpotLight(position=(1e15, 0, 0), direction=(0, 0, -1e-30)).position == (1e15, 0.0, 0.0)


def test_a_bad_light_file_exits_1_naming_file_and_line(tmp_path, capsys):
    f = tmp_path / "l.txt"
    f.write_text("sun\npoint intensity x\n")
    assert main(["--lights", str(f)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{f}:2:" in err and "Traceback" not in err


def test_scene_add_light_takes_lights_only():
    from warp_spt.scene.model import MaterialTable, Scene

    s = Scene(meshes=[], spheres=np.zeros((0, 4)), sphere_material=np.zeros(0, np.int32),
              materials=MaterialTable.from_rows([]), textures=[])
    assert s.add_light(PointLight(position=(0, 0, 1), intensity=3.0)).lights[0].intensity == (3.0, 3.0, 3.0)
    with pytest.raises(TypeError, match="SunLight, PointLight or SpotLight"):
        s.add_light("sun")


def test_parse_light_defaults_and_grey():
    assert parse_light(["sun"]) == SunLight()
    assert parse_light(["point", "intensity", "2", "position", "1", "2", "3"]).intensity == (2.0, 2.0, 2.0)


def test_a_gltf_files_lights_reach_the_scene():
    from tests.support.format_files import gltf_camera_and_light
    from warp_spt.io.gltf import parse_gltf_bytes
    from warp_spt.io.loader import load_scene

    scene = load_scene([parse_gltf_bytes(gltf_camera_and_light().gltf()[0], "scene.gltf")])
    (light,) = scene.lights
    assert isinstance(light, PointLight) and light.position == (0, 3, 0) and light.intensity == (20, 10, 5)


def test_the_command_line_renders_a_scene_lit_by_its_flags_only(tmp_path, capsys):
    # a square at y = 0 (Y up) lit by a sun straight above: with a black sky, radiance = a / pi * E
    # where the camera sees the square (the clay's albedo 0.6), 0 elsewhere
    obj = tmp_path / "plane.obj"
    obj.write_text("v -5 0 -5\nv 5 0 -5\nv 5 0 5\nv -5 0 5\nf 1 3 2\nf 1 4 3\n")
    out = tmp_path / "o.npy"
    status = main(["-obj", str(obj), "--sun", "0", "1", "0", "--sun-color", "2", "2", "2", "--sky-color", "0", "0", "0",
                   "-cam", "0", "3", "0.01", "0", "-1", "0", "40", "3", "0", "--up", "y",
                   "-res", "8", "6", "-sr", "2", "-depth", "2", "-out", str(out), "--quiet"])
    assert status == 0, capsys.readouterr().err
    img = np.load(out)
    assert np.allclose(img, 0.6 / np.pi * 2.0, rtol=1e-4)


@dataclass(frozen=True)
class RingLight:
    """A probe punctual kind: a record and its declaration, nothing else (no parser edit)."""

    position: tuple[float, float, float] = (0.0, 0.0, 0.0)
    power: tuple[float, float, float] = (1.0, 1.0, 1.0)
    spread_deg: float = 10.0
    name: str = "ring"
    kind = 9

    def __post_init__(self):
        check_fields(self)


RING = PunctualKind("ring", RingLight, (
    LightField("position", "position", VECTOR), LightField("power", "power", COLOUR, 0.0, 10.0),
    LightField("spread", "spread_deg", ANGLE, 0.0, 30.0), LightField("name", "name", WORD)))


def test_a_registered_punctual_kind_is_read_by_the_light_file_and_the_flag(tmp_path, monkeypatch):
    monkeypatch.setitem(PUNCTUAL_KINDS, "ring", RING)
    f = tmp_path / "l.txt"
    f.write_text("point position 0 1 0\nring position 1 2 3 power 2 spread 20 name halo\n")
    point, ring = load_lights(str(f))
    assert point == PointLight(position=(0, 1, 0)) and ring == RingLight((1, 2, 3), (2, 2, 2), 20.0, "halo")
    (flag,) = parse_args(["--light", "ring", "power", "1", "2", "3"]).lights
    assert flag == RingLight(power=(1, 2, 3), name="light0")          # numbered, as points and spots
    for line, mentions in (("ring spread 40", "spread must be in [0, 30]"), ("ring power 11", "power must be in"),
                           ("ring inner 3", "a ring light takes position, power, spread, name; got 'inner'"),
                           ("lamp", "(sun, point, spot or ring)")):
        f.write_text(f"ring\n{line}\n")
        with pytest.raises(SceneError) as info:
            load_lights(str(f))
        assert str(info.value).startswith(f"{f}:2: ") and mentions in str(info.value), str(info.value)
    with pytest.raises(UsageError, match=r"--light ring spread 31: spread must be in \[0, 30\]"):
        parse_args(["--light", "ring", "spread", "31"])
    with pytest.raises(ValueError, match="light 'ring': power must be in"):
        RingLight(power=-1.0)
