"""A new light kind is one module and its name in ``scene/families.py``'s ``LIGHT_KINDS`` (issue 40).

Two probe kinds, registered that way in a fresh process (tests/support/probe_kinds.py), one of each
shape the dispatch tells apart by a tag: ``probe_sky``, an infinite light of constant radiance L_p
(sampled uniformly over the sphere), and ``probe_sun``, a delta light of irradiance E_p from the
zenith. They light a diffuse floor (albedo a) together with the built-in kinds of the same shapes, an
environment map of constant radiance L_e and a punctual sun of irradiance E_s from the zenith: two
infinite kinds and two delta kinds in one scene, each compiled in because it declared itself. The
floor sees only the sky above it, so its radiance is a (L_e + L_p) + a / pi (E_p + E_s) exactly,
through light sampling, BSDF sampling and their MIS weights.
"""

from __future__ import annotations

from tests.support.probe_kinds import run_probe

# An infinite light: sampled, weighed and seen by rays that miss (``le``, ``pdf_li`` by direction)
PROBE_SKY = '''
    from types import SimpleNamespace
    import numpy as np
    import warp as wp
    from warp_spt.accel.ray_queries import KIND_MISS, NO_HIT
    from warp_spt.device.sampling import TWO_PI
    from warp_spt.device.structs import Geometry
    from warp_spt.emitters.base import LightKind, LightSample, Weighed
    from warp_spt.emitters.punctual import scene_radius

    RADIANCE = 0.3


    @wp.struct
    class ProbeSky:
        radiance: wp.vec3
        prob: float


    def make(Lights, features):
        @wp.func
        def sample_li(geo: Geometry, lights: Lights, entry: int, prob: float, x: wp.vec3, u: wp.vec2) -> LightSample:
            z = 1.0 - 2.0 * u[0]
            r = wp.sqrt(wp.max(0.0, 1.0 - z * z))
            ls = LightSample()
            ls.dir = wp.vec3(r * wp.cos(TWO_PI * u[1]), r * wp.sin(TWO_PI * u[1]), z)
            ls.pdf = prob / (2.0 * TWO_PI)
            ls.t_max = NO_HIT
            ls.h.kind = KIND_MISS
            return ls

        @wp.func
        def pdf_li(lights: Lights, d: wp.vec3) -> float:
            return lights.probe_sky.prob / (2.0 * TWO_PI)

        @wp.func
        def le(lights: Lights, d: wp.vec3) -> wp.vec3:
            return lights.probe_sky.radiance

        return SimpleNamespace(sample_li=sample_li, pdf_li=pdf_li, le=le)


    def weigh(scene, sky):        # as the built-in sky: a sphere of the scene's radius seen from inside
        return Weighed(np.array([4.0 * np.pi * scene_radius(scene) ** 2 * RADIANCE / 3.0]))


    def upload(payload, prob, scene, sky, up, device):
        s = ProbeSky()
        s.radiance = wp.vec3(RADIANCE, RADIANCE, RADIANCE)
        s.prob = float(prob[0])
        return s


    KIND = LightKind("probe_sky", ProbeSky, KIND_MISS, area=False, weigh=weigh, upload=upload, make=make,
                     declare_sky=lambda sky: frozenset({"probe_sky"}))
'''

# A delta light: no ray meets it; its samples' radiance is its ``radiance``
PROBE_SUN = '''
    from types import SimpleNamespace
    import numpy as np
    import warp as wp
    from warp_spt.device.structs import Geometry
    from warp_spt.emitters.base import KIND_PUNCTUAL, LightKind, LightSample, Weighed
    from warp_spt.emitters.punctual import scene_radius

    IRRADIANCE = 1.0


    @wp.struct
    class ProbeSun:
        irradiance: wp.vec3


    def make(Lights, features):
        @wp.func
        def sample_li(geo: Geometry, lights: Lights, entry: int, prob: float, x: wp.vec3, u: wp.vec2) -> LightSample:
            ls = LightSample()
            ls.dir = wp.vec3(0.0, 0.0, 1.0)
            ls.pdf = prob
            ls.t_max = 1.0e30
            ls.h.kind = KIND_PUNCTUAL
            ls.h.t = 1.0e30
            return ls

        @wp.func
        def radiance(lights: Lights, ls: LightSample, x: wp.vec3) -> wp.vec3:
            return lights.probe_sun.irradiance

        return SimpleNamespace(sample_li=sample_li, radiance=radiance)


    def weigh(scene, sky):        # as the punctual sun: its irradiance over the disc of the scene's sphere
        return Weighed(np.array([IRRADIANCE * np.pi * scene_radius(scene) ** 2]))


    def upload(payload, prob, scene, sky, up, device):
        s = ProbeSun()
        s.irradiance = wp.vec3(IRRADIANCE, IRRADIANCE, IRRADIANCE)
        return s


    KIND = LightKind("probe_sun", ProbeSun, KIND_PUNCTUAL, area=False, weigh=weigh, upload=upload, make=make,
                     delta=True, declare=lambda scene, used, base: frozenset({"probe_sun"}))
'''

