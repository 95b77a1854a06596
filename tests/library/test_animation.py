"""Animation: frame ranges, camera paths against independent formulas, OBJ sequences, determinism, GIFs."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from PIL import Image

import warp_spt
from warp_spt.animation import CameraPath, ObjSequence, render_animation, slerp
from warp_spt.images.files import save_gif
from warp_spt.io.templates import frame_path, parse_frames
from warp_spt.scene.errors import SceneError

from tests.support.scenes import write_ball_sequence

KEYS = {"keyframes": [
    {"frame": 0, "position": [0, -3, 1], "direction": [0, 1, 0], "fov": 40, "focus": 2, "aperture": 0.0},
    {"frame": 10, "position": [2, -1, 3], "direction": [1, 0, -1], "fov": 60, "focus": 4},
    {"frame": 14, "position": [2, -1, 5], "direction": [1, 0.2, -1.2], "fov": 30, "focus": 1, "aperture": 0.5},
]}


@pytest.mark.parametrize("text, expected", [("0:48", range(0, 48)), ("3:10:3", range(3, 10, 3)), ("7", range(7, 8))])
def test_parse_frames(text, expected):
    assert parse_frames(text) == expected


@pytest.mark.parametrize("text", ["", "a:3", "5:5", "4:2", "0:9:0", "-1:3", "1:2:3:4"])
def test_parse_frames_rejects(text):
    with pytest.raises(ValueError, match="frames"):
        parse_frames(text)


def _rodrigues(a, b, t):
    """Independent slerp: rotate unit a about a x b by t times the angle between a and b."""
    a, b = np.asarray(a, float) / np.linalg.norm(a), np.asarray(b, float) / np.linalg.norm(b)
    axis = np.cross(a, b)
    axis /= np.linalg.norm(axis)
    phi = t * math.atan2(np.linalg.norm(np.cross(a, b)), np.dot(a, b))
    return a * math.cos(phi) + np.cross(axis, a) * math.sin(phi) + axis * np.dot(axis, a) * (1 - math.cos(phi))


@pytest.mark.parametrize("frame", [0, 2.5, 7, 10, 11, 13.9])
def test_camera_path_interpolates_against_independent_formulas(frame):
    path = CameraPath.from_json(KEYS)
    k = KEYS["keyframes"]
    i = 0 if frame < 10 else 1
    t = (frame - k[i]["frame"]) / (k[i + 1]["frame"] - k[i]["frame"])
    cam = path.at(frame)
    aperture = [0.0, 0.0, 0.5]        # keyframe 2 inherits keyframe 1's aperture
    np.testing.assert_allclose(cam.position, np.add(k[i]["position"], t * np.subtract(k[i + 1]["position"], k[i]["position"])),
                               atol=1e-12)
    np.testing.assert_allclose(cam.direction, _rodrigues(k[i]["direction"], k[i + 1]["direction"], t), atol=1e-12)
    assert cam.fov == pytest.approx(k[i]["fov"] + t * (k[i + 1]["fov"] - k[i]["fov"]), abs=1e-12)
    assert cam.focus == pytest.approx(k[i]["focus"] + t * (k[i + 1]["focus"] - k[i]["focus"]), abs=1e-12)
    assert cam.aperture == pytest.approx(aperture[i] + t * (aperture[i + 1] - aperture[i]), abs=1e-12)


def test_camera_path_holds_the_ends_and_has_unit_directions():
    path = CameraPath.from_json(KEYS)
    assert path.at(-5) == path.keys[0].camera and path.at(99) == path.keys[-1].camera
    assert path.frames == range(0, 15)
    for f in np.linspace(0, 14, 57):
        assert np.linalg.norm(path.at(f).direction) == pytest.approx(1.0, abs=1e-12)
    # slerp moves at constant angular speed: equal steps in t give equal angles
    a, b = np.array([1.0, 0, 0]), np.array([0.0, 0.6, 0.8])
    steps = [math.acos(np.clip(np.dot(slerp(a, b, t0), slerp(a, b, t0 + 0.125)), -1, 1)) for t0 in np.arange(0, 1, 0.125)]
    assert np.ptp(steps) < 1e-9 and sum(steps) == pytest.approx(math.pi / 2, abs=1e-9)


@pytest.mark.parametrize("data, message", [
    ({"keyframes": []}, "at least one keyframe"),
    ({"keyframes": [{"frame": 0, "position": [0, 0, 0]}]}, "missing 'direction'"),
    ({"keyframes": [{"frame": 0, "position": [0, 0], "direction": [0, 1, 0]}]}, "list of 3 numbers"),
    ({"keyframes": [{"frame": 0, "position": [0, 0, 0], "direction": [0, 1, 0], "zoom": 2}]}, "unknown field"),
    ({"keyframes": [{"frame": 0, "position": [0, 0, 0], "direction": [0, 0, 0]}]}, "must not be zero"),
    ({"keyframes": [{"frame": 3, "position": [0, 0, 0], "direction": [0, 1, 0]},
                    {"frame": 3, "position": [0, 0, 0], "direction": [0, 1, 0]}]}, "does not follow"),
    ({"keyframes": [{"frame": 0, "position": [0, 0, 0], "direction": [0, 1, 0]},
                    {"frame": 3, "position": [0, 0, 0], "direction": [0, -1, 0]}]}, "opposite"),
])
def test_camera_path_errors_name_the_file_and_keyframe(tmp_path, data, message):
    f = tmp_path / "path.json"
    f.write_text(json.dumps(data))
    with pytest.raises(SceneError, match=message) as err:
        CameraPath.load(f)
    assert str(f) in str(err.value)


def test_camera_path_bad_json_names_the_line(tmp_path):
    f = tmp_path / "path.json"
    f.write_text('{"keyframes": [\n  {"frame": 0,,}\n]}')
    with pytest.raises(SceneError, match=r"path.json:2: invalid JSON"):
        CameraPath.load(f)


def test_camera_path_round_trips_through_json():
    path = CameraPath.from_json(KEYS)
    again = CameraPath.from_json(json.loads(json.dumps(path.to_json())))
    for a, b in zip(again.keys, path.keys):
        assert a.frame == b.frame and a.camera.position == b.camera.position
        np.testing.assert_allclose(a.camera.direction, b.camera.direction, rtol=0, atol=1e-15)
        assert (a.camera.fov, a.camera.focus, a.camera.aperture) == (b.camera.fov, b.camera.focus, b.camera.aperture)


def test_obj_sequence_reloads_only_what_changes(tmp_path):
    objs, mtls = write_ball_sequence(tmp_path, range(4))
    assert frame_path(objs[1], 3) == str(tmp_path / "ball_03.obj")
    seq = ObjSequence(objs, mtls)
    for k in range(4):
        scene = seq.scene(k)
        direct = warp_spt.load_scene([str(tmp_path / "room.obj"), str(tmp_path / f"ball_{k:02d}.obj")], mtls,
                                     warn=lambda m: None)
        np.testing.assert_array_equal(scene.spheres, direct.spheres)
        np.testing.assert_array_equal(scene.meshes[0].positions, direct.meshes[0].positions)
        assert scene.materials.names == direct.materials.names
    assert seq.loads == 1 + 4               # the room once, a ball per frame
    assert seq.scene(3) is seq.scene(3)     # same files: same scene, nothing re-read
    assert seq.loads == 5
    static = ObjSequence([objs[0]], mtls)
    assert static.scene(0) is static.scene(7) and static.loads == 1


def test_unchanged_meshes_are_uploaded_once_and_render_the_same(tmp_path, monkeypatch):
    """Frames share a static mesh's wp.Mesh; a changed mesh is built anew; images equal fresh uploads."""
    import warp as wp

    from warp_spt.upload.device_scene import DeviceScene

    from tests.support.scenes import box_obj, material

    (tmp_path / "room.obj").write_text(box_obj((-1, -1, -1), (1, 1, 1), "wall"))
    for k in range(3):       # a quad moving along x: a mesh that changes every frame
        x = -0.4 + 0.2 * k
        (tmp_path / f"quad_{k}.obj").write_text(
            "usemtl lamp\n" + "".join(f"v {x + dx} 0.3 {dz}\n" for dx, dz in ((0, 0), (0.3, 0), (0.3, 0.3), (0, 0.3)))
            + "f 1 2 3 4\n")
    (tmp_path / "seq.mtl").write_text(material("wall", Kd=(0.7, 0.6, 0.5), Roughness=0.9) + material("lamp", Kl=(6, 5, 4)))
    seq = ObjSequence([str(tmp_path / "room.obj"), str(tmp_path / "quad_{frame}.obj")], [str(tmp_path / "seq.mtl")])
    cache: dict = {}
    devs = [DeviceScene(seq.scene(k), meshes=cache) for k in range(3)]
    assert devs[0]._meshes[0] is devs[1]._meshes[0] is devs[2]._meshes[0]          # the room: built once
    assert len({id(d._meshes[1]) for d in devs}) == 3 and len(cache) == 1 + 3      # the quad: every frame
    cam = warp_spt.Camera(position=(0, -0.9, 0), direction=(0, 1, 0), fov=70, focus=1)
    for k, dev in enumerate(devs):
        fresh = DeviceScene(seq.scene(k))
        assert np.array_equal(warp_spt.render_film(dev, cam, **SETTINGS).sum,
                              warp_spt.render_film(fresh, cam, **SETTINGS).sum)
    built = []
    real_mesh = wp.Mesh
    monkeypatch.setattr(wp, "Mesh", lambda *a, **kw: built.append(1) or real_mesh(*a, **kw))
    frames = dict(render_animation(seq, (), range(3), cam, **SETTINGS))
    assert len(built) == 1 + 3 and sorted(frames) == [0, 1, 2]                      # room once, quad per frame


