"""Distributed rendering on a LocalCluster (loopback only, two worker processes, tiny images).

The reference for every cluster image is the single-process renderer with the same seed and
settings; equality is exact (np.array_equal on the float64 sums), not a tolerance.
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("distributed")

import warp_spt  # noqa: E402
from warp_spt import cluster  # noqa: E402
from warp_spt.rendering.schedule import pass_ranges  # noqa: E402
from warp_spt.rendering.settings import RenderSettings  # noqa: E402

from tests.support.scenes import box_obj, material, write_scene_files  # noqa: E402

TIMEOUT = 180.0        # seconds: bounds every cluster render in these tests
CAMERA = warp_spt.Camera(position=(0.0, -0.9, 0.0), direction=(0.0, 1.0, 0.0), fov=70.0, focus=1.0,
                         aperture=0.02)


@pytest.fixture(scope="module")
def small_scene(tmp_path_factory):
    """A room with a light, a glossy box and a glass sphere: meshes, spheres, refraction, emitters."""
    obj = (box_obj((-1, -1, -1), (1, 1, 1), "wall") + "o light\n"
           + "\n".join(f"v {x} {y} 0.99" for x, y in ((-0.3, -0.3), (0.3, -0.3), (0.3, 0.3), (-0.3, 0.3)))
           + "\nusemtl lamp\nf 9 10 11 12\nusemtl glass\nb 0.3 0.2 -0.6 0.3\n")
    mtl = (material("wall", Kd=(0.7, 0.6, 0.5), Roughness=0.9) + material("lamp", Kl=(8, 8, 8))
           + material("glass", Kn=1.5, Refractable=True, Roughness=0))
    objs, mtls = write_scene_files(tmp_path_factory.mktemp("cluster"), "room", obj, mtl)
    return warp_spt.load_scene(objs, mtls, warn=lambda m: None)


@pytest.fixture(scope="module")
def client():
    with cluster.local_client(2) as c:
        yield c


def _reference(scene, **kw) -> warp_spt.Film:
    return warp_spt.render_film(scene, CAMERA, **kw)


def test_tasks_cover_every_row_and_pass_once_in_order():
    s = RenderSettings(width=16, height=16, spp=1000, sample_offset=5)
    passes = pass_ranges(s.spp, s.width, s.height, s.sample_offset)
    assert sum(c for _, c in passes) == 1000 and passes[0][0] == 5
    assert [a for a, _ in passes] == list(np.cumsum([5] + [c for _, c in passes[:-1]]))
    for task_spp in (None, 1, 256, 700, 5000):
        for tile_rows in (None, 1, 5, 16, 40):
            tasks = cluster.plan(s, 3, cluster.ClusterOptions(task_spp=task_spp, tile_rows=tile_rows))
            for y in range(16):          # every row gets every pass once, in pass order
                assert [p for t in tasks if t.rows[0] <= y < t.rows[1] for p in t.passes] == passes
    for bad in (dict(task_spp=0), dict(tile_rows=-1), dict(tile_rows=2.5), dict(timeout=0)):
        with pytest.raises(ValueError, match=next(iter(bad))):
            cluster.ClusterOptions(**bad)


def test_default_row_tiles_keep_workers_busy_and_task_films_small():
    one_pass = RenderSettings(width=128, height=128, spp=8)           # a single pass: only tiles split it
    assert len(cluster.plan(one_pass, 4)) == 4 * cluster.TASKS_PER_WORKER
    many_passes = RenderSettings(width=128, height=128, spp=8 * 64)
    assert {t.rows for t in cluster.plan(many_passes, 4)} == {(0, 128)}
    huge = RenderSettings(width=3840, height=2160, spp=8)               # one pass is 199 MB of float64 RGB
    tiles = {t.rows for t in cluster.plan(huge, 1, cluster.ClusterOptions(task_spp=8))}
    assert max(b - a for a, b in tiles) * 3840 * 24 <= cluster.TASK_FILM_BYTES < 3840 * 2160 * 24


def test_renderer_rows_are_exactly_those_rows_of_the_full_render(small_scene):
    """The renderer's row window (render_scene(..., rows=...)), on which tile tasks stand."""
    kw = dict(width=13, height=9, spp=24, max_depth=4, seed=5, tile_pixels=7)
    full = _reference(small_scene, **kw)
    for rows in [(0, 9), (0, 1), (3, 7), (8, 9)]:
        part = _reference(small_scene, rows=rows, **kw)
        assert part.spp == 24 and np.array_equal(part.sum, full.sum[rows[0]:rows[1]])
    for bad in [(0, 0), (5, 3), (0, 10), (-1, 2), [0, 2]]:
        with pytest.raises(ValueError, match="rows"):
            _reference(small_scene, rows=bad, **kw)


