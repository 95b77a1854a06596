"""The light flags (--sun, --light, --lights) and --fog through every front end of the command line.

They are part of the scene, not of one runner: frame k alone, frame k of a sequence rendered here,
the same sequence on ``--workers 2`` and a single ``--workers 2`` image are one image bit for bit
(the determinism rule of docs/architecture.md: same scene, camera, settings and seed, same film).
The expected image is the single render on this machine, which tests/emitters/test_punctual_front.py and
tests/media/test_volumes.py check against analytic values; a runner that dropped a light or the fog on
the way to its workers would render another image.
"""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.cli.main import main
from warp_spt.cli.options import parse_args

from tests.support.scenes import box_obj, material

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


# ---------------------------------------------------------------- the API: animation and cluster

def _api_scene(tmp_path, k: int):
    from warp_spt.io.loader import load_scene

    files = _frames(tmp_path)(k)
    return load_scene([files[1], files[3]], [files[5]]), [files[1], files[3]], [files[5]]


SUN = dict(direction=(0.3, 1.0, 0.5), color=(2.0, 2.0, 2.0), radius_deg=1.0)
LAMP = dict(position=(-1.0, 2.0, 1.0), intensity=(20.0, 20.0, 20.0))
FOG = dict(sigma_s=0.05, sigma_a=(0.005, 0.01, 0.02), g=0.3)


def test_the_animation_api_takes_lights_and_fog_as_a_single_render_does(tmp_path):
    """render_animation(..., lights=, fog=) here and on two local workers, frame 1 against
    render_scene of frame 1's scene given the same lights (Scene.add_light) and fog."""
    pytest.importorskip("dask.distributed")
    from warp_spt import cluster
    from warp_spt.animation import ObjSequence, render_animation
    from warp_spt.rendering.settings import RenderSettings
    from warp_spt.rendering.tiles import render_scene
    from warp_spt.scene.camera import Camera
    from warp_spt.scene.lights import PointLight, SunLight
    from warp_spt.scene.media import Medium

    scene, _, mtls = _api_scene(tmp_path, 1)
    template = str(tmp_path / "box_{frame}.obj")
    objs = [str(tmp_path / "floor.obj"), template]
    cam = Camera.look_at((4.0, 3.0, 5.0), (0.0, 0.3, 0.0), up=(0.0, 1.0, 0.0))
    rs = RenderSettings(width=16, height=12, spp=2, max_depth=3, integrator="volpath")
    lights, fog = [SunLight(**SUN), PointLight(**LAMP)], Medium(**FOG)
    scene.add_light(lights[0]).add_light(lights[1])
    scene.fog = fog
    single = render_scene(scene, cam, rs).image
    here = dict(render_animation(objs, mtls, [0, 1], cam, rs, lights=lights, fog=fog))
    assert np.array_equal(here[1], single)
    assert not np.array_equal(here[0], single)
    with cluster.local_client(2) as client:
        seq = ObjSequence(objs, mtls, lights=lights, fog=fog)
        remote = dict(render_animation(seq, frames=[0, 1], camera=cam, settings=rs, client=client))
    assert np.array_equal(remote[1], single) and np.array_equal(remote[0], here[0])
    without = render_scene(_api_scene(tmp_path, 1)[0], cam, rs).image
    assert not np.array_equal(without, single), "the lights and the fog change the image"


def test_the_cluster_api_ships_a_scenes_lights_fog_and_environment(tmp_path):
    """cluster.render_scene of a Scene with add_light, a fog, and an environment as its sky (apart
    and together with RenderSettings.sky) gives render_scene's image bit for bit."""
    pytest.importorskip("dask.distributed")
    from dataclasses import replace

    from warp_spt import cluster
    from warp_spt.rendering.settings import RenderSettings
    from warp_spt.rendering.tiles import render_scene
    from warp_spt.scene.camera import Camera
    from warp_spt.scene.lights import SpotLight, SunLight
    from warp_spt.scene.media import Medium
    from warp_spt.scene.sky import Sky

    yy = np.linspace(0.2, 1.0, 8)[:, None, None]
    env = Sky.environment(np.broadcast_to(yy * np.array([0.6, 0.7, 1.0]), (8, 16, 3)).copy(), rotate=30.0,
                          strength=1.5, background=(0.1, 0.1, 0.1))
    lit, _, _ = _api_scene(tmp_path, 0)
    lit.add_light(SunLight(**SUN)).add_light(SpotLight(position=(0.0, 2.5, 0.0), direction=(0.0, -1.0, 0.0),
                                                       intensity=30.0, outer_deg=35.0))
    lit.sky = env
    foggy = replace(lit, sky=None, fog=Medium(**FOG))
    cam = Camera.look_at((4.0, 3.0, 5.0), (0.0, 0.3, 0.0), up=(0.0, 1.0, 0.0))
    cases = [(lit, RenderSettings(width=16, height=12, spp=2, max_depth=3, sky=None)),
             (foggy, RenderSettings(width=16, height=12, spp=2, max_depth=3, integrator="volpath")),
             (replace(lit, sky=None), RenderSettings(width=16, height=12, spp=2, max_depth=3, sky=env))]
    with cluster.local_client(2) as client:
        for scene, rs in cases:
            assert np.array_equal(cluster.render_scene(client, scene, cam, rs).image,
                                  render_scene(scene, cam, rs).image)
