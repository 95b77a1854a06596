"""Several infinite lights in one scene (issue 40): an environment map and a constant or gradient sky.

``Sky.environment(..., plus=Sky.gradient())`` gives each of the two infinite light kinds its part:
``environment`` the map, ``sky`` the plus sky, one table entry each, chosen by power. Checked
independently of the code that sums them:

* linearity: the image under both is the sum of the images under each alone (renders of different
  seeds, every pixel within a Student-t bound of the summed standard errors);
* a closed form: a diffuse floor under a constant sky L1 and a constant map L2 is albedo x (L1 + L2),
  and a camera ray that misses sees L1 + L2;
* MIS: next-event estimation (both lights sampled, BSDF samples weighed against both densities) agrees
  with the seed's path tracer, which samples no light, under a bright, uneven map and a gradient sky;
* the host side: what is refused, what the scene declares (one infinite light: the features as
  before), the light table's choice by power, the named parameters, the command line.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from warp_spt.emitters import light_table
from warp_spt.rendering.setup import bind
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

from tests.integrators.test_light_transport import FLOOR, FLOOR_CAM, assert_matches_expected, seed_batches
from tests.support.scenes import box_obj, material
from tests.support.stability_scenes import GENERAL, quads_obj, scene_from_text, t_quantile

ALBEDO = np.array([0.3, 0.5, 0.7])
L_SKY, L_MAP = 0.3, 0.2
Z = (0.0, 0.0, 1.0)
# a camera that sees the floor, the box on it and the sky above the horizon
VIEW = Camera(position=(0.0, -7.0, 1.6), direction=(0.0, 1.0, -0.12), fov=50.0, aperture=0.0, focus=7.0)


def uneven_map(h: int = 16) -> np.ndarray:
    """An (h, 2h, 3) map: a dim, coloured ramp and a bright spot half-way up (far from uniform, so the
    map's importance sampling and the sky's differ)."""
    theta = (np.arange(h) + 0.5) / h * np.pi
    phi = (np.arange(2 * h) + 0.5) / (2 * h) * 2 * np.pi
    t, p = np.meshgrid(theta, phi, indexing="ij")
    spot = 12.0 * np.exp(-((t - 1.0) ** 2 + (p - 2.0) ** 2) / 0.08)
    ramp = 0.1 + 0.1 * np.cos(t)
    return (np.stack([ramp + spot, 0.8 * ramp + spot, 1.2 * ramp + 0.7 * spot], axis=-1)).astype(np.float32)


def constant_map(value: float) -> np.ndarray:
    return np.full((8, 16, 3), value, np.float32)


@pytest.fixture(scope="module")
def floor(scene_dir):
    return scene_from_text(scene_dir, "skies_floor", quads_obj([("floor", FLOOR)]),
                           material("floor", Kd=tuple(ALBEDO), Roughness=1))


@pytest.fixture(scope="module")
def boxed(scene_dir):
    """The floor with a box standing on it: shadows, and light reflected between the two."""
    obj = quads_obj([("floor", FLOOR)]) + "\n" + _offset(box_obj(lo=(-1.0, -1.0, 0.0), hi=(1.0, 1.0, 1.5),
                                                                  material="box"), 4)
    mtl = material("floor", Kd=tuple(ALBEDO), Roughness=1) + material("box", Kd=(0.6, 0.4, 0.3), Roughness=1)
    return scene_from_text(scene_dir, "skies_boxed", obj, mtl)


def _offset(obj: str, n: int) -> str:
    """OBJ text whose face indices are moved past ``n`` vertices of text before it."""
    out = []
    for line in obj.splitlines():
        if line.startswith("f "):
            line = "f " + " ".join(str(int(v) + n) for v in line.split()[1:])
        out.append(line)
    return "\n".join(out)


def both(plus: Sky | None = None, image=None) -> Sky:
    return Sky.environment(uneven_map() if image is None else image, rotate=30.0, up=Z, plus=plus)


# --------------------------------------------------------------------------------------------
# The host side


def test_only_an_environment_takes_a_plus_sky_of_the_colour_kinds():
    with pytest.raises(ValueError, match="only an environment sky takes a plus sky"):
        Sky(plus=Sky.gradient())
    with pytest.raises(ValueError, match="plus must be a constant or gradient Sky"):
        both(plus=both())
    with pytest.raises(ValueError, match="plus must be a constant or gradient Sky"):
        Sky.environment(constant_map(1.0), plus="gradient")
    sky = both(plus=Sky.gradient())
    assert sky.colour_sky() is sky.plus and Sky.gradient().colour_sky() == Sky.gradient()
    assert sky.colour_fields() == ("zenith", "nadir") and both().colour_fields() == ()


def test_each_kind_declares_its_part_and_one_infinite_light_is_as_before(floor):
    rs = dict(width=4, height=4)
    lights = [bind(floor, FLOOR_CAM, RenderSettings(sky=s, **rs)).features.lights
              for s in (both(), Sky.gradient(), both(plus=Sky.gradient()), both(plus=Sky.constant(0, 0, 0)))]
    assert lights[0] == ("environment", "environment.seen")       # the map alone: what it compiled before
    assert lights[1] == ("sky",)
    assert lights[2] == ("environment", "environment.seen", "sky")
    assert lights[3] == lights[0]                                  # a black plus sky is no light


def test_the_table_chooses_between_them_by_power(floor):
    """One entry each, weighed as the sky always was (a sphere of the scene's radius radiating the mean
    radiance): for two constants, in the ratio of their radiances."""
    L = light_table(floor, Sky.environment(constant_map(L_MAP), up=Z, plus=Sky.constant(L_SKY, L_SKY, L_SKY)))
    assert L.num_entries == 2
    prob = L.entry_prob.numpy().astype(np.float64)
    assert np.allclose(prob, [L_SKY / (L_SKY + L_MAP), L_MAP / (L_SKY + L_MAP)], rtol=1e-6)
    assert np.isclose(L.sky.prob, prob[0]) and np.isclose(L.environment.prob, prob[1])
    assert L.sky.kind == 0 and np.allclose(L.sky.colors.numpy(), L_SKY)
    # the sky's own table differs from the map's alone (a light table is cached per sky)
    assert light_table(floor, both()).num_entries == 1


def test_named_parameters_name_the_plus_sky(floor):
    from warp_spt.diff.params import SceneParameters

    params = SceneParameters(floor, FLOOR_CAM, both(plus=Sky.gradient()))
    assert {"sky.zenith", "sky.nadir", "environment.strength", "environment.rotate"} <= set(params.names())
    assert np.allclose(params["sky.zenith"], (0.5, 0.7, 1.0))
    params["sky.zenith"] = (0.2, 0.3, 0.4)
    assert params.sky.plus.zenith == (0.2, 0.3, 0.4) and params.sky.env is not None
    with pytest.raises(ValueError, match=r"sky.zenith: values must lie in \[0"):
        params["sky.zenith"] = (-1.0, 0.0, 0.0)
    with pytest.raises(ValueError, match="no constant or gradient part"):
        both().with_colours(color=(1.0, 1.0, 1.0))


def test_the_command_line_adds_the_sky_flags_to_env(tmp_path):
    """--env with -sky or --sky-color: the map with that sky beside it (without them: the map alone)."""
    from warp_spt.cli.options import UsageError, parse_args
    from warp_spt.cli.view_checks import _environment
    from warp_spt.images.hdr import write_hdr

    write_hdr(tmp_path / "map.hdr", constant_map(L_MAP))
    path = str(tmp_path / "map.hdr")
    opts = parse_args(["--env", path, "-sky", "1", "--env-strength", "2"])
    assert opts.sky is None and opts.env.plus == Sky.gradient()
    sky = _environment(opts, print)
    assert sky.env is not None and sky.strength == 2.0 and sky.plus == Sky.gradient()
    assert _environment(parse_args(["--env", path, "--sky-color", "0.1", "0.2", "0.3"]), print).plus \
        == Sky.constant(0.1, 0.2, 0.3)
    assert _environment(parse_args(["--env", path]), print).plus is None
    with pytest.raises(UsageError, match="either -sky or --sky-color"):
        parse_args(["--env", path, "-sky", "1", "--sky-color", "1", "1", "1"])


# --------------------------------------------------------------------------------------------
# Renders


def test_a_floor_under_a_constant_sky_and_a_constant_map_is_albedo_times_their_sum(floor):
    """Every floor point sees the whole upper hemisphere: albedo (L1 + L2) through light sampling,
    BSDF sampling and their MIS weights (nee), and through BSDF sampling alone (seed)."""
    sky = Sky.environment(constant_map(L_MAP), up=Z, plus=Sky.constant(L_SKY, L_SKY, L_SKY))
    expected = np.broadcast_to(ALBEDO * (L_SKY + L_MAP), (8, 8, 3))
    for integrator in ("nee", "seed"):
        b = seed_batches(floor, FLOOR_CAM, 8, 8, 0, width=8, height=8, max_depth=2, sky=sky,
                         integrator=integrator, features=GENERAL)
        assert_matches_expected(b, expected)
        if integrator == "seed":
            assert np.allclose(b, expected, rtol=1e-5)       # every path: one bounce, then the sky
    up = Camera(position=(0.0, 0.0, 1.0), direction=(0.0, 0.2, 1.0), fov=40.0, aperture=0.0, focus=1.0)
    seen = seed_batches(floor, up, 1, 2, 0, width=4, height=4, max_depth=2, sky=sky, features=GENERAL)
    assert np.allclose(seen, L_SKY + L_MAP, rtol=1e-6)      # a camera ray that misses sees the sum


def assert_cancel(what: str, parts: list[np.ndarray], signs: list[float]) -> None:
    """sum of sign x batch mean is 0 over independent batch stacks (K, H, W, 3): every pixel channel
    within a Student-t bound of its standard error (Bonferroni over pixels and channels, the fewest
    batches' degrees of freedom), and the whole image's mean, which a bias spread over the pixels
    cannot hide in, within 5 of its standard errors (the batches' image means)."""
    diff = sum(s * p.mean(axis=0) for s, p in zip(signs, parts))
    se = np.sqrt(sum(p.var(axis=0, ddof=1) / p.shape[0] for p in parts))
    bound = t_quantile(1e-4 / (2 * diff.size), min(p.shape[0] for p in parts) - 1)
    scale = np.abs(parts[0].mean(axis=0))
    ok = np.abs(diff) <= bound * se + 1e-5 * scale + 1e-6
    ratio = float(np.max(np.abs(diff) / np.maximum(se, 1e-9)))
    means = [p.mean(axis=(1, 2, 3)) for p in parts]
    mean_diff = float(sum(s * m.mean() for s, m in zip(signs, means)))
    mean_se = math.sqrt(sum(m.var(ddof=1) / len(m) for m in means))
    print(f"{what}: worst pixel |diff| / se = {ratio:.2f} (bound {bound:.2f}); image mean {means[0].mean():.4f}, "
          f"difference {mean_diff:+.5f} = {mean_diff / mean_se:+.2f} se")
    assert ok.all(), f"{what}: {(~ok).sum()} pixel channels off; worst |diff| / se = {ratio:.2f} (bound {bound:.2f})"
    assert abs(mean_diff) <= 5 * mean_se, (what, mean_diff, mean_se)


def test_the_image_under_both_is_the_sum_of_the_images_under_each(boxed):
    """Linearity, with the features the scene declares (the kernel a user gets): every pixel of
    both = map alone + sky alone within the bound (the floor, the box and the sky above them)."""
    plus = Sky.gradient(zenith=(0.4, 0.6, 0.9), nadir=(0.9, 0.8, 0.6))
    kw = dict(width=10, height=8, max_depth=3, integrator="nee")
    parts = [seed_batches(boxed, VIEW, 16, 16, first, sky=s, **kw)
             for first, s in ((0, both(plus=plus)), (100, both()), (200, plus))]
    assert_cancel("both - map - sky", parts, [1.0, -1.0, -1.0])


@pytest.mark.parametrize("integrator", ["nee", "volpath"])
def test_light_sampling_of_both_agrees_with_the_path_tracer(boxed, integrator):
    """MIS unbiased with both infinite lights sampled: an integrator that samples them (a bright spot
    in the map, a gradient sky) against the seed's, which only follows the BSDF."""
    sky = both(plus=Sky.gradient(zenith=(0.4, 0.6, 0.9), nadir=(0.9, 0.8, 0.6)))
    kw = dict(width=10, height=8, max_depth=3, sky=sky, features=GENERAL)
    lit = seed_batches(boxed, VIEW, 16, 16, 0, integrator=integrator, **kw)
    plain = seed_batches(boxed, VIEW, 16, 64, 50, integrator="seed", **kw)
    assert_cancel(f"{integrator} - seed", [lit, plain], [1.0, -1.0])