def test_cluster_render_is_bit_identical_to_one_process(client, small_scene):
    kw = dict(width=20, height=12, spp=700, max_depth=5, seed=7, sky=warp_spt.Sky.gradient())
    ref = _reference(small_scene, **kw)
    seen = []
    film = cluster.render_film(client, small_scene, CAMERA, task_spp=1, tile_rows=5, timeout=TIMEOUT,
                               progress=lambda done, total: seen.append((done, total)), **kw)
    assert len(pass_ranges(700, 20, 12)) >= 3     # really several passes x 3 tiles
    assert film.spp == ref.spp == 700
    assert np.array_equal(film.sum, ref.sum)
    assert seen[-1] == (20 * 12 * 700, 20 * 12 * 700) and [d for d, _ in seen] == sorted(d for d, _ in seen)
    # each worker uploaded the scene at most once for all its tasks
    builds = client.run(lambda dask_worker: dask_worker.plugins[cluster.PLUGIN_NAME].builds)
    assert set(builds.values()) <= {0, 1} and sum(builds.values()) >= 1


def test_a_different_seed_gives_a_different_image(client, small_scene):
    kw = dict(width=8, height=8, spp=64, max_depth=3)
    a = cluster.render_film(client, small_scene, CAMERA, seed=1, timeout=TIMEOUT, **kw)
    b = cluster.render_film(client, small_scene, CAMERA, seed=2, timeout=TIMEOUT, **kw)
    assert not np.array_equal(a.sum, b.sum)


def test_animation_frames_on_the_cluster_equal_local_frames(client, tmp_path):
    """Frames x sample ranges as tasks: every frame equals the one rendered here, bit for bit."""
    from warp_spt.animation import CameraPath, render_animation

    from tests.support.scenes import write_ball_sequence

    objs, mtls = write_ball_sequence(tmp_path, range(3))
    path = CameraPath.from_json({"keyframes": [
        {"frame": 0, "position": [0, -0.9, 0], "direction": [0, 1, 0], "fov": 70, "focus": 1},
        {"frame": 2, "position": [0.3, -0.9, 0.2], "direction": [-0.2, 1, -0.1], "fov": 60, "focus": 1}]})
    kw = dict(width=16, height=12, spp=1000, max_depth=4, seed=9)
    here = dict(render_animation(objs, mtls, range(3), path, **kw))
    meshes_before = client.run(lambda dask_worker: dask_worker.plugins[cluster.PLUGIN_NAME].mesh_builds)
    there = dict(render_animation(objs, mtls, range(3), path, client=client,
                                  options=cluster.ClusterOptions(task_spp=1, timeout=TIMEOUT), **kw))
    assert sorted(there) == [0, 1, 2]
    for k in range(3):
        assert np.array_equal(there[k], here[k])
    # the static room is the only mesh (the balls are spheres): uploaded at most once per worker
    meshes_after = client.run(lambda dask_worker: dask_worker.plugins[cluster.PLUGIN_NAME].mesh_builds)
    assert all(meshes_after[w] - meshes_before.get(w, 0) <= 1 for w in meshes_after)


