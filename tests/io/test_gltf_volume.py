"""KHR_materials_volume onto the interior media: thick coloured glass absorbs by Beer-Lambert.

A closed glass cube (ior 1.5, smooth, side 2) between the camera and an emitter of radiance 1, black
sky, rendered by volpath: along the axis each pixel is the slab's incoherent sum over its internal
reflections, T^2 e^(-sigma d) / (1 - R^2 e^(-2 sigma d)) with R = 0.04 (normal incidence) and T = 1 - R,
sigma = -ln(attenuationColor) / attenuationDistance, d = 2; within 4.5 standard errors (estimated
over the pixels). Thickness 0 is thin-walled with no medium, an open mesh is drawn thin-walled with
a warning, bad values name the file and the JSON pointer.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.support.format_files import CUBE_POSITIONS, CUBE_TRIANGLES, GltfBuilder
from warp_spt.io.gltf import parse_gltf_bytes
from warp_spt.io.loader import load_scene
from warp_spt.rendering import tiles as R
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.camera import Camera
from warp_spt.scene.errors import SceneError
from warp_spt.scene.sky import Sky
from warp_spt.upload.device_scene import DeviceScene

CAM = Camera(position=(0, -6, 0), direction=(0, 1, 0), fov=6.0, aperture=0.0, focus=6.0)
COLOUR, DISTANCE = (0.5, 0.8, 1.0), 1.0


def _glass_gltf(volume: dict | None, triangles=CUBE_TRIANGLES) -> bytes:
    g = GltfBuilder()
    g.mesh(CUBE_POSITIONS, triangles)
    g.doc["meshes"][0]["primitives"][0]["material"] = 0
    quad = np.array([(-4, 3, -4), (4, 3, -4), (4, 3, 4), (-4, 3, 4)], np.float64)
    g.mesh(quad, np.array([[0, 1, 2], [0, 2, 3]], np.int32))
    g.doc["meshes"][1]["primitives"][0]["material"] = 1
    ext = {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": 1.5}}
    if volume is not None:
        ext["KHR_materials_volume"] = volume
    g.doc["materials"] = [
        {"name": "glass", "pbrMetallicRoughness": {"metallicFactor": 0.0, "roughnessFactor": 0.0}, "extensions": ext},
        {"name": "light", "pbrMetallicRoughness": {"baseColorFactor": [0, 0, 0, 1], "metallicFactor": 0.0},
         "emissiveFactor": [1, 1, 1]}]
    g.doc["extensionsUsed"] = sorted(ext)
    g.node(mesh=0, scale=[2.0, 2.0, 2.0])
    g.node(mesh=1)
    return g.gltf()[0]


def _scene(volume, name="glass.gltf", **kw):
    return load_scene([parse_gltf_bytes(_glass_gltf(volume, **kw), name)])


def test_thick_coloured_glass_absorbs_by_beer_lambert():
    scene = _scene({"thicknessFactor": 1.0, "attenuationColor": list(COLOUR), "attenuationDistance": DISTANCE})
    sigma = -np.log(COLOUR) / DISTANCE
    (medium,) = scene.interiors.values()
    np.testing.assert_allclose(medium.sigma_a, sigma, rtol=1e-6)
    assert medium.sigma_s == (0.0, 0.0, 0.0)
    res = R.render_scene(DeviceScene(scene), CAM, RenderSettings(width=16, height=16, spp=64, max_depth=10, seed=2,
                                                                 integrator="volpath", sky=Sky.constant(0, 0, 0)))
    px = res.image.reshape(-1, 3).astype(np.float64)
    mean, se = px.mean(0), px.std(0, ddof=1) / math.sqrt(len(px))
    r = 0.04
    att = np.exp(-sigma * 2.0)
    expected = (1 - r) ** 2 * att / (1 - r * r * att * att)
    assert np.all(np.abs(mean - expected) < 4.5 * se + 1e-4), (mean, expected, se)
    assert mean[0] < 0.3 < 0.9 < mean[2]           # the absorption is there: the comparison can fail


def test_thin_walled_clear_and_open_glass_have_no_medium():
    for volume in (None, {"thicknessFactor": 0.0, "attenuationColor": list(COLOUR), "attenuationDistance": 1.0},
                   {"thicknessFactor": 1.0}):              # the last: thick, but clear (nothing absorbs)
        scene = _scene(volume)
        assert not scene.interiors, volume
        assert bool(scene.materials.thin[scene.materials.names.index("glass.gltf: glass")]) == (
            volume is None or volume["thicknessFactor"] == 0.0)
    thick = {"thicknessFactor": 1.0, "attenuationColor": list(COLOUR), "attenuationDistance": 1.0}
    d = parse_gltf_bytes(_glass_gltf(thick, CUBE_TRIANGLES[:-1]), "open.gltf")     # one triangle short
    assert any("open.gltf: material 'open.gltf: glass' has KHR_materials_volume but its surfaces are not closed" in w
               for w in d.warnings), d.warnings
    scene = load_scene([d])
    assert not scene.interiors and scene.materials.thin[scene.materials.names.index("open.gltf: glass")]


@pytest.mark.parametrize("volume, key", [
    ({"thicknessFactor": 1, "attenuationColor": [1.2, 0.5, 0.5]}, "attenuationColor"),
    ({"thicknessFactor": 1, "attenuationDistance": 0}, "attenuationDistance"),
    ({"thicknessFactor": 1, "attenuationColor": [0.5, 0.5]}, "attenuationColor")])
def test_bad_attenuation_names_the_file_and_pointer(volume, key):
    with pytest.raises(SceneError) as info:
        parse_gltf_bytes(_glass_gltf(volume), "bad.gltf")
    assert info.value.path == "bad.gltf" and f"/materials/0/extensions/KHR_materials_volume/{key}" in str(info.value), \
        str(info.value)