def test_missing_frame_file_is_a_scene_error(tmp_path):
    objs, mtls = write_ball_sequence(tmp_path, range(2))
    with pytest.raises(SceneError, match="ball_05.obj"):
        ObjSequence(objs, mtls).scene(5)


SETTINGS = dict(width=12, height=10, spp=24, max_depth=4, seed=5)


def _direct(tmp_path, mtls, path, k):
    """Frame k rendered without the animation module: load the frame's files, interpolate by hand."""
    scene = warp_spt.load_scene([str(tmp_path / "room.obj"), str(tmp_path / f"ball_{k:02d}.obj")], mtls,
                                warn=lambda m: None)
    return warp_spt.render(scene, path.at(k), **SETTINGS)


def test_frame_k_is_the_same_alone_in_a_sequence_and_rendered_directly(tmp_path):
    objs, mtls = write_ball_sequence(tmp_path, range(4))
    path = CameraPath.from_json(KEYS)
    seen = []
    sequence = dict(render_animation(objs, mtls, range(0, 4), path, progress=lambda d, t: seen.append((d, t)),
                                     **SETTINGS))
    assert list(sequence) == [0, 1, 2, 3]
    assert seen[-1] == (4 * 12 * 10 * 24,) * 2
    alone = dict(render_animation(objs, mtls, [2], path, **SETTINGS))
    assert np.array_equal(alone[2], sequence[2])
    for k in (0, 2):
        assert np.array_equal(sequence[k], _direct(tmp_path, mtls, path, k))
    assert not np.array_equal(sequence[0], sequence[1])


