"""This round's kinds on a CUDA device (issues 29, 34, 35): skipped where there is none.

``tests/gpu/test_device_render.py`` renders the Cornell box on the device; this file renders what came after it --
the ``pbr`` material kind under an HDR environment map, sun, point and spot lights, the light tree
over many emitters, and ``volpath`` with a chromatic homogeneous medium, a NanoVDB density grid and
a scene-wide fog -- on the device and on the CPU, and asks that the two agree statistically: per
4x4 block over independent batches (disjoint sample ranges), Welch t against Student's quantile
(``stability_scenes.compare``). Each scene also checks that the device scene really uses the kind
(its ``Features``), so a silently dropped feature cannot pass.

The device is ``WARP_SPT_TEST_DEVICE`` (default ``cuda``), as in ``tests/gpu/test_device_render.py``; with
``WARP_SPT_TEST_DEVICE=cpu`` the comparisons run CPU against CPU (independent seeds), which is how
they are checked on machines without a GPU. ``benchmarks/gpu_check.py`` runs this file on a GPU.
"""

from __future__ import annotations

import os
from dataclasses import replace

import numpy as np
import pytest

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.io.loader import load_scene
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene
from warp_spt.runtime.warp_init import check_device
from warp_spt.scene.camera import Camera
from warp_spt.scene.lights import PointLight, SpotLight, SunLight
from warp_spt.scene.media import Medium
from warp_spt.scene.sky import Sky

from tests.support.scenes import box_obj, material, write_scene_files
from tests.support.stability_scenes import assert_same_image, cornell_camera, cornell_files, quads_obj

DEVICE = os.environ.get("WARP_SPT_TEST_DEVICE", "cuda")
SIZE = 24
BATCHES = 8


@pytest.fixture(scope="module")
def device() -> str:
    try:
        check_device(DEVICE)
    except ValueError as err:
        pytest.skip(str(err))
    return DEVICE


def _sun_and_sky_map(width: int = 64) -> np.ndarray:
    """A Y-up lat-long map: a sky gradient and a bright disc (the environment sampling's hard case)."""
    h = width // 2
    theta = np.pi * (np.arange(h) + 0.5) / h
    phi = 2 * np.pi * (np.arange(width) + 0.5) / width
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    img = np.stack([0.3 + 0.5 * np.cos(th) ** 2, 0.4 + 0.3 * np.sin(ph) ** 2, 0.8 + 0.0 * th], -1)
    img[(np.abs(th - 0.7) < 0.12) & (np.abs(ph - 2.0) < 0.12)] = (400.0, 360.0, 300.0)
    return img.astype(np.float32)


