"""Rendering on a CUDA device (issue 33): skipped where there is none.

The device is ``WARP_SPT_TEST_DEVICE`` (default ``cuda``); ``benchmarks/gpu_check.py`` runs this file
on a GPU machine. With ``WARP_SPT_TEST_DEVICE=cpu`` the same checks run on the CPU (every "device"
image is then a CPU image): that is how they are checked on machines without a GPU.

* Every integrator x sampler renders the Cornell box (glass, glossy, diffuse, an area light, spheres
  and meshes) on the device with finite samples only; on CUDA each pass is one launch over the whole
  image from one thread, and meshes use Warp's BVH by default.
* The device's image agrees with the CPU's, statistically: per 4x4 block over independent batches
  (disjoint sample ranges), Welch t against Student's quantile (``stability_scenes.compare``), for
  ``nee`` and for ``guided`` and ``ears``, whose training records are integer atomics.
* ``guided`` and ``ears`` are deterministic on the device: two renders are the same bit for bit
  (their records are order-independent integer sums, so concurrent threads cannot change them).
* The progressive driver and the albedo/normal pass run there too; the command line's ``--device``
  renders an image; with Warp's default device set to the other device, every integrator's
  render still allocates and launches where its scene is.
* Without the device: the API and the command line say so in one line (exit status 1).
"""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from warp_spt.upload.device_scene import WIDE_BVH_MAX_TRIANGLES, DeviceScene
from warp_spt.integrators import INTEGRATORS
from warp_spt.io.loader import load_scene
from warp_spt.rendering.aux_buffers import feature_buffers
from warp_spt.rendering.progressive import render_progressive
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene
from warp_spt.runtime.warp_init import check_device
from warp_spt.samplers import SAMPLERS
from warp_spt.scene.sky import Sky

from tests.support.stability_scenes import assert_same_image, cornell_camera, cornell_files

DEVICE = os.environ.get("WARP_SPT_TEST_DEVICE", "cuda")
SIZE = 24
BATCHES = 8


def _available(name: str) -> str | None:
    try:
        check_device(name)
        return None
    except ValueError as err:
        return str(err)


@pytest.fixture(scope="module")
def device() -> str:
    why = _available(DEVICE)
    if why is not None:
        pytest.skip(why)
    return DEVICE


@pytest.fixture(scope="module")
def host(tmp_path_factory):
    return load_scene(*cornell_files(tmp_path_factory.mktemp("gpu")), warn=lambda message: None)


@pytest.fixture(scope="module")
def scenes(host, device):
    """The Cornell box on the device and on the CPU."""
    return DeviceScene(host, device=device), DeviceScene(host, device="cpu")


def _render(dev, **kw):
    kw = {"width": SIZE, "height": SIZE, "spp": 8, "sky": Sky.constant(0.1, 0.1, 0.1), **kw}
    return render_scene(dev, cornell_camera(), RenderSettings(device=dev.device, **kw))


def _batches(dev, spp: int = 4, **kw) -> np.ndarray:
    """(BATCHES, H, W, 3): renders of disjoint sample ranges (independent estimates)."""
    return np.stack([_render(dev, spp=spp, sample_offset=k * spp, **kw).image for k in range(BATCHES)])


def _seeds(dev, **kw) -> np.ndarray:
    """(BATCHES, H, W, 3): renders with different seeds (for integrators that train on the whole image)."""
    return np.stack([_render(dev, seed=100 + k, **kw).image for k in range(BATCHES)])


def _is_cuda(device: str) -> bool:
    return device.startswith("cuda")


@pytest.mark.parametrize("sampler", list(SAMPLERS))
@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_every_integrator_and_sampler_renders_on_the_device(scenes, integrator, sampler):
    dev = scenes[0]
    res = _render(dev, integrator=integrator, sampler=sampler)
    assert res.stats.dropped_samples == 0
    assert np.isfinite(res.image).all() and res.image.mean() > 0.0
    if _is_cuda(dev.device):
        assert res.stats.tiles == 1 and res.stats.threads == 1       # one launch per pass


@pytest.mark.parametrize("integrator", list(INTEGRATORS))
def test_the_device_reaches_every_allocation_and_launch(scenes, integrator):
    """With Warp's default device set to the other one, an array made without ``device=`` would
    land there and the launch fail: every render still runs where its scene is."""
    import warp as wp

    dev, cpu = scenes
    with wp.ScopedDevice("cpu"):
        assert np.isfinite(_render(dev, integrator=integrator, spp=4).image).all()
    with wp.ScopedDevice(dev.device):
        assert np.isfinite(_render(cpu, integrator=integrator, spp=4).image).all()


