"""A new medium kind is one module and its name in ``scene/families.py``'s ``MEDIUM_KINDS`` (issue 40).

``probe_absorber``, registered that way in a fresh process (tests/support/probe_kinds.py): a medium
that absorbs all it would scatter (coefficients (sigma_a + sigma_s, 0), its majorant the built-in
one). A fog of that kind (``Medium(model="probe_absorber")``) between the camera and an emitting
floor of radiance 1: each pixel is the mean over its rays of exp(-sigma_t r), r the distance to the
floor, in closed form. A homogeneous fog of the same coefficients would scatter light back and be
brighter; the image is the probe's. The fog of the probe kind sits beside an interior of the built-in
homogeneous kind, so the dispatch between kinds is compiled too.
"""

from __future__ import annotations

from tests.support.probe_kinds import run_probe

PROBE_ABSORBER = '''
    from types import SimpleNamespace
    import warp as wp
    from warp_spt.device.media_table import Media

    NAME = "probe_absorber"


    def declare(medium):
        return frozenset({NAME})


    def make(features):
        @wp.func
        def coefficients(media: Media, m: int, x: wp.vec3):
            return media.sigma_a[m] + media.sigma_s[m], wp.vec3(0.0, 0.0, 0.0)

        @wp.func
        def segment(media: Media, m: int, o: wp.vec3, d: wp.vec3, t: float, t_max: float):
            return t_max, media.majorant[m]

        return SimpleNamespace(coefficients=coefficients, segment=segment)
'''

SCRIPT = '''
    from dataclasses import replace
    from pathlib import Path
    import numpy as np
    from warp_spt.io.loader import load_scene
    from warp_spt.media import KINDS
    from warp_spt.rendering.tiles import RenderSettings, render_scene
    from warp_spt.scene.media import Medium
    from warp_spt.scene.sky import Sky
    from warp_spt.upload.device_scene import DeviceScene
    from tests.support.scenes import material, write_scene_files
    from tests.support.stability_scenes import quads_obj
    from tests.integrators.test_light_transport import FLOOR, FLOOR_CAM, floor_points

    SIGMA_A, SIGMA_S, W, H = 0.1, 0.3, 12, 10
    assert list(KINDS)[-1] == "probe_absorber"
    box = [(-40.0, -40.0, 60.0), (-39.0, -40.0, 60.0), (-39.0, -39.0, 60.0), (-40.0, -39.0, 60.0)]  # out of view
    objs, mtls = write_scene_files(Path(folder), "floor", quads_obj([("floor", FLOOR), ("glass", box)]),
                                   material("floor", Kd=(0.0,) * 3, Ke=(1.0,) * 3) + material("glass", Kd=(0.5,) * 3))
    fog = Medium(sigma_a=SIGMA_A, sigma_s=SIGMA_S, model="probe_absorber")
    scene = replace(load_scene(objs, mtls, warn=lambda m: None), fog=fog,
                    interiors={"glass": Medium(sigma_s=1.0)})
    dev = DeviceScene(scene)
    assert dev.features.media == ("homogeneous", "probe_absorber"), dev.features.media
    rs = RenderSettings(width=W, height=H, spp=256, max_depth=3, seed=2, sky=Sky.constant(0.0, 0.0, 0.0),
                        integrator="volpath", sampler="independent")
    img = render_scene(dev, FLOOR_CAM, rs).image.astype(np.float64).mean(axis=2)
    hits = floor_points(FLOOR_CAM, W, H, 8)
    r = np.linalg.norm(hits - np.asarray(FLOOR_CAM.position), axis=-1)
    expected = np.exp(-(SIGMA_A + SIGMA_S) * r).mean(axis=2)
    se = np.sqrt(expected * (1 - expected) / rs.spp)         # per pixel: each sample is 0 or 1
    se_mean = np.sqrt((se ** 2).mean() / (W * H))
    assert abs(img.mean() - expected.mean()) < max(5 * se_mean, 1e-3), (img.mean(), expected.mean(), se_mean)
    assert (np.abs(img - expected) < 6 * se + 1e-3).all(), np.abs(img - expected).max()
    print(f"image {img.mean():.5f}, expected {expected.mean():.5f} +- {se_mean:.5f}")
    print("ok")
'''


def test_a_medium_kind_is_one_module_and_a_name(tmp_path):
    print(run_probe(tmp_path, "MEDIUM_KINDS", "media", {"probe_absorber": PROBE_ABSORBER}, SCRIPT))


def test_the_registry_is_the_list_and_a_medium_names_its_kind():
    """The device registry is ``MEDIUM_KINDS`` in order; a medium names a kind of the list or is refused."""
    import pytest

    from warp_spt.media.registry import KINDS
    from warp_spt.scene.families import MEDIUM_KINDS
    from warp_spt.scene.media import Medium

    assert tuple(KINDS) == MEDIUM_KINDS
    assert Medium(sigma_s=1.0).kind == "homogeneous" and Medium(sigma_s=1.0, model="grid").kind == "grid"
    with pytest.raises(ValueError, match="model must be a medium kind"):
        Medium(sigma_s=1.0, model="smoke").check()