SPHERES_CAM = Camera.look_at((0.0, 0.8, 7.5), (0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov=48.0)
BALL_CAM = Camera(position=(0, -6, 0), direction=(0, 1, 0), fov=22.0, aperture=0.0, focus=6.0)
SKY = Sky.constant(1.0, 0.8, 0.6)


def _pbr_under_a_map(folder):
    """A diffuse, a rough metal and a rough glass sphere (the pbr kind) lit by an HDR map only."""
    obj = "\n".join(f"usemtl {m}\nb {x} 0 0 1" for m, x in (("grey", -2.2), ("metal", 0.0), ("glass", 2.2)))
    mtl = ("newmtl grey\nKd 0.6 0.6 0.6\nPr 1\n"
           "newmtl metal\nKd 0.9 0.6 0.3\nPm 1\nPr 0.35\n"
           "newmtl glass\nKd 1 1 1\nPr 0.2\nNi 1.5\nTf 1 1 1\nd 0\n")
    host = load_scene(*write_scene_files(folder, "pbr_env", obj, mtl), warn=lambda message: None)
    host = replace(host, sky=Sky.environment(_sun_and_sky_map(), up=(0.0, 1.0, 0.0)))
    return host, SPHERES_CAM, {"spp": 8, "max_depth": 12}, lambda f: "pbr" in f.material_kinds and f.lit("environment")


def _punctual(folder):
    host = load_scene(*cornell_files(folder), warn=lambda message: None)
    lights = [SunLight(direction=(0.3, 1.0, 0.4), color=(2.0, 1.8, 1.5), radius_deg=2.0),
              PointLight(position=(0.2, 0.4, 0.1), intensity=(0.6, 0.5, 0.4)),
              SpotLight(position=(-0.2, 0.8, 0.3), direction=(0.0, -1.0, 0.0), intensity=(1.5, 1.5, 2.0),
                        inner_deg=10.0, outer_deg=30.0)]
    return (replace(host, lights=lights), cornell_camera(), {"sky": Sky.constant(0.05, 0.05, 0.05)},
            lambda f: f.lit("punctual"))


def _many_lamps(folder):
    xs, ys = np.linspace(-4.0, 4.0, 12), np.linspace(-2.0, 6.0, 8)
    half = 0.06
    lamps = [("lamp", [(x - half, y - half, 0.6), (x + half, y - half, 0.6), (x + half, y + half, 0.6),
                       (x - half, y + half, 0.6)]) for x in xs.tolist() for y in ys.tolist()]
    floor = [(-6.0, -4.0, 0.0), (6.0, -4.0, 0.0), (6.0, 8.0, 0.0), (-6.0, 8.0, 0.0)]
    mtl = material("floor", Kd=(0.7,) * 3, Roughness=1) + material("lamp", Kd=(0, 0, 0), Kl=(40.0,) * 3)
    host = load_scene(*write_scene_files(folder, "lamps", quads_obj([("floor", floor), *lamps]), mtl),
                      warn=lambda message: None)
    cam = Camera.look_at((0.0, -5.0, 3.0), (0.0, 2.0, 0.0), up=(0.0, 0.0, 1.0), fov=60.0)
    return host, cam, {"sky": Sky.black(), "max_depth": 3, "spp": 8}, lambda f: f.lit("triangle.tree")


def _ball_with(folder, name: str, medium: Medium | None, mtl_lines: str = ""):
    objs, mtls = write_scene_files(folder, name, "usemtl m\nb 0 0 0 1\n", "newmtl m\nindex_matched\n" + mtl_lines)
    host = load_scene(objs, mtls, warn=lambda message: None)
    if medium is not None:
        host.interiors = {"m": medium}
    return host


VOLPATH = {"integrator": "volpath", "sky": SKY, "spp": 8, "max_depth": 32}


def _homogeneous(folder):
    host = _ball_with(folder, "ball_h", None, "medium_sigma_s 1.5 2.5 0.4\nmedium_sigma_a 0.3 0.1 0.6\nmedium_g 0.5\n")
    return host, BALL_CAM, VOLPATH, lambda f: "homogeneous" in f.media


def _grid(folder):
    z, y, x = np.meshgrid(*(np.linspace(-1.0, 1.0, 12),) * 3, indexing="ij")
    density = np.clip(1.2 - (x * x + y * y + z * z), 0.0, None).astype(np.float32) * 3.0
    grid = Medium(sigma_s=(1.5, 2.0, 0.5), sigma_a=(0.3, 0.1, 0.6), g=0.3, density=density,
                  origin=(-1.5, -1.5, -1.5), voxel_size=0.25)
    return _ball_with(folder, "ball_grid", grid), BALL_CAM, VOLPATH, lambda f: "grid" in f.media


def _fog(folder):
    room = box_obj(lo=(-2.0, -2.0, -1.0), hi=(2.0, 2.0, 1.5), material="wall")
    lamp = quads_obj([("lamp", [(-0.4, -0.4, 1.45), (0.4, -0.4, 1.45), (0.4, 0.4, 1.45), (-0.4, 0.4, 1.45)])])
    mtl = material("wall", Kd=(0.6, 0.5, 0.4), Roughness=1) + material("lamp", Kd=(0, 0, 0), Kl=(8.0,) * 3)
    objs, mtls = write_scene_files(folder, "fog_room", room, mtl)
    lamp_objs, _ = write_scene_files(folder, "fog_lamp", lamp)
    host = load_scene(objs + lamp_objs, mtls, warn=lambda message: None)
    host.fog = Medium(sigma_s=(0.3, 0.4, 0.5), sigma_a=0.05, g=0.4)
    cam = Camera(position=(0, -1.8, 0.2), direction=(0, 1, 0), fov=70.0, aperture=0.0, focus=1.0)
    return host, cam, {**VOLPATH, "sky": Sky.black(), "max_depth": 16}, lambda f: "homogeneous" in f.media


# name -> builder(folder) -> (host scene, camera, RenderSettings keywords, check of the device's Features)
KIND_SCENES = {
    "pbr spheres under an environment map": _pbr_under_a_map,
    "sun, point and spot lights": _punctual,
    "the light tree over 96 lamps": _many_lamps,
    "media: volpath in a chromatic homogeneous medium": _homogeneous,
    "media: volpath in a density grid": _grid,
    "media: volpath in fog under an area light": _fog,
}


def settings(device: str, kw: dict, spp: int | None = None, seed: int = 1, sample_offset: int = 0) -> RenderSettings:
    kw = {"width": SIZE, "height": SIZE, **kw}
    if spp is not None:
        kw["spp"] = spp
    return RenderSettings(device=device, seed=seed, sample_offset=sample_offset, **kw)


@pytest.mark.parametrize("name", list(KIND_SCENES))
def test_the_device_agrees_with_the_cpu(device, tmp_path, name):
    host, camera, kw, uses = KIND_SCENES[name](tmp_path)
    dev, cpu = DeviceScene(host, device=device), DeviceScene(host, device="cpu")
    assert uses(dev.features), f"{name}: the device scene does not use the kind under test"
    spp = kw.get("spp", 4)

    def batches(d, seed):
        return np.stack([render_scene(d, camera, settings(d.device, kw, seed=seed, sample_offset=k * spp)).image
                         for k in range(BATCHES)])

    one = batches(dev, 1)
    assert np.isfinite(one).all() and one.mean() > 0.0, f"{name}: the device image is empty or not finite"
    # another seed on the CPU side: where the device is the CPU too, the batches are still independent
    assert_same_image(one, batches(cpu, 2), f"{name} on {device} vs cpu")