def test_killed_worker_costs_only_its_tasks(client, small_scene):
    """SIGKILL a worker process while it runs a tile task: Dask reruns its tasks; the image is unchanged."""
    kw = dict(width=32, height=32, spp=64 * 12, max_depth=6, seed=11)
    ref = _reference(small_scene, **kw)
    pids_before = client.run(os.getpid)
    killed = {}

    def kill_a_busy_worker(done: int, total: int) -> None:
        if killed or done >= total:
            return
        busy = [w for w, keys in client.processing().items() if keys]
        if busy:
            pid = pids_before[busy[0]]
            os.kill(pid, signal.SIGKILL)
            killed.update(pid=pid, remaining=total - done)

    film = cluster.render_film(client, small_scene, CAMERA, task_spp=64, tile_rows=16, timeout=TIMEOUT,
                               progress=kill_a_busy_worker, **kw)
    assert killed, "no worker was busy after the first task finished"
    assert killed["remaining"] > 0
    assert np.array_equal(film.sum, ref.sum)
    client.wait_for_workers(2, timeout=60)        # the nanny restarted the killed process
    assert killed["pid"] not in client.run(os.getpid).values()


def test_missing_dask_gives_an_install_hint(monkeypatch):
    monkeypatch.setitem(sys.modules, "distributed", None)
    monkeypatch.delitem(sys.modules, "warp_spt.cluster")
    with pytest.raises(ImportError, match=r"warp-spt\[cluster\]"):
        importlib.import_module("warp_spt.cluster")


def test_cli_cluster_and_workers_write_the_single_process_image(client, small_scene, tmp_path, scene_dir):
    """--cluster ADDRESS (this module's cluster) and --workers 1 give the same .npy as a plain render."""
    from warp_spt.cli.main import main

    from tests.support.scenes import write_ball_sequence

    objs, mtls = write_ball_sequence(tmp_path, [0])
    base = ["-mtl", mtls[0], "-obj", objs[0], "-obj", str(tmp_path / "ball_00.obj"), "-res", "10", "8",
            "-sr", "300", "-depth", "4", "--seed", "3", "--quiet", "-cam", "0", "-0.9", "0", "0", "1", "0",
            "70", "1", "0"]
    assert main(base + ["-out", str(tmp_path / "here.npy")]) == 0
    assert main(base + ["-out", str(tmp_path / "there.npy"), "--cluster", client.scheduler.address]) == 0
    here = np.load(tmp_path / "here.npy")
    assert np.array_equal(np.load(tmp_path / "there.npy"), here)
    # without -cam the CLI frames the scene (a probe render): --workers renders that same view
    framed = base[:base.index("-cam")]
    assert main(framed + ["-out", str(tmp_path / "framed.npy")]) == 0
    assert main(framed + ["-out", str(tmp_path / "local.npy"), "--workers", "1"]) == 0
    assert np.array_equal(np.load(tmp_path / "local.npy"), np.load(tmp_path / "framed.npy"))
    assert not np.array_equal(np.load(tmp_path / "local.npy"), here)


