"""The seams issue 20 found broken between front ends and layers, each fixed on purpose.

1. ``--frames`` and ``--workers``/``--cluster`` render what a single render renders: the same files,
   camera, settings and seed give the same image through every front end (a bare OBJ gets clay,
   framing and --studio everywhere, not only in a single render). Several frames without a camera
   share one view, framed over all their bounds (issue 43): each is the single render of its files
   through the camera the run printed.
2. A scene far from the origin keeps its precision: OBJ coordinates stay float64 until the scene is
   recentred, and are rounded to float32 once, at upload. Before, they were rounded when parsed, so a
   room whose light hangs just under its ceiling, moved 1e5 away, lost its light gap and rendered darker.
"""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.io.loader import load_scene
from warp_spt.scene.recentre import recentre

from tests.support.stability_scenes import (
    assert_same_image,
    cornell_camera,
    cornell_files,
    render_batches,
    sky,
)

# ---------------------------------------------------------------- 2. float64 until recentred

SCALE, SHIFT = 1.0 / 32.0, 1e5   # a 1-unit room; its walls are exact in float32 at 1e5 (spacing 1/128)...
LIGHT_GAP = 0.1                  # ...but its light hangs 0.1 / 32 = 0.003 under the ceiling: less than half a
                                 # float32 step there, so rounding when parsing put the light into the ceiling


def _room(folder, shift):
    scene = load_scene(*cornell_files(folder, SCALE, shift, LIGHT_GAP, exact32=False), warn=lambda m: None)
    local, cam, _ = recentre(scene, cornell_camera(SCALE, shift))
    return DeviceScene(local), cam


def test_positions_stay_float64_until_the_scene_is_recentred(tmp_path):
    scene = load_scene(*cornell_files(tmp_path, SCALE, SHIFT, LIGHT_GAP, exact32=False), warn=lambda m: None)
    assert scene.meshes[0].positions.dtype == np.float64 and scene.spheres.dtype == np.float64
    ceiling = scene.meshes[0].positions[:, 2].max()
    light = np.sort(np.unique(scene.meshes[0].positions[:, 2]))[-2]
    assert ceiling - light == pytest.approx(LIGHT_GAP * SCALE, rel=1e-6), "the light gap survives parsing"
    dev = DeviceScene(recentre(scene)[0])
    z = dev.scene.meshes[0].positions[:, 2]
    assert dev.scene.meshes[0].positions.dtype == np.float32
    assert float(np.max(z)) - float(np.sort(np.unique(z))[-2]) == pytest.approx(LIGHT_GAP * SCALE, rel=1e-4)


def test_a_room_far_from_the_origin_renders_like_the_room_at_the_origin(tmp_path):
    dev0, cam0 = _room(tmp_path, 0.0)
    dev1, cam1 = _room(tmp_path, SHIFT)
    kw = dict(width=24, height=24, max_depth=6, sky=sky(50.0))
    a = render_batches(dev0, cam0, 32, 16, seed=1, **kw)
    b = render_batches(dev1, cam1, 32, 16, seed=2, **kw)
    c = assert_same_image(a, b, f"room with a light gap of {LIGHT_GAP * SCALE:.4f}, shifted {SHIFT:g}")
    print(f"worst block |t| {c.worst:.2f} / {c.bound:.2f}; difference {c.rel_diff:.2%} +- {c.rel_se:.2%}")


# ---------------------------------------------------------------- 1. every front end, the same image

def _cli(tmp_path, *args, out="one.npy"):
    from warp_spt.cli.main import main

    assert main([*args, "--quiet", "-res", "16", "12", "-sr", "2", "-depth", "3", "-out", str(tmp_path / out)]) == 0


def _bare_frames(tmp_path):
    """A bare model (no MTL, no material names) as two frame files: clay, framing and studio apply."""
    from tests.support.models import write_model

    for k in range(2):
        write_model(tmp_path / f"cow_{k}.obj", "cow", up="y", offset=(0.2 * k, 0.0, 0.0))
    return str(tmp_path / "cow_{frame}.obj")


@pytest.mark.parametrize("look", [[], ["--studio"], ["--up", "z", "--default-material", "checker"]],
                         ids=["bare", "studio", "checker"])
def test_frames_render_what_a_single_render_renders(tmp_path, look):
    template = _bare_frames(tmp_path)
    _cli(tmp_path, "-obj", str(tmp_path / "cow_1.obj"), *look, out="single.npy")
    _cli(tmp_path, "-obj", template, "--frames", "1", *look, out="alone_{frame}.npy")
    single = np.load(tmp_path / "single.npy")
    assert np.array_equal(np.load(tmp_path / "alone_1.npy"), single), "frame 1 alone differs from a single render"


def test_a_sequence_is_framed_once_and_its_printed_camera_renders_each_frame(tmp_path, capsys):
    """Several frames without a camera are framed once, over all their bounds (issue 43): each frame
    is then the single render of its files through the printed -cam (without the studio, whose
    ground and key the animation places from the same union of bounds)."""
    import re

    from warp_spt.cli.main import main

    template = _bare_frames(tmp_path)
    capsys.readouterr()
    assert main(["-obj", template, "--frames", "0:2", "--no-studio", "-res", "16", "12", "-sr", "2", "-depth", "3",
                 "-out", str(tmp_path / "seq_{frame}.npy")]) == 0
    said = capsys.readouterr().err
    assert said.count("framed the scene") == 1, said
    cam = re.search(r"-cam ((?:\S+ ){8}\S+) --up y", said).group(1).split()
    for k in range(2):
        _cli(tmp_path, "-obj", str(tmp_path / f"cow_{k}.obj"), "--no-studio", "-cam", *cam, "--up", "y",
             out=f"single_{k}.npy")
        assert np.array_equal(np.load(tmp_path / f"seq_{k}.npy"), np.load(tmp_path / f"single_{k}.npy")), k


def test_workers_render_what_a_single_render_renders(tmp_path):
    pytest.importorskip("dask.distributed")
    model = _bare_frames(tmp_path).format(frame=0)
    _cli(tmp_path, "-obj", model, "--studio", out="single.npy")
    _cli(tmp_path, "-obj", model, "--studio", "--workers", "1", out="workers.npy")
    assert np.array_equal(np.load(tmp_path / "workers.npy"), np.load(tmp_path / "single.npy"))
