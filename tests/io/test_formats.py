"""EXR (optional openexr package) and JPEG output (issue 10); scene files in formats other than OBJ."""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.images.files import load_image, save_image, tonemap_srgb


def test_exr_holds_linear_float32_exactly(tmp_path):
    pytest.importorskip("OpenEXR")
    rng = np.random.default_rng(3)
    img = (rng.random((7, 5, 3)) * 1e3).astype(np.float32)
    img[0, 0] = (0.0, 1e-30, 6e4)
    save_image(tmp_path / "a.exr", img)
    import OpenEXR
    with OpenEXR.File(str(tmp_path / "a.exr")) as f:          # read back by the library, not by our reader
        assert set(f.channels()) == {"RGB"} and f.channels()["RGB"].pixels.dtype == np.float32
    assert np.array_equal(load_image(tmp_path / "a.exr"), img)
    assert [p.name for p in tmp_path.iterdir()] == ["a.exr"]      # no temporary file left behind


def test_jpeg_is_the_tone_mapped_image_up_to_compression(tmp_path):
    ramp = np.linspace(0, 1, 64, dtype=np.float32)
    img = np.stack(np.broadcast_arrays(ramp[None, :], ramp[:, None], 0.5 * np.ones((64, 64), np.float32)), -1)
    save_image(tmp_path / "a.jpg", img, tonemap="srgb")
    got = load_image(tmp_path / "a.jpg").astype(int)
    assert got.shape == (64, 64, 3) and np.abs(got - tonemap_srgb(img).astype(int)).mean() < 2.0


OTHER_FORMATS = [
    ("model.fbx", b"Kaydara FBX Binary  \x00\x1a\x00", "FBX files are not supported"),
    ("model.stl", b"solid part\nfacet normal 0 0 1\n", "STL files are not supported"),
    ("model.stl", b"\x00" * 80 + b"\x01\x00\x00\x00", "STL files are not supported"),      # binary STL
    ("model.3ds", b"MM\x10\x00\x00\x00", "3DS files are not supported"),
    ("model.dae", b'<?xml version="1.0"?>\n<COLLADA version="1.4.1">', "COLLADA (.dae) files are not"),
]


@pytest.mark.parametrize("name, data, message", OTHER_FORMATS, ids=[f"{n}-{i}" for i, (n, _, _) in
                                                                    enumerate(OTHER_FORMATS)])
def test_a_model_in_another_format_is_one_line_that_says_so(tmp_path, capsys, name, data, message):
    """By suffix and by content: it was "binary data (a NUL byte)" or "the scene has no geometry"."""
    from warp_spt.cli.main import main

    (tmp_path / name).write_bytes(data)
    assert main(["-obj", str(tmp_path / name), "-res", "8", "8", "-out", str(tmp_path / "o.png")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"warp-spt: error: {tmp_path / name}: ") and message in err
    assert err.rstrip().endswith("convert to OBJ (e.g. with Blender or MeshLab)")
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]          # no output


def test_other_formats_are_named_by_the_api_too_and_json_camera_paths_still_read(tmp_path):
    from warp_spt.animation import CameraPath
    from warp_spt.io.loader import load_scene
    from warp_spt.scene.errors import SceneError

    (tmp_path / "a.stl").write_bytes(b"solid part\n")
    with pytest.raises(SceneError, match="STL files are not supported yet"):
        load_scene([str(tmp_path / "a.stl")])
    (tmp_path / "b.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "m.mtl").write_bytes(b"glTF\x02\x00\x00\x00")
    with pytest.raises(SceneError, match="not MTL text: a glTF file"):
        load_scene([str(tmp_path / "b.obj")], [str(tmp_path / "m.mtl")])
    (tmp_path / "path.json").write_text('{"keyframes": [{"frame": 0, "position": [0, -5, 1], "direction": [0, 1, 0]}]}')
    assert CameraPath.load(tmp_path / "path.json").frames == range(0, 1)      # a camera path is JSON