def test_meshes_use_warps_bvh_on_cuda_by_default(host, device):
    dev = DeviceScene(host, device=device)
    wide = DeviceScene(host, device=device, wide_bvh_max_triangles=WIDE_BVH_MAX_TRIANGLES)
    assert wide.features.bvh_stack > 0
    if _is_cuda(device):
        assert dev.features.bvh_stack == 0 and dev.features.warp_meshes
    assert_same_image(_batches(dev), _batches(wide), f"Warp's BVH vs the wide BVH on {device}")


def test_nee_on_the_device_agrees_with_the_cpu(scenes):
    dev, cpu = scenes
    assert_same_image(_batches(dev), _batches(cpu), f"nee on {dev.device} vs cpu")


@pytest.mark.parametrize("integrator", ["guided", "ears"])
def test_trained_integrators_agree_with_the_cpu_and_are_deterministic(scenes, integrator):
    dev, cpu = scenes
    kw = {"integrator": integrator, "spp": 16}
    one, two = _render(dev, **kw), _render(dev, **kw)
    assert np.array_equal(one.film.sum, two.film.sum), f"{integrator} on {dev.device} is not deterministic"
    assert_same_image(_seeds(dev, **kw), _seeds(cpu, **kw), f"{integrator} on {dev.device} vs cpu")


def test_progressive_and_aov_passes_run_on_the_device(scenes):
    dev, cpu = scenes
    res = render_progressive(dev, cornell_camera(), width=SIZE, height=SIZE, spp=8, batches=4,
                             sky=Sky.constant(0.1, 0.1, 0.1), device=dev.device)
    assert res.stats.dropped_samples == 0 and np.isfinite(res.image).all() and res.image.mean() > 0.0
    albedo, normal = feature_buffers(dev, cornell_camera(), SIZE, SIZE, spp=2)
    albedo_cpu, normal_cpu = feature_buffers(cpu, cornell_camera(), SIZE, SIZE, spp=2)
    # the same samples: albedo and normals are the same up to rounding where the first hit is the same
    assert np.mean(np.abs(albedo - albedo_cpu) < 1e-4) > 0.95
    assert np.mean(np.abs(normal - normal_cpu) < 1e-4) > 0.95


def test_the_command_line_renders_on_the_device(device, tmp_path):
    out = tmp_path / "x.npy"
    run = subprocess.run([sys.executable, "-m", "warp_spt", "--device", device, "-res", "16", "16", "-sr", "2",
                          "-out", str(out), "--quiet"], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    img = np.load(out)
    assert img.shape == (16, 16, 3) and np.isfinite(img).all() and img.mean() > 0.0


# --------------------------------------------------------------------------------------------
# No such device: one clear line


def test_a_missing_cuda_device_is_one_clear_error(tmp_path):
    missing = "cuda:999"
    why = _available(missing)
    assert why is not None and "cuda:999" in why
    with pytest.raises(ValueError, match="cuda:999"):
        check_device(missing)
    with pytest.raises(ValueError, match="device must be"):
        check_device("gpu")
    run = subprocess.run([sys.executable, "-m", "warp_spt", "--device", missing, "-res", "8", "8", "-sr", "1",
                          "-out", str(tmp_path / "x.png")], capture_output=True, text=True, timeout=300)
    assert run.returncode == 1
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("warp-spt: error: device 'cuda:999'"), run.stderr
    assert not (tmp_path / "x.png").exists()
    run = subprocess.run([sys.executable, "-m", "warp_spt", "--device", "gpu", "-out", str(tmp_path / "x.png")],
                         capture_output=True, text=True, timeout=300)
    assert run.returncode == 2 and "--device" in run.stderr and len(run.stderr.strip().splitlines()) == 1


def test_render_settings_refuse_a_missing_device(host):
    with pytest.raises(ValueError, match="cuda:999"):
        render_scene(host, cornell_camera(), RenderSettings(width=4, height=4, spp=1, device="cuda:999"))


def test_the_cpu_keeps_its_tiles_and_wide_bvh(host):
    dev = DeviceScene(host, device="cpu")
    assert dev.features.bvh_stack > 0
    res = _render(dev, tile_pixels=100, threads=2)
    assert res.stats.tiles == -(-SIZE * SIZE // 100) and res.stats.threads == 2


def test_the_device_flag_reaches_the_settings():
    from warp_spt.cli.options import parse_args, settings_of

    assert parse_args([]).device == "cpu" and settings_of(parse_args([])).device == "cpu"
    opts = parse_args(["--device", "cuda:1"])
    assert opts.device == "cuda:1" and settings_of(opts).device == "cuda:1"