def test_cli_unreachable_cluster_is_one_line(tmp_path, capsys, monkeypatch):
    from functools import partial

    from warp_spt.cli.main import main

    monkeypatch.setattr(cluster, "connect", partial(cluster.connect, timeout=2))
    out = tmp_path / "x.png"
    assert main(["--cluster", "tcp://127.0.0.1:9", "-res", "4", "4", "-sr", "1", "--quiet", "-out", str(out)]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot connect to the cluster at tcp://127.0.0.1:9" in err[0]
    assert not out.exists()


def test_a_second_render_keeps_the_workers_scene_caches(client, small_scene):
    """Scenes uploaded by one render stay on the workers for the next (the cache is not replaced)."""
    def caches(dask_worker):
        c = dask_worker.plugins[cluster.PLUGIN_NAME]
        return c.token, c.builds
    kw = dict(width=6, height=5, spp=16, max_depth=2, timeout=TIMEOUT)
    cluster.render_film(client, small_scene, CAMERA, **kw)
    before = client.run(caches)
    cluster.render_film(client, small_scene, CAMERA, seed=4, **kw)       # same scene, other settings
    after = client.run(caches)
    assert {w: t for w, (t, _) in after.items()} == {w: t for w, (t, _) in before.items()}


def _batch_films_are_plain_renders(scene, result, seed: int, **kw) -> None:
    """Batch b of a budgeted cluster render is the plain single-process render of its samples with
    seed batch_seed(seed, b): an independent reference, bit for bit."""
    from warp_spt.rendering.schedule import batch_seed

    assert (result.counts[:, :1, :1] == result.counts).all()
    for b, n in enumerate(result.counts[:, 0, 0]):
        if n:
            ref = _reference(scene, spp=int(n), seed=batch_seed(seed, b), **kw)
            assert np.array_equal(result.sums[b], ref.sum)
        else:
            assert not result.sums[b].any()


def test_target_error_on_the_cluster_stops_on_whole_passes(client, small_scene):
    """--target-error on a cluster: rounds until the estimate is met; the run equals one asked for its samples."""
    kw = dict(width=12, height=10, max_depth=4)
    rs = RenderSettings(spp=1 << 20, seed=3, **kw)
    errors = []
    res = cluster.render_progressive(client, small_scene, CAMERA, rs, cluster.ClusterOptions(tile_rows=4),
                                     target_error=0.02, on_pass=lambda r: errors.append(r.relative_error))
    assert res.stats.stopped_by == "error" and res.relative_error <= 0.02 < errors[0]
    assert res.stats.passes == len(errors) >= 2
    _batch_films_are_plain_renders(small_scene, res, 3, **kw)
    again = cluster.render_progressive(client, small_scene, CAMERA, replace(rs, spp=res.spp_total))
    assert again.stats.stopped_by == "spp" and np.array_equal(again.sums, res.sums)
    assert again.relative_error == res.relative_error


def test_time_budget_on_the_cluster(client, small_scene):
    """A time budget ends the render; what it rendered is still the plain renders of its samples."""
    import time

    kw = dict(width=12, height=10, max_depth=4)
    t0 = time.perf_counter()
    res = cluster.render_progressive(client, small_scene, CAMERA, RenderSettings(spp=1 << 20, seed=8, **kw),
                                     time_budget=4.0, started=t0)
    assert res.stats.stopped_by == "time" and res.stats.passes >= 1
    assert np.isfinite(res.relative_error)
    _batch_films_are_plain_renders(small_scene, res, 8, **kw)
    with pytest.raises(ValueError, match="time_budget"):
        cluster.render_progressive(client, small_scene, CAMERA, time_budget=-1.0)


def test_cli_target_error_on_the_cluster(client, tmp_path, capsys):
    """--target-error with --cluster: rounds until the estimate is met; other budget flags are refused."""
    from warp_spt.cli.main import main

    from tests.support.scenes import write_ball_sequence

    objs, mtls = write_ball_sequence(tmp_path, [0])
    base = ["-mtl", mtls[0], "-obj", objs[0], "-obj", str(tmp_path / "ball_00.obj"), "-res", "10", "8",
            "-depth", "3", "-cam", "0", "-0.9", "0", "0", "1", "0", "70", "1", "0", "--cluster", client.scheduler.address]
    out = tmp_path / "x.npy"
    assert main(base + ["--target-error", "3%", "-out", str(out)]) == 0
    err = capsys.readouterr().err
    assert "stopped by error" in err and out.exists() and np.load(out).shape == (8, 10, 3)
    assert main(base + ["--target-error", "3%", "--adaptive", "-out", str(tmp_path / "y.npy")]) == 2
    assert "--adaptive is not supported on a cluster" in capsys.readouterr().err
    assert not (tmp_path / "y.npy").exists()