def test_save_gif_writes_every_frame(tmp_path):
    rng = np.random.default_rng(0)
    images = [rng.random((9, 13, 3), dtype=np.float32) * k for k in (0.2, 0.5, 1.0)]
    out = tmp_path / "a.gif"
    save_gif(out, images, fps=10, tonemap="srgb")
    with Image.open(out) as gif:
        assert gif.n_frames == 3 and gif.size == (13, 9)
        gif.seek(2)
        got = np.asarray(gif.convert("RGB"), dtype=float)
    want = warp_spt.tonemap_srgb(images[2]).astype(float)
    assert np.abs(got - want).mean() < 8          # a 256-colour palette of 117 pixels: nearly exact
    assert not list(tmp_path.glob(".*.tmp"))
    with pytest.raises(ValueError):
        save_gif(tmp_path / "b.gif", [])


# ---------------------------------------------------------------------------------------------
# Command line


@pytest.mark.parametrize("argv, message", [
    (["--cluster", "tcp://127.0.0.1:1", "--workers", "2"], "either --cluster or --workers"),
    (["--frames", "3:1"], "--frames"),
    (["-obj", "w_{frame}.obj"], "give --frames"),
    (["-obj", "w_{frame}.obj", "--frames", "0:4", "-out", "one.png"], r"put \{frame\} in the name"),
    (["--frames", "0:2", "--gif", "a.png"], "must end in .gif"),
    (["-cam", "0", "0", "0", "0", "1", "0", "40", "1", "0", "--camera-path", "p.json"], "either -cam or --camera-path"),
    (["-obj", "w_{frame:q}.obj", "--frames", "0:2"], r"may hold only \{frame\}"),
    (["--frames", "0:2", "-out", "f_{frame}.tif"], r"\.png, \.jpg, \.npy, \.pfm or \.exr"),
])
def test_animation_flags_are_validated(argv, message):
    from warp_spt.cli.common import UsageError
    from warp_spt.cli.options import parse_args
    with pytest.raises(UsageError, match=message):
        parse_args(argv)