SCRIPT = '''
    from dataclasses import replace
    from pathlib import Path
    import numpy as np
    from warp_spt.emitters import KINDS, Lights
    from warp_spt.io.loader import load_scene
    from warp_spt.rendering.setup import bind
    from warp_spt.rendering.tiles import RenderSettings, render_scene
    from warp_spt.scene.lights import SunLight
    from warp_spt.scene.sky import Sky
    from warp_spt.upload.device_scene import DeviceScene
    from tests.support.scenes import material, write_scene_files
    from tests.support.stability_scenes import quads_obj
    from tests.integrators.test_light_transport import FLOOR, FLOOR_CAM

    A, L_E, E_S = 0.5, 0.2, 2.0
    L_P = sys.modules["warp_spt.emitters.probe_sky"].RADIANCE
    E_P = sys.modules["warp_spt.emitters.probe_sun"].IRRADIANCE
    assert [k.name for k in KINDS][-2:] == ["probe_sky", "probe_sun"] and "probe_sun" in Lights.vars
    objs, mtls = write_scene_files(Path(folder), "floor", quads_obj([("floor", FLOOR)]),
                                   material("floor", Kd=(A,) * 3, Roughness=1))
    scene = replace(load_scene(objs, mtls, warn=lambda m: None),
                    lights=[SunLight(direction=(0.0, 0.0, 1.0), color=(E_S,) * 3)])
    dev = DeviceScene(scene)
    assert dev.features.lights == ("probe_sun", "punctual"), dev.features.lights      # declared by the scene
    env = Sky.environment(np.full((8, 16, 3), L_E, np.float32), up=(0.0, 0.0, 1.0))
    rs = RenderSettings(width=12, height=10, spp=128, max_depth=2, seed=1, sky=env, sampler="independent")
    b = bind(dev, FLOOR_CAM, rs)
    assert b.features.lights == ("environment", "environment.seen", "probe_sky", "probe_sun", "punctual"), b.features
    img = render_scene(dev, FLOOR_CAM, rs).image.astype(np.float64)
    expected = A * (L_E + L_P) + A / np.pi * (E_P + E_S)
    mean, se = img.mean(), img.reshape(-1, 3).mean(1).std(ddof=1) / np.sqrt(img.shape[0] * img.shape[1])
    assert abs(mean - expected) < max(5 * se, 1e-3) and abs(mean - expected) < 0.01 * expected, (mean, se, expected)
    # without the probes' light the floor would be a L_e + a / pi E_s: each probe's share is in the image
    assert mean - (A * L_E + A / np.pi * E_S) > 0.9 * (A * L_P + A / np.pi * E_P)
    print(f"floor {mean:.5f} +- {se:.5f}, expected {expected:.5f}")
    print("ok")
'''


def test_an_infinite_and_a_delta_kind_are_each_one_module_and_a_name(tmp_path):
    """Both probes beside an environment map and a punctual sun: two infinite and two delta kinds in
    one scene, the floor at its closed form."""
    print(run_probe(tmp_path, "LIGHT_KINDS", "emitters", {"probe_sky": PROBE_SKY, "probe_sun": PROBE_SUN}, SCRIPT))


def test_the_registry_is_the_list_and_checks_it():
    """The device registry is ``LIGHT_KINDS`` in order; a module that is not the kind its name says is
    refused by name."""
    import pytest

    from warp_spt.emitters.registry import KINDS
    from warp_spt.scene.families import LIGHT_KINDS, check_kind

    assert tuple(k.name for k in KINDS) == LIGHT_KINDS
    with pytest.raises(ImportError, match="emitters kind 'sky'"):
        check_kind("emitters", "sky", "environment")
