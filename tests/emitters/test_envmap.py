"""Environment maps (issue 34): the sky as a light of the scene, the .hdr reader, the map's checks,
its sampling distribution (the pdf integrates to 1 and matches its samples), a furnace under a
constant map for every integrator and sampler, one bright texel against its analytic irradiance,
importance against uniform sampling, and the command line's flags.

Expected values are independent of the code under test: closed-form integrals, chi-square
statistics, Student-t bounds from the renders' own spread, Mitsuba 3's .hdr reader.
"""

from __future__ import annotations

import importlib.util
import math
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import warp as wp

import warp_spt as ws
from warp_spt.upload.device_scene import DeviceScene
from warp_spt.emitters import Lights, env_pdf, env_radiance, light_table, sample_env
from warp_spt.images.environment import load_environment, read_environment_image
from warp_spt.images.hdr import HdrError, read_hdr, write_hdr
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.camera import Camera
from warp_spt.scene.environment import EnvironmentMap, row_solid_angles
from warp_spt.scene.sky import Sky

from tests.support.combos import every_pair
from tests.support.scenes import material, write_scene_files
from tests.support.stability_scenes import t_quantile

ROOT = Path(__file__).resolve().parents[2]
Z = (0.0, 0.0, 1.0)


def synthetic_envmap(*args, **kw) -> np.ndarray:
    spec = importlib.util.spec_from_file_location("make_test_envmap", ROOT / "scripts" / "make_test_envmap.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.synthetic_envmap(*args, **kw)


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    """A host scene: one sphere of radius 1 at the origin, diffuse albedo 1 (the seed's Kd 1)."""
    d = tmp_path_factory.mktemp("envball")
    objs, mtls = write_scene_files(d, "ball", "usemtl white\nb 0 0 0 1\n", material("white", Kd=(1, 1, 1)))
    return ws.load_scene(objs, mtls)


FACING = Camera(position=(0.0, -4.0, 0.0), direction=(0.0, 1.0, 0.0), fov=20.0, up=Z)


# --------------------------------------------------------------------------------------------
# The sky belongs to the scene


def test_the_scenes_sky_renders_as_the_settings_sky_and_the_settings_override_it(ball):
    rs = RenderSettings(width=8, height=8, spp=2, max_depth=3)
    pink_in_scene = ws.render_scene(replace(ball, sky=Sky.pink()), FACING, rs).image
    pink_setting = ws.render_scene(ball, FACING, replace(rs, sky=Sky.pink())).image
    assert np.array_equal(pink_in_scene, pink_setting)
    overridden = ws.render_scene(replace(ball, sky=Sky.pink()), FACING, replace(rs, sky=Sky.black())).image
    assert np.array_equal(overridden, ws.render_scene(ball, FACING, rs).image)
    assert not np.array_equal(overridden, pink_in_scene)


def test_a_scene_sky_that_is_not_a_sky_is_refused(ball):
    with pytest.raises(TypeError, match="scene.sky must be a warp_spt.Sky"):
        ws.render_scene(replace(ball, sky="sky.hdr"), FACING, RenderSettings(width=4, height=4, spp=1))


# --------------------------------------------------------------------------------------------
# Files and checks


def test_hdr_round_trip_rle_and_flat(tmp_path):
    img = synthetic_envmap(64)
    write_hdr(tmp_path / "a.hdr", img)
    write_hdr(tmp_path / "b.hdr", img, rle=False)
    a, b = read_hdr(tmp_path / "a.hdr"), read_hdr(tmp_path / "b.hdr")
    assert np.array_equal(a, b)
    assert (tmp_path / "a.hdr").stat().st_size < (tmp_path / "b.hdr").stat().st_size / 4
    # RGBE keeps 8 bits of mantissa for the largest channel: the others within 2^-8 of it
    assert np.all(np.abs(a - img) <= img.max(axis=2, keepdims=True) * 2.0**-8)


def test_our_hdr_reader_agrees_with_mitsubas(tmp_path):
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    write_hdr(tmp_path / "m.hdr", synthetic_envmap(64))
    theirs = np.array(mi.Bitmap(str(tmp_path / "m.hdr")), dtype=np.float32)[..., :3]
    ours = read_hdr(tmp_path / "m.hdr")
    # Radiance's decoding takes a mantissa's middle (c + 0.5); stb (Mitsuba) takes its bottom (c)
    assert ours.shape == theirs.shape
    assert np.all(np.abs(ours - theirs) <= ours.max(axis=2, keepdims=True) * 2.0**-8 + 1e-12)


@pytest.mark.parametrize("data, what", [
    (b"P6\n2 1\n255\n", "not a Radiance .hdr"),
    (b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n", "header never ends"),
    (b"#?RADIANCE\n\n+X 4 -Y 2\n", "resolution line"),
    (b"#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 1 +X 2\n", "XYZE"),
    (b"#?RADIANCE\n\n-Y 2 +X 4\n" + bytes(20), "truncated at scanline 1"),
])
def test_malformed_hdr_is_refused_naming_the_file(tmp_path, data, what):
    p = tmp_path / "bad.hdr"
    p.write_bytes(data)
    with pytest.raises(HdrError, match=what) as e:
        read_hdr(p)
    assert str(p) in str(e.value)


@pytest.mark.parametrize("change, what", [
    (lambda a: a.__setitem__((1, 2, 0), np.nan), "not finite"),
    (lambda a: a.__setitem__((0, 0, 1), -1.0), "negative"),
])
def test_bad_texels_are_refused_naming_the_file(tmp_path, change, what):
    img = np.ones((4, 8, 3), np.float32)
    change(img)
    np.save(tmp_path / "e.npy", img)
    with pytest.raises(ValueError, match=what) as e:
        load_environment(tmp_path / "e.npy")
    assert "e.npy" in str(e.value)


def test_a_map_that_is_not_2_to_1_is_refused():
    with pytest.raises(ValueError, match="equirectangular.*8x8"):
        Sky.environment(np.ones((8, 8, 3), np.float32), name="cube.hdr")


def test_unreadable_and_oversized_maps_are_one_error_naming_the_file(tmp_path, capsys):
    """What the image libraries raise (a junk EXR, a truncated PNG) and a map over the texel budget,
    known from its header before anything is decoded (a 220 KB PNG once took 3.9 GB; an .npy was read
    whole first): a ValueError naming the file, and from --env one line, exit 1, no "internal error"."""
    import zlib

    from warp_spt.cli.main import main
    from warp_spt.scene.atlas_layout import TEXEL_BUDGET

    cases = {}
    cases["junk.exr"] = (b"\x76\x2f\x31\x01" + bytes(64), "cannot read the environment map")
    cases["junk.png"] = (b"\x89PNG\r\n\x1a\n" + bytes(40), "cannot read the environment map")
    side = int((TEXEL_BUDGET / 2) ** 0.5) + 8                      # 2:1 and over the budget
    # a PNG header (IHDR) of side x 2 side pixels and one empty compressed row: a few hundred bytes
    ihdr = b"IHDR" + (2 * side).to_bytes(4, "big") + side.to_bytes(4, "big") + bytes([8, 2, 0, 0, 0])
    chunk = lambda b: len(b[4:]).to_bytes(4, "big") + b + zlib.crc32(b).to_bytes(4, "big")
    png = b"\x89PNG\r\n\x1a\n" + chunk(ihdr) + chunk(b"IDAT" + zlib.compress(bytes(7))) + chunk(b"IEND")
    cases["huge.png"] = (png, "more than the texel budget")
    npy = tmp_path / "huge.npy"
    with open(npy, "wb") as f:          # the header of a (side, 2 side, 3) float32 array, and no data
        np.lib.format.write_array_header_1_0(f, {"descr": "<f4", "fortran_order": False,
                                                 "shape": (side, 2 * side, 3)})
    for name, (data, what) in cases.items():
        (tmp_path / name).write_bytes(data)
    for name, what in [*((n, w) for n, (_, w) in cases.items()), ("huge.npy", "more than the texel budget")]:
        path = tmp_path / name
        if name.endswith(".exr"):
            pytest.importorskip("OpenEXR")
        with pytest.raises(ValueError, match=what) as e:
            read_environment_image(path)
        assert str(e.value).startswith(f"{path}: ") and "\n" not in str(e.value)
        assert main(["--env", str(path), "-res", "8", "8", "-sr", "1", "--quiet", "-out", str(tmp_path / "o.npy")]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and str(path) in err[0] and "internal" not in err[0], err


def test_an_8bit_png_is_an_ldr_map_with_a_warning(tmp_path):
    from PIL import Image

    Image.fromarray(np.full((4, 8, 3), 255, np.uint8)).save(tmp_path / "ldr.png")
    said = []
    img = read_environment_image(tmp_path / "ldr.png", warn=said.append)
    assert said and "low-dynamic-range" in said[0]
    assert np.allclose(img, 1.0)


# --------------------------------------------------------------------------------------------
# The distribution


@wp.kernel
def _pdf_kernel(lights: Lights, dirs: wp.array(dtype=wp.vec3), out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = env_pdf(lights, dirs[i])


@wp.kernel
def _sample_kernel(lights: Lights, us: wp.array(dtype=wp.vec2), out: wp.array(dtype=wp.vec4),
                   back: wp.array(dtype=float)):
    i = wp.tid()
    s = sample_env(lights, us[i])
    out[i] = s
    back[i] = env_pdf(lights, wp.vec3(s[0], s[1], s[2]))


def _table(ball, img, rotate=0.0):
    sky = Sky.environment(img, rotate=rotate, up=Z)
    dev = DeviceScene(replace(ball, sky=sky))
    return light_table(dev, sky, Z)


def _grid(nt, nphi):
    """Midpoints of an (nt x nphi) grid in (theta, phi), their directions (Z up, phi from +X) and
    solid angles."""
    th = np.pi * (np.arange(nt) + 0.5) / nt
    ph = 2 * np.pi * (np.arange(nphi) + 0.5) / nphi
    T, P = np.meshgrid(th, ph, indexing="ij")
    d = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    dw = (np.sin(T) * (np.pi / nt) * (2 * np.pi / nphi)).ravel()
    return d.astype(np.float32), dw


def _pdfs(lights, d):
    out = wp.zeros(len(d), dtype=float)
    wp.launch(_pdf_kernel, dim=len(d), inputs=[lights, wp.array(d, dtype=wp.vec3), out])
    return out.numpy().astype(np.float64)


@pytest.mark.parametrize("rotate", [0.0, 37.0])
def test_the_pdf_integrates_to_one_over_the_sphere(ball, rotate):
    lights = _table(ball, synthetic_envmap(32, sun_radius=12.0), rotate)
    d, dw = _grid(512, 1024)
    total = float((_pdfs(lights, d) * dw).sum())
    assert abs(total - 1.0) < 2e-3, total


def test_the_pdf_holds_next_to_the_poles(ball):
    """Within about 0.02 degrees of a pole, 1 - z^2 rounds to 0 in float32: the density there must
    still be the pole row's (a BSDF-sampled ray escaping to a bright pole otherwise took the whole MIS
    weight: one pixel of 622 among neighbours of 6). Per row the map is uniform, so along a meridian
    the density is the row's weight over 2 pi^2 sin(theta): density x sin(theta) is constant."""
    img = np.ones((64, 128, 3), np.float32)
    img[0], img[-1] = 1000.0, 300.0                                 # bright poles
    lights = _table(ball, img)
    theta = np.radians([1e-4, 1e-3, 5e-3, 0.01, 0.02, 0.05, 0.2, 1.0])
    for pole, phi in ((1.0, 0.3), (-1.0, 2.0)):
        d = np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), pole * np.cos(theta)], -1)
        got = _pdfs(lights, d.astype(np.float32))
        scaled = got * np.sin(theta)
        assert np.all(got > 0) and np.allclose(scaled, scaled[-1], rtol=2e-3), (pole, got)


def test_a_bright_pole_over_a_floor_gives_no_pixel_beyond_a_hoeffding_bound(tmp_path, ball):
    """A sun of 1 degree at the zenith (2e5, in a 2048 x 1024 map) over a diffuse floor seen from
    above: every pixel has the same expectation (an infinite plane under a sky symmetric about its
    normal), so the brightest pixel is bounded. A BSDF-sampled direction exactly along the normal (u = 0:
    sample 1577 of pixel (11, 45) in the default sampler) reached the pole, where the density read 0
    and the ray took the whole MIS weight: 20,000 times the median at 1 spp (47 among 3.9 at 2048 spp).
    The bound: each sample lies in [0, 4 mu] (light samples measured within 2.03 mu, BSDF ones far
    below), so by Hoeffding's inequality, over N pixels of n samples, P(max > mu + t) <= N exp(-2 n
    t^2 / (4 mu)^2), 1e-9 for the t below; mu is estimated by the median."""
    objs, mtls = write_scene_files(tmp_path, "floor", "v -20 -20 0\nv 20 -20 0\nv 20 20 0\nv -20 20 0\n"
                                   "usemtl grey\nf 1 2 3\nf 1 3 4\n", material("grey", Kd=(0.5, 0.5, 0.5)))
    floor = ws.load_scene(objs, mtls)
    sky = Sky.environment(synthetic_envmap(2048, sun_elevation=90.0, sun_radius=0.5, sun_radiance=2e5), up=Z)
    down = Camera(position=(0.0, 0.0, 1.0), direction=(0.0, 0.0, -1.0), up=(0.0, 1.0, 0.0), fov=40.0)
    n, side = 16, 96
    img = ws.render(floor, down, width=side, height=side, spp=n, sample_offset=1570, max_depth=2,
                    integrator="nee", sky=sky).mean(-1)
    mu = float(np.median(img))
    t = 4.0 * mu * math.sqrt(math.log(side * side / 1e-9) / (2 * n))
    assert img.max() <= mu + t, (img.max(), mu, t, np.unravel_index(np.argmax(img), img.shape))
    # and the density at the pole itself is the pole row's, not 0
    lights = _table(ball, synthetic_envmap(64, sun_elevation=90.0, sun_radius=3.0))
    assert _pdfs(lights, np.array([[0.0, 0.0, 1.0]], np.float32))[0] > 1e6


def test_sampling_matches_the_pdf_chi_square(ball):
    lights = _table(ball, synthetic_envmap(32, sun_radius=12.0, sun_radiance=50.0), 20.0)
    n = 200_000
    us = np.random.default_rng(1).random((n, 2)).astype(np.float32)
    out = wp.zeros(n, dtype=wp.vec4)
    back = wp.zeros(n, dtype=float)
    wp.launch(_sample_kernel, dim=n, inputs=[lights, wp.array(us, dtype=wp.vec2), out, back])
    s = out.numpy()
    # the density returned with a sample is the one the pdf gives its direction (MIS needs both alike)
    inside = np.isclose(s[:, 3], back.numpy(), rtol=1e-4)
    assert inside.mean() > 0.995
    # counts over a coarse grid of directions (not aligned with the texels) against the pdf's integral
    nt, nphi, sub = 9, 14, 24
    theta = np.arccos(np.clip(s[:, 2], -1, 1))
    phi = np.mod(np.arctan2(s[:, 1], s[:, 0]), 2 * np.pi)
    counts = np.histogram2d(theta, phi, bins=[nt, nphi], range=[[0, np.pi], [0, 2 * np.pi]])[0].ravel()
    d, dw = _grid(nt * sub, nphi * sub)
    p = (_pdfs(lights, d) * dw).reshape(nt, sub, nphi, sub).sum(axis=(1, 3)).ravel()
    expected = n * p / p.sum()
    keep = expected >= 5
    chi2 = float(((counts[keep] - expected[keep]) ** 2 / expected[keep]).sum())
    # Wilson-Hilferty: (chi2 / k)^(1/3) is nearly normal; z > 3.7 has probability about 1e-4
    k = keep.sum() - 1
    z = ((chi2 / k) ** (1 / 3) - (1 - 2 / (9 * k))) / math.sqrt(2 / (9 * k))
    assert z < 3.7, (chi2, k, z)


# --------------------------------------------------------------------------------------------
# Rendering


def _batches(scene, camera, k, **kw):
    rs = RenderSettings(**kw)
    return np.stack([ws.render_scene(scene, camera, replace(rs, seed=s)).image for s in range(k)])


def _assert_mean(batches, expected, alpha=1e-4):
    k = batches.shape[0]
    mean = batches.mean(axis=0)
    se = batches.std(axis=0, ddof=1) / math.sqrt(k)
    bound = t_quantile(alpha / (2 * mean.size), k - 1)
    err = np.abs(mean - expected)
    assert np.all(err <= bound * se + 1e-6 * np.abs(expected)), \
        f"worst |err| / se = {np.max(err / np.maximum(se, 1e-12)):.2f} (bound {bound:.2f})"


@pytest.mark.parametrize("integrator,sampler", every_pair())
def test_furnace_constant_map_every_integrator_and_sampler(ball, integrator, sampler):
    # a convex albedo-1 sphere in a constant environment L: every path sees L (one bounce, then out)
    L = np.array([0.5, 1.0, 2.0], np.float32)
    scene = replace(ball, sky=Sky.environment(np.ones((16, 32, 3), np.float32) * L, up=Z))
    b = _batches(scene, FACING, 6, width=6, height=6, spp=4, max_depth=3, integrator=integrator, sampler=sampler)
    if integrator == "seed":
        # the seed's estimator on the seed's diffuse kind is off L by a few 1e-3 at this spp under any
        # sky (its scattering; measured the same under Sky.constant): the constant map renders as the
        # constant sky does, sample for sample
        sky = _batches(ball, FACING, 6, width=6, height=6, spp=4, max_depth=3, integrator=integrator,
                       sampler=sampler, sky=Sky.constant(*L))
        assert np.allclose(b, sky, rtol=1e-5)
    else:
        _assert_mean(b, np.broadcast_to(L, b.shape[1:]))


PLANE = """v -50 -50 0
v 50 -50 0
v 50 50 0
v -50 50 0
usemtl grey
f 1 2 3
f 1 3 4
"""


@pytest.fixture(scope="module")
def plane(tmp_path_factory):
    d = tmp_path_factory.mktemp("envplane")
    # albedo 1: the seed's reflectance is Kd as read only for 0 and 1 (0.5 reflects 0.506)
    objs, mtls = write_scene_files(d, "plane", PLANE, material("grey", Kd=(1, 1, 1)))
    return ws.load_scene(objs, mtls)


DOWN = Camera(position=(0.0, 0.0, 5.0), direction=(0.0, 0.0, -1.0), fov=10.0, up=(0.0, 1.0, 0.0))


def test_one_bright_texel_gives_its_analytic_irradiance(plane):
    # a black map but one texel of radiance L at row r: a diffuse plane (albedo 1, normal up) under it
    # reflects 1 / pi x L x the texel's cos-weighted solid angle, dphi (sin^2 theta_b - sin^2 theta_a) / 2
    h, w, r, c, L = 16, 32, 5, 9, 40.0
    img = np.zeros((h, w, 3), np.float32)
    img[r, c] = L
    th_a, th_b = np.pi * r / h, np.pi * (r + 1) / h
    expected = 1.0 / np.pi * L * (2 * np.pi / w) * (np.sin(th_b) ** 2 - np.sin(th_a) ** 2) / 2
    scene = replace(plane, sky=Sky.environment(img, up=Z))
    b = _batches(scene, DOWN, 8, width=4, height=4, spp=16, max_depth=2)
    _assert_mean(b, np.full(b.shape[1:], expected))
    assert abs(b.mean() / expected - 1) < 0.02


def test_importance_sampling_beats_uniform_at_equal_spp(plane):
    # a sun-like blob holding most of the light: at equal spp, the squared error against a long
    # importance-sampled render is far lower with importance sampling (uniform sampling finds the blob
    # by chance: most of its 8-spp estimates miss it, a few are huge)
    img = synthetic_envmap(64, sun_radius=4.0, sun_radiance=3000.0)
    scenes = {s: replace(plane, sky=Sky.environment(EnvironmentMap(img, "blob", s), up=Z))
              for s in ("importance", "uniform")}
    ref = ws.render_scene(scenes["importance"], DOWN, RenderSettings(width=4, height=4, spp=512, max_depth=2,
                                                                       seed=99)).image
    mse = {s: float(((_batches(sc, DOWN, 6, width=4, height=4, spp=8, max_depth=2) - ref) ** 2).mean())
           for s, sc in scenes.items()}
    assert mse["importance"] * 10 < mse["uniform"], mse


def test_background_is_seen_by_camera_rays_only(ball):
    L = np.array([0.5, 1.0, 2.0], np.float32)
    img = np.ones((8, 16, 3), np.float32) * L
    rs = RenderSettings(width=12, height=12, spp=2, max_depth=3, integrator="seed")
    wide = Camera(position=(0.0, -4.0, 0.0), direction=(0.0, 1.0, 0.0), fov=60.0, up=Z)
    plain = ws.render_scene(replace(ball, sky=Sky.environment(img, up=Z)), wide, rs).image
    bg = ws.render_scene(replace(ball, sky=Sky.environment(img, up=Z, background=(0.1, 0.2, 0.3))), wide, rs).image
    corner, centre = (0, 0), (6, 6)
    assert np.allclose(bg[corner], (0.1, 0.2, 0.3)) and np.allclose(plain[corner], L)
    assert np.allclose(bg[centre], plain[centre])     # the sphere is lit by the map either way


def test_strength_scales_and_rotation_turns(ball):
    img = synthetic_envmap(32, sun_radius=15.0, sun_radiance=20.0)
    rs = RenderSettings(width=8, height=8, spp=4, max_depth=3, integrator="seed")
    a = ws.render_scene(replace(ball, sky=Sky.environment(img, up=Z)), FACING, rs).image
    b = ws.render_scene(replace(ball, sky=Sky.environment(img, strength=2.0, up=Z)), FACING, rs).image
    assert np.allclose(b, 2 * a, rtol=1e-5)
    # turning the map a whole number of texel columns is the map with its columns rolled (a direction
    # then shows the column a quarter turn further on)
    turned = ws.render_scene(replace(ball, sky=Sky.environment(img, rotate=90.0, up=Z)), FACING, rs).image
    rolled = ws.render_scene(replace(ball, sky=Sky.environment(np.roll(img, -8, axis=1), up=Z)), FACING, rs).image
    assert np.allclose(turned, rolled, rtol=1e-4, atol=1e-6)


# --------------------------------------------------------------------------------------------
# Command line


def _cli(*args, cwd):
    return subprocess.run([sys.executable, "-m", "warp_spt", *args], cwd=cwd, capture_output=True, text=True)


def test_cli_env_flags(tmp_path):
    write_hdr(tmp_path / "sky.hdr", synthetic_envmap(32, sun_radius=15.0, sun_radiance=20.0))
    (tmp_path / "ball.obj").write_text("b 0 0 0 1\n")
    r = _cli("-obj", "ball.obj", "--env", "sky.hdr", "--env-rotate", "30", "--env-strength", "2",
             "--env-background", "1", "1", "1", "-res", "8", "8", "-sr", "2", "--quiet", "-out", "e.npy", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    img = np.load(tmp_path / "e.npy")
    assert np.allclose(img[0, 0], 1.0)
    for args, what in [(["--env", "missing.hdr"], "cannot read --env file 'missing.hdr'"),
                       (["--env-strength", "2"], "--env-strength needs --env")]:
        r = _cli("-obj", "ball.obj", *args, "-res", "4", "4", "-out", "x.npy", cwd=tmp_path)
        assert r.returncode != 0 and what in r.stderr, r.stderr
        assert "Traceback" not in r.stderr and len(r.stderr.strip().splitlines()) >= 1


# --------------------------------------------------------------------------------------------
# Differentiable: the environment's strength and rotation


def test_environment_parameters_are_named_read_and_set(ball):
    sky = Sky.environment(np.ones((8, 16, 3), np.float32), rotate=10.0, strength=2.0, up=Z)
    p = ws.parameters(replace(ball, sky=sky))
    assert "environment.strength" in p and "environment.rotate" in p and "sky.color" not in p
    assert p["environment.strength"] == pytest.approx(2.0) and p["environment.rotate"] == pytest.approx(10.0)
    p["environment.rotate"] = 45.0
    assert p.sky.rotate == 45.0 and p.sky.env is sky.env
    with pytest.raises(ValueError, match="environment.strength"):
        p["environment.strength"] = -1.0
    assert "environment.strength" not in ws.parameters(ball, sky=Sky.black())


def _lit_ball(ball, **kw):
    # a broad sun beside the ball (map azimuth 90: along -X; the camera looks along +Y): turning the map
    # moves the lit side across the view, a derivative well above the noise
    img = synthetic_envmap(64, sun_elevation=20.0, sun_azimuth=90.0, sun_radius=30.0, sun_radiance=10.0)
    return replace(ball, sky=Sky.environment(img, up=Z, **kw))


SIDE = Camera(position=(0.0, -5.0, 1.0), direction=(0.0, 1.0, -0.2), fov=35.0, up=Z)


def test_strength_gradient_is_the_image_over_the_strength(ball):
    # the image is linear in the strength (the only light): d sum(I) / d s = sum(I) / s, sample for sample
    scene = _lit_ball(ball, strength=1.5)
    p = ws.parameters(scene, SIDE)
    rs = RenderSettings(width=8, height=8, spp=4, max_depth=3)
    g = ws.render_gradients(p, rs, adjoint=np.ones((8, 8, 3)), wrt=["environment.strength"])
    assert g.grads["environment.strength"] == pytest.approx(g.image.astype(np.float64).sum() / 1.5, rel=1e-4)


def test_rotation_gradient_matches_finite_differences(ball):
    # d sum(I) / d rotate by path replay against central differences of renders (seed k on both
    # sides), compared within their joint standard error (Student t over the seeds). (The tape's
    # pathwise derivative is biased here: a BSDF-sampled ray's MIS weight jumps where the rotating
    # map's piecewise-constant density does, a term no pathwise derivative sees; docs/lights.md.)
    mode = "prb"
    scene = _lit_ball(ball, rotate=20.0)
    rs = RenderSettings(width=6, height=6, spp=32, max_depth=2)
    h, k = 6.0, 8
    grads, fds = [], []
    for seed in range(k):
        p = ws.parameters(scene, SIDE)
        g = ws.render_gradients(p, replace(rs, seed=seed), adjoint=np.ones((6, 6, 3)), wrt=["environment.rotate"],
                                mode=mode)
        grads.append(float(g.grads["environment.rotate"]))
        sums = []
        for r in (20.0 + h, 20.0 - h):
            s = replace(scene, sky=replace(scene.sky, rotate=r))
            sums.append(ws.render_scene(s, SIDE, replace(rs, seed=seed + 1000)).image.astype(np.float64).sum())
        fds.append((sums[0] - sums[1]) / (2 * h))
    grads, fds = np.array(grads), np.array(fds)
    se = math.sqrt(grads.var(ddof=1) / k + fds.var(ddof=1) / k)
    assert abs(grads.mean()) > 3 * se, "the test scene's rotation derivative is lost in its noise"
    assert abs(grads.mean() - fds.mean()) < t_quantile(1e-3, k - 1) * se + 0.03 * abs(fds.mean()), \
        (grads.mean(), fds.mean(), se)


def test_frames_and_workers_render_what_a_single_render_renders(tmp_path):
    # the map is the scene's sky, prepared once for every front end (a cluster's workers get it with
    # the scene): frame 0 of --frames, a --workers render and a single render are the same image
    write_hdr(tmp_path / "sky.hdr", synthetic_envmap(32, sun_radius=15.0, sun_radiance=20.0))
    (tmp_path / "ball.obj").write_text("b 0 0 0 1\n")
    common = ["-obj", "ball.obj", "--env", "sky.hdr", "--env-rotate", "40", "-res", "8", "8", "-sr", "2", "--quiet"]
    for extra, out in [([], "single.npy"), (["--frames", "0:1"], "f_{frame}.npy"), (["--workers", "2"], "w.npy")]:
        r = _cli(*common, *extra, "-out", out, cwd=tmp_path)
        assert r.returncode == 0, r.stderr
    single = np.load(tmp_path / "single.npy")
    assert np.array_equal(single, np.load(tmp_path / "f_0.npy"))
    assert np.array_equal(single, np.load(tmp_path / "w.npy"))


def test_the_viewer_takes_an_environment_file(ball, tmp_path):
    from warp_spt.scene.sky import SKY_ENVIRONMENT
    from warp_spt.viewer.session import Session

    class Replies:          # not a list: an empty one would be falsy, and the session broadcast instead
        def __init__(self):
            self.messages = []

        def __call__(self, message, buffers=()):
            self.messages.append(message)

        def __iter__(self):
            return iter(self.messages)

    write_hdr(tmp_path / "sky.hdr", synthetic_envmap(32, sun_radius=15.0, sun_radiance=20.0))
    s = Session(ball, FACING, width=16, height=16, max_spp=4)
    try:
        replies = Replies()
        s.handle({"type": "set", "key": "env_path", "value": str(tmp_path / "missing.hdr")}, reply=replies)
        assert any("missing.hdr" in m.get("text", "") for m in replies) and s.settings.env_path == ""
        for key, value in [("env_path", str(tmp_path / "sky.hdr")), ("env_rotate", 30.0), ("sky", "environment")]:
            s.handle({"type": "set", "key": key, "value": value})
        res = s.wait_for(2, timeout=120)
        assert res.settings.sky.kind == SKY_ENVIRONMENT and res.settings.sky.rotate == 30.0
        line = s.command_line(spp=4)
        assert f"--env {tmp_path / 'sky.hdr'}" in line and "--env-rotate 30" in line
    finally:
        s.close()


@wp.kernel
def _radiance_kernel(lights: Lights, dirs: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = env_radiance(lights, dirs[i])


@pytest.mark.parametrize("rotate", [0.0, 30.0])
def test_the_maps_orientation_is_mitsubas(ball, rotate):
    # Mitsuba 3's envmap emitter (Y up) and ours with up Y show the same column in every direction,
    # and both the first row straight up and the last straight down; Mitsuba's map turned by its
    # to_world rotation about Y, ours by ``rotate``. (Their latitudes differ by design: Mitsuba puts row
    # r's centre at v = r / (h - 1), poles included, we at (r + 0.5) / h as pbrt and Blender do, so the
    # map's rows hold one value each here and only the poles are compared across rows.)
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    h, w = 8, 16
    columns = np.random.default_rng(4).random((w, 3)).astype(np.float32) + 0.1
    img = np.repeat(columns[None], h, axis=0)
    img[0], img[-1] = (5.0, 6.0, 7.0), (0.5, 0.25, 0.125)
    env = mi.load_dict({"type": "envmap", "bitmap": mi.Bitmap(img),
                        "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], rotate)})
    sky = Sky.environment(img, rotate=rotate, up=(0.0, 1.0, 0.0))
    lights = light_table(DeviceScene(replace(ball, sky=sky)), sky, (0.0, 1.0, 0.0))
    # directions at column centres on three latitudes away from the pole rows, in Mitsuba's own frame
    # (u = atan2(x, -z) / 2 pi, v = acos(y) / pi), turned into the world by the rotation; then the poles
    th = np.radians([60.0, 90.0, 120.0])[:, None]
    ps = (2 * np.pi * (np.arange(w) + 0.5) / w)[None, :]
    local = np.stack(np.broadcast_arrays(np.sin(th) * np.sin(ps), np.cos(th), -np.sin(th) * np.cos(ps)), -1)
    a = np.radians(rotate)
    rot = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
    dirs = np.concatenate([(local.reshape(-1, 3) @ rot.T), [[0, 1, 0], [0, -1, 0]]]).astype(np.float32)
    expected = np.concatenate([np.tile(columns, (3, 1)), img[[0, -1], 0]])
    theirs = []
    for d in dirs:
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*(-d.astype(np.float64)))
        theirs.append(np.array(env.eval(si), dtype=np.float64))
    out = wp.zeros(len(dirs), dtype=wp.vec3)
    wp.launch(_radiance_kernel, dim=len(dirs), inputs=[lights, wp.array(dirs, dtype=wp.vec3), out])
    ours = out.numpy()
    assert np.allclose(np.array(theirs), expected, rtol=1e-3)     # the directions are Mitsuba's texel centres
    assert np.allclose(ours, expected, rtol=1e-3), np.abs(ours - expected).max()


MITSUBA_REFS = ROOT / "tests" / "data" / "mitsuba_envmap_refs.npz"


def test_three_spheres_under_the_map_match_mitsuba(tmp_path):
    # a grey, a rough gold and a rough glass sphere lit by the synthetic sun + sky, ours against
    # Mitsuba 3's envmap emitter (references made once by tests/data/make_mitsuba_envmap_refs.py,
    # the map hidden from camera rays on both sides): per 4 x 4 block Welch t over 8 batches each, with
    # a Bonferroni bound, and the whole image
    from tests.support import mitsuba_envmap_scene as ES
    from tests.data.make_mitsuba_envmap_refs import block_means, synthetic

    with np.load(MITSUBA_REFS) as z:
        ref = z["blocks"].astype(np.float64)
    objs, mtls = ES.write_files(tmp_path)
    host = ws.load_scene(objs, mtls, warn=lambda message: None)
    host.materials.multiscatter[:] = False          # Mitsuba has no multiple-scattering compensation
    host.sky = Sky.environment(synthetic(), up=(0.0, 1.0, 0.0), background=(0.0, 0.0, 0.0))
    c = ES.CAMERA
    cam = Camera.look_at(c["position"], c["target"], up=c["up"], fov=c["fov"])
    spp, k = 64, 8
    ours = np.stack([block_means(ws.render_scene(host, cam, RenderSettings(
        width=ES.WIDTH, height=ES.HEIGHT, spp=spp, sample_offset=b * spp, max_depth=ES.MAX_DEPTH, seed=7)
    ).image.astype(np.float64)) for b in range(k)])
    se = np.sqrt(ours.var(0, ddof=1) / len(ours) + ref.var(0, ddof=1) / len(ref))
    diff = ours.mean(0) - ref.mean(0)
    # blocks of black background alone: both exactly 0
    exact = (se == 0) & (np.abs(diff) <= 1e-4 * np.abs(ref.mean(0)))
    t = np.where(se > 0, diff / np.where(se > 0, se, 1.0), np.where(exact, 0.0, np.inf))
    dof = min(len(ours), len(ref)) - 1
    assert np.abs(t).max() < t_quantile(1e-3 / (2 * t.size), dof), np.abs(t).max()
    whole = ours.mean(axis=(1, 2)), ref.mean(axis=(1, 2))
    se_whole = math.sqrt(whole[0].var(ddof=1) / k + whole[1].var(ddof=1) / len(ref))
    assert abs(whole[0].mean() - whole[1].mean()) < t_quantile(1e-3 / 2, dof) * se_whole
    assert abs(whole[0].mean() / whole[1].mean() - 1) < 0.005

