"""An animation without a camera is framed once, over every frame's bounds (issue 43, item 2).

Framed frame by frame, a translating object stood still in the output (the camera followed it) and
a growing one kept its size (the camera backed away); the "framed" line was printed once per frame.
Judged on the images, by code that does not share the renderer's: under ``--no-studio`` a pixel
that no sample hits is exactly the sky's colour, so the object's pixels are the others; their
centroid must move the way the printed camera's image-right axis says +x goes, and their count
must grow with the object.
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np
from PIL import Image

from tests.support.format_files import CUBE_POSITIONS, CUBE_TRIANGLES, GltfBuilder
from warp_spt.cli.main import run
from warp_spt.cli.options import parse_args

SIZE = ["-res", "48", "32", "-sr", "2"]


def _moving_cube(tmp: Path) -> str:
    """A unit cube translated from (0, 0, 0) at t = 0 to (3, 0, 0) at t = 1 (frames 0, 1, 2 at --fps 2)."""
    g = GltfBuilder()
    g.mesh(CUBE_POSITIONS, CUBE_TRIANGLES)
    g.node(mesh=0)
    times = g.accessor(np.array([0.0, 1.0], np.float32), "SCALAR", 5126)
    keys = g.accessor(np.array([[0, 0, 0], [3, 0, 0]], np.float32), "VEC3", 5126)
    g.doc["animations"] = [{"samplers": [{"input": times, "output": keys}],
                            "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}}]}]
    p = tmp / "move.gltf"
    p.write_bytes(g.gltf()[0])
    return str(p)


def _cli(argv: list[str]) -> str:
    err = io.StringIO()
    assert run(parse_args(argv), stderr=err) == 0, err.getvalue()
    return err.getvalue()


def _object(image: np.ndarray) -> np.ndarray:
    """The pixels some sample hit: those not exactly the sky's colour (the top-left corner's)."""
    return np.any(image != image[0, 0], axis=2)


def _printed_right(said: str) -> np.ndarray:
    from warp_spt.scene.camera import AXES, Camera

    line = next(s for s in said.splitlines() if "framed the scene" in s)
    numbers = [float(v) for v in re.search(r"-cam (\S+ \S+ \S+ \S+ \S+ \S+ \S+ \S+ \S+)", line).group(1).split()]
    return Camera(position=numbers[:3], direction=numbers[3:6], fov=numbers[6], up=AXES["y"]).axes()[1]


def test_a_translating_object_moves_in_the_output_framed_once(tmp_path):
    said = _cli(["-obj", _moving_cube(tmp_path), "--fps", "2", "--frames", "0:3", "--no-studio", *SIZE,
                 "-out", str(tmp_path / "f_{frame}.npy")])
    assert said.count("framed the scene") == 1 and "over every frame's bounds, once" in said, said
    masks = [_object(np.load(tmp_path / f"f_{k}.npy")) for k in range(3)]
    assert all(m.any() and not m.all() for m in masks)
    cx = [float(np.nonzero(m)[1].mean()) for m in masks]
    towards = np.sign(_printed_right(said)[0])          # which way +x goes across the image
    assert towards != 0
    # measured: the centroid moves 13.6 px per frame (48 px wide); framed per frame it stood still
    steps = np.diff(cx) * towards
    assert np.all(steps > 0.15 * 48), cx


def test_a_growing_object_grows_in_the_output(tmp_path):
    """An OBJ sequence whose cube doubles in size: framed per frame, both frames showed it at the
    same size; framed once, its area grows (measured 3.6 x; 4 x at an orthographic limit)."""
    for k, scale in enumerate((1.0, 2.0)):
        v = CUBE_POSITIONS * scale + (0.0, 0.5 * scale, 0.0)
        (tmp_path / f"cube_{k}.obj").write_text("".join(f"v {x} {y} {z}\n" for x, y, z in v)
                                                + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in CUBE_TRIANGLES))
    said = _cli(["-obj", str(tmp_path / "cube_{frame}.obj"), "--frames", "0:2", "--no-studio", *SIZE,
                 "-out", str(tmp_path / "g_{frame}.npy")])
    assert said.count("framed the scene") == 1, said
    small, big = (_object(np.load(tmp_path / f"g_{k}.npy")).sum() for k in range(2))
    assert big > 2.5 * small > 0, (small, big)


def test_gif_alone_writes_one_multi_frame_gif_and_nothing_else(tmp_path, monkeypatch):
    model = _moving_cube(tmp_path)
    monkeypatch.chdir(tmp_path)
    said = _cli(["-obj", model, "--fps", "2", *SIZE, "--gif", "anim.gif"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["anim.gif", "move.gltf"], said
    assert said.count("framed the scene") == 1
    with Image.open(tmp_path / "anim.gif") as gif:
        assert gif.format == "GIF" and gif.n_frames == 3 and gif.size == (48, 32)
        frames = []
        for k in range(3):
            gif.seek(k)
            frames.append(np.asarray(gif.convert("RGB"), dtype=np.int32))
    assert all(np.abs(frames[k + 1] - frames[k]).max() > 0 for k in range(2))     # the cube moves
