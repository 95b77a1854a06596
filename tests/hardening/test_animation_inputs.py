"""Animations that lost work (issue 42, item 3): an object scaled to nothing hides it and its frames
render (empty, where nothing else is left); every frame's pose is checked before frame 0 is rendered;
--fps keeps every frame's time finite."""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.animation import ObjSequence, render_animation
from warp_spt.cli.main import main
from warp_spt.scene.camera import Camera
from warp_spt.scene.errors import SceneError
from warp_spt.scene.sky import Sky

from tests.support.format_files import gltf_scaled_away


def write(tmp_path, name, builder) -> str:
    path = tmp_path / name
    path.write_bytes(builder.gltf()[0])
    return str(path)


def test_frames_that_scale_everything_to_nothing_are_hidden_and_render_empty(tmp_path):
    seq = ObjSequence([write(tmp_path, "away.gltf", gltf_scaled_away())], fps=8)
    assert seq.check(range(0, 16, 4)) == [8, 12]             # t = 1 s and after: scale 0
    assert not seq.scene(4).hidden and seq.scene(4).num_triangles == 12
    scene = seq.scene(8)
    assert scene.hidden and scene.num_triangles == 0 and len(scene.spheres) == 0
    sky = Sky.constant(0.25, 0.5, 0.75)
    [(k, image)] = render_animation(seq, frames=[8], camera=Camera(), width=6, height=4, spp=2, sky=sky)
    assert k == 8 and np.allclose(image, [0.25, 0.5, 0.75], atol=1e-6)


def test_a_static_file_whose_meshes_are_all_scaled_to_nothing_says_so(tmp_path):
    from warp_spt.io.loader import load_scene

    g = gltf_scaled_away()
    del g.doc["animations"]
    g.doc["nodes"][0]["scale"] = [0, 0, 0]
    g.node(mesh=0, scale=[0, 0, 0])                           # two placements: the mesh is instanced
    with pytest.raises(SceneError, match=r"hidden\.gltf: the scene has no geometry: its 2 mesh placement\(s\) are "
                                         "scaled to nothing"):
        load_scene([write(tmp_path, "hidden.gltf", g)])


def test_a_pose_out_of_range_is_refused_before_frame_0_naming_file_frame_and_pointer(tmp_path, capsys):
    path = write(tmp_path, "far.gltf", gltf_scaled_away(big_keys=True))
    with pytest.raises(SceneError, match=r"far\.gltf: at frame 8 \(0\.333333 s\): /meshes/0: .*beyond the supported"):
        ObjSequence([path]).check(range(0, 48, 8))
    out = tmp_path / "o_{frame}.png"
    assert main(["-obj", path, "--frames", "0:48:8", "-res", "8", "8", "-sr", "1", "-out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err[-1].startswith("warp-spt: error: ") and "at frame 8" in err[-1], err
    assert not list(tmp_path.glob("o_*.png"))                 # nothing rendered before the refusal


@pytest.mark.parametrize("fps", ["5e-324", "1e-4", "2e6"])
def test_fps_that_would_make_a_frame_time_infinite_is_a_usage_error(tmp_path, capsys, fps):
    path = write(tmp_path, "away.gltf", gltf_scaled_away())
    assert main(["-obj", path, "--fps", fps, "--frames", "0:3", "-out", str(tmp_path / "o_{frame}.png")]) == 2
    assert "--fps must lie in [0.001, 1e+06]" in capsys.readouterr().err
    with pytest.raises(ValueError, match="fps must lie in"):
        ObjSequence([path], fps=float(fps))


def test_the_command_line_renders_hidden_frames_beside_shown_ones(tmp_path, capsys):
    """The studio look stands its ground where the last shown frame had it; hidden frames keep it."""
    from PIL import Image

    path = write(tmp_path, "away.gltf", gltf_scaled_away())
    out = tmp_path / "o_{frame}.png"
    assert main(["-obj", path, "--fps", "8", "--frames", "4:16:4", "-res", "8", "8", "-sr", "1", "-out", str(out),
                 "--quiet"]) == 0, capsys.readouterr().err
    images = {k: np.asarray(Image.open(tmp_path / f"o_{k}.png"), np.float64) for k in (4, 8, 12)}
    assert np.array_equal(images[8], images[12])              # both hidden, the same view
    assert not np.array_equal(images[4], images[8])           # the cube is gone
    assert images[8].std() > 0                                # the ground and the sky, not one colour
