"""volpath against Mitsuba 3's volpath: a cube of homogeneous chromatic medium and one of a density
grid, behind pass-through boundaries, under an area light and a grey sky (issue 35, check 6).

The references were rendered once by ``tests/data/make_mitsuba_volume_refs.py`` (the scenes:
``tests/support/mitsuba_volume_scenes.py``); Mitsuba is not needed here. Per 4 x 4 pixel block and for the
whole image, Welch's t between our batches and the reference's, against Student t bounds with a
family-wise false-failure probability of 1e-4 per scene (as tests/bsdfs/test_materials_mitsuba.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.io.loader import load_scene
from warp_spt.rendering import tiles as R
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.sky import Sky

from tests.support import mitsuba_scenes as MS
from tests.support import mitsuba_volume_scenes as VS
from tests.bsdfs.test_materials_mitsuba import camera, comparison, describe

REFS = Path(__file__).parents[1] / "data" / "mitsuba_volume_refs.npz"
BATCHES = 16
SPP = 32

pytestmark = pytest.mark.skipif(not REFS.exists(), reason=f"{REFS.name} absent (make_mitsuba_volume_refs.py)")


@pytest.fixture(scope="module")
def refs():
    with np.load(REFS) as z:
        return {k: z[k] for k in z.files}


def ours(folder: Path, name: str) -> np.ndarray:
    """(BATCHES, blocks, 3): our 4 x 4 block means per batch (disjoint sample ranges)."""
    host = load_scene(*VS.write_files(folder / name, name), warn=lambda message: None)
    if name == "grid":
        host.interiors = {"m": VS.grid_medium()}
    dev = DeviceScene(host)
    out = []
    for k in range(BATCHES):
        res = R.render_scene(dev, camera(), RenderSettings(
            width=MS.WIDTH, height=MS.HEIGHT, spp=SPP, sample_offset=k * SPP, max_depth=VS.MAX_DEPTH, seed=11,
            integrator="volpath", sky=Sky.constant(MS.SKY, MS.SKY, MS.SKY)))
        assert res.stats.dropped_samples == 0
        img = res.image.astype(np.float64)
        out.append(img.reshape(MS.HEIGHT // 4, 4, MS.WIDTH // 4, 4, 3).mean(axis=(1, 3)).reshape(-1, 3))
    return np.stack(out)


def test_the_references_say_how_they_were_made(refs):
    s = json.loads(str(refs["settings"]))
    assert s["scenes"] == list(VS.SCENES) and s["spp"] * s["batches"] >= 8192


@pytest.mark.parametrize("name", VS.SCENES)
def test_volpath_matches_mitsuba(refs, scene_dir, name):
    c = comparison(ours(scene_dir, name), refs[f"{name}_blocks"].astype(np.float64))
    assert c["worst"] < c["bound"] and c["total"] < c["bound_total"], describe(c)
    # the medium is seen: without it the cube's middle would be the bare sky (0.25 in every channel)
    assert np.abs(refs[f"{name}_mean"][12:20, 12:20].mean(axis=(0, 1)) - MS.SKY).max() > 0.06
    print(name, describe(c))
