"""The light flags (--sun, --light, --lights) and --fog through every front end of the command line.

They are part of the scene, not of one runner: frame k alone, frame k of a sequence rendered here,
the same sequence on ``--workers 2`` and a single ``--workers 2`` image are one image bit for bit
(the determinism rule of docs/architecture.md: same scene, camera, settings and seed, same film).
The expected image is the single render on this machine, which tests/test_punctual_front.py and
tests/test_volumes.py check against analytic values; a runner that dropped a light or the fog on
the way to its workers would render another image.
"""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.cli.main import main
from warp_spt.cli.options import parse_args

from .scenes import box_obj, material

RENDER = ["--quiet", "-res", "16", "12", "-sr", "2", "-depth", "3", "--look-at", "0", "0", "0"]

KINDS = {
    "sun": ["--sun", "0.3", "1", "0.5", "--sun-color", "2", "2", "2"],
    "point": ["--light", "point", "position", "0.5", "2", "1.5", "intensity", "8"],
    # a fog fills all space, so no sky light gets through it: a point light inside lights it
    "fog": ["--fog", "sigma_s=0.05", "--fog", "sigma_a=0.005,0.01,0.02", "--fog", "g=0.3",
            "--light", "point", "position", "-1", "2", "1", "intensity", "20"],
}


def _frames(folder):
    """A floor (one file) and a box moved between frames 0 and 1 (a file per frame); returns the
    flags that load frame ``k`` (``None``: the sequence's template)."""
    (folder / "floor.obj").write_text(box_obj((-3, -0.2, -3), (3, 0, 3), "floor"))
    for k in range(2):
        x = -0.4 + 0.5 * k
        (folder / f"box_{k}.obj").write_text(box_obj((x - 0.4, 0, -0.4), (x + 0.4, 0.8, 0.4), "box"))
    (folder / "scene.mtl").write_text(material("floor", Kd=(0.7, 0.7, 0.7)) + material("box", Kd=(0.8, 0.3, 0.2)))

    def files(k):
        box = folder / ("box_{frame}.obj" if k is None else f"box_{k}.obj")
        return ["-obj", str(folder / "floor.obj"), "-obj", str(box), "-mtl", str(folder / "scene.mtl")]
    return files


def _cli(folder, *args, out):
    assert main([*args, *RENDER, "-out", str(folder / out)]) == 0


@pytest.mark.parametrize("kind", sorted(KINDS))
def test_frame_alone_in_a_sequence_and_on_workers_is_the_same_image(tmp_path, kind):
    pytest.importorskip("dask.distributed")
    files = _frames(tmp_path)
    _cli(tmp_path, *files(1), *KINDS[kind], out="single.npy")
    _cli(tmp_path, *files(None), "--frames", "0:2", *KINDS[kind], out="seq_{frame}.npy")
    _cli(tmp_path, *files(None), "--frames", "0:2", "--workers", "2", *KINDS[kind], out="workers_{frame}.npy")
    single = np.load(tmp_path / "single.npy")
    assert single.max() > 0, "the scene renders black: the test would not see a light go missing"
    assert np.array_equal(np.load(tmp_path / "seq_1.npy"), single), f"{kind}: frame 1 of a sequence differs"
    assert np.array_equal(np.load(tmp_path / "workers_1.npy"), single), f"{kind}: frame 1 on --workers 2 differs"
    assert not np.array_equal(np.load(tmp_path / "seq_0.npy"), single), "the frames do not differ"


def test_one_image_on_workers_with_every_flag_is_the_single_image(tmp_path):
    pytest.importorskip("dask.distributed")
    flags = [*_frames(tmp_path)(0), *KINDS["sun"], *KINDS["fog"]]
    _cli(tmp_path, *flags, out="single.npy")
    _cli(tmp_path, *flags, "--workers", "2", out="workers.npy")
    assert np.array_equal(np.load(tmp_path / "workers.npy"), np.load(tmp_path / "single.npy"))


@pytest.mark.parametrize("extra", [["--frames", "0:2"], ["--workers", "2"], ["--cluster", "localhost:8786"]])
def test_light_and_fog_flags_are_taken_with_frames_and_clusters(tmp_path, extra):
    f = tmp_path / "l.txt"
    f.write_text("point position 0 1 0 intensity 3\n")
    opts = parse_args(["--sun", "0", "1", "0", "--light", "spot", "position", "0", "2", "0", "--lights", str(f),
                       "--fog", "sigma_s=0.1", *extra])
    assert [x.kind for x in opts.lights] == [0, 2, 1] and opts.fog.sigma_s == (0.1, 0.1, 0.1)