def test_animation_defaults():
    from warp_spt.cli.options import parse_args
    opts = parse_args(["-obj", "w_{frame:03d}.obj", "--frames", "2:8:2"])
    assert opts.animated and opts.frames == range(2, 8, 2) and opts.out == "frame_{frame:04d}.png"
    assert parse_args(["--frames", "0:3", "--gif", "a.gif"]).out == ""          # only the GIF
    assert parse_args(["--frames", "5", "-out", "single.png"]).out == "single.png"
    assert not parse_args(["-out", "x.png"]).animated


def test_cli_writes_every_frame_and_a_gif(tmp_path, capsys):
    from warp_spt.cli.main import main
    objs, mtls = write_ball_sequence(tmp_path, range(3))
    path = tmp_path / "path.json"
    path.write_text(json.dumps(KEYS))
    argv = ["-mtl", mtls[0], "-obj", objs[0], "-obj", objs[1], "--frames", "0:3", "--camera-path", str(path),
            "-res", "12", "10", "-sr", "24", "-depth", "4", "--seed", "5", "--quiet",
            "-out", str(tmp_path / "f_{frame}.npy"), "--gif", str(tmp_path / "a.gif")]
    assert main(argv) == 0
    want = dict(render_animation(objs, mtls, range(3), CameraPath.from_json(KEYS), **SETTINGS))
    for k in range(3):
        assert np.array_equal(np.load(tmp_path / f"f_{k}.npy"), want[k])
    with Image.open(tmp_path / "a.gif") as gif:
        assert gif.n_frames == 3
    assert capsys.readouterr().err == ""


def test_cli_missing_frame_file_is_one_line(tmp_path, capsys):
    from warp_spt.cli.main import main
    objs, mtls = write_ball_sequence(tmp_path, range(2))
    status = main(["-mtl", mtls[0], "-obj", objs[0], "-obj", objs[1], "--frames", "0:3", "--quiet",
                   "-out", str(tmp_path / "f_{frame}.png")])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 1 and len(err) == 1 and "ball_02.obj" in err[0]
    assert not list(tmp_path.glob("f_*.png"))          # checked before anything was rendered
