"""Procedural textures (warp_spt.device.proctex): MTL syntax, analytic renders, the seed's checker through
the new path, user modules from the CLI, compile errors and NaN named, kernel specialisation."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import warp as wp

import warp_spt
from warp_spt.cli.main import main
from warp_spt.device import proctex
from warp_spt.upload.device_scene import DeviceScene, Features
from warp_spt.device.textures import checker_np
from warp_spt.integrators import get_step, make_kernel
from warp_spt.io.loader import load_scene
from warp_spt.io.mtl import parse_mtl_bytes
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene
from warp_spt.scene.camera import Camera
from warp_spt.scene.errors import SceneError
from warp_spt.scene.model import TEX_PROC_BASE
from warp_spt.scene.sky import Sky

from tests.support.scenes import material, quad_obj, write_scene_files


@warp_spt.texture("t_const", color=(0.2, 0.4, 0.6))
def t_const(uv: wp.vec2, p: wp.vec3, n: wp.vec3, prm: warp_spt.ProcParams) -> wp.vec3:
    return wp.vec3(prm[0], prm[1], prm[2])


@warp_spt.texture("t_ramp_u")
def t_ramp_u(uv: wp.vec2, p: wp.vec3, n: wp.vec3) -> wp.vec3:
    return wp.vec3(uv[0], 1.0 - uv[0], 0.5)


@warp_spt.texture("t_nan")
def t_nan(uv: wp.vec2, p: wp.vec3, n: wp.vec3) -> wp.vec3:
    return wp.vec3(wp.log(-1.0 - uv[0]))      # NaN for every u > -1


# Camera at y=-10 looking +y, pinhole, focus on the plane y=0 with fov 90: the plane y=0 is the image
# plane, 20 units wide, so WIDTH pixels of 2 units each: pixel x covers plane x in [-10+2x, -8+2x].
WIDTH, HEIGHT, SPP = 10, 4, 64
CAMERA = Camera(position=(0.0, -10.0, 0.0), direction=(0.0, 1.0, 0.0), fov=90.0, aperture=0.0, focus=10.0)


def _quad(x0: float, x1: float) -> list[tuple[float, float, float]]:
    return [(x0, 0.0, -5.0), (x1, 0.0, -5.0), (x1, 0.0, 5.0), (x0, 0.0, 5.0)]


def _emitter(name: str, proc: str) -> str:
    return material(name, Kd=(0, 0, 0), Roughness=1) + f"map_Kl proc:{proc}\n"


@pytest.fixture(scope="module")
def analytic(tmp_path_factory):
    """Three emitting quads side by side: constant (pixels 0-2), ramp in u (3-7), NaN (8-9). The first
    two have Kd 0, so the second bounce (max_depth 2) adds nothing to them."""
    obj = "".join(quad_obj(_quad(a, b), material=m).replace("f 1/1 2/2 3/3", f"f {o+1}/{o+1} {o+2}/{o+2} {o+3}/{o+3}")
                  .replace("f 1/1 3/3 4/4", f"f {o+1}/{o+1} {o+3}/{o+3} {o+4}/{o+4}")
                  for o, (a, b, m) in zip((0, 4, 8), ((-10, -4, "c"), (-4, 6, "r"), (6, 10, "n"))))
    # the NaN is in the diffuse colour of an emitter: the path's next step carries it to the film guard
    nan = material("n", Kl=(1, 1, 1), Roughness=1) + "map_Kd proc:t_nan\n"
    mtl = _emitter("c", "t_const color=0.25,0.5,1.5") + _emitter("r", "t_ramp_u") + nan
    objs, mtls = write_scene_files(tmp_path_factory.mktemp("proc"), "analytic", obj, mtl)
    scene = load_scene(objs, mtls)
    with pytest.warns(RuntimeWarning, match="t_nan"):
        result = render_scene(scene, CAMERA, RenderSettings(width=WIDTH, height=HEIGHT, spp=SPP, max_depth=2))
    return scene, result


def test_constant_texture_renders_its_parameter_exactly(analytic):
    _, result = analytic
    img = result.image
    assert np.array_equal(img[:, 0:3], np.broadcast_to(np.float32([0.25, 0.5, 1.5]), (HEIGHT, 3, 3)))


def test_ramp_in_u_renders_u_at_the_pixel(analytic):
    _, result = analytic
    x_centre = -10.0 + 2.0 * np.arange(3, 8) + 1.0          # plane x at the pixel centres
    u = (x_centre + 4.0) / 10.0                               # the quad maps x in [-4, 6] to u in [0, 1]
    # per sample u is uniform over the pixel (width 0.2): mean error std 0.2 / sqrt(12 * SPP)
    tol = 5 * 0.2 / np.sqrt(12 * SPP)
    img = result.image[:, 3:8].astype(np.float64)
    np.testing.assert_allclose(img[..., 0], np.broadcast_to(u, (HEIGHT, 5)), atol=tol)
    np.testing.assert_allclose(img[..., 1], np.broadcast_to(1 - u, (HEIGHT, 5)), atol=tol)
    np.testing.assert_allclose(img[..., 2], 0.5, atol=1e-6)
    assert abs(img[..., 0].mean() - u.mean()) < tol / 2      # no bias in the mean over 20 pixels


def test_nan_texture_is_dropped_and_named(analytic):
    _, result = analytic
    assert result.stats.dropped_samples == 2 * HEIGHT * SPP
    assert result.stats.nonfinite_textures == ("t_nan",)
    assert np.all(result.image[:, 8:] == 0)


def test_parameters_are_a_device_array_per_instance(analytic):
    scene, result = analytic
    assert [r.name for r in scene.procedural] == ["t_const", "t_ramp_u", "t_nan"]
    dev = DeviceScene(scene)
    params = dev.proc_params.numpy()
    assert params.shape == (3, proctex.MAX_PARAMS) and tuple(params[0, :3]) == (0.25, 0.5, 1.5)
    names = [n for n, _ in result.stats.features.procedural]
    assert [names[k] for k in dev.proc_kind.numpy()] == ["t_const", "t_ramp_u", "t_nan"]
    assert set(scene.materials.tex[scene.materials.tex < -2]) == {TEX_PROC_BASE - k for k in range(3)}


def test_seed_checker_is_bit_identical_through_the_procedural_path(tmp_path):
    """The built-in Inner_CheckerTexture material vs the same material written with map_Kd proc:checker."""
    obj = quad_obj(_quad(-10, 10), uvs=((0, 0), (2.5, 0), (2.5, 1.3), (0, 1.3)), material="Inner_CheckerTexture")
    lit = "\n" + "\n".join(["v -30 -20 30", "v 30 -20 30", "v 0 -20 40", "usemtl lamp", "f 5 6 7"]) + "\n"
    lamp = material("lamp", Kl=(4, 4, 4), Kd=(0, 0, 0))
    proc = material("chk", Roughness=0.75, Fuzz=0.62, Kn=1.0) + "map_Kd proc:checker\n"
    settings = RenderSettings(width=24, height=8, spp=4, max_depth=3, seed=7)
    images = []
    for name, mat in (("builtin", "Inner_CheckerTexture"), ("proc", "chk")):
        objs, mtls = write_scene_files(tmp_path, name, obj.replace("usemtl Inner_CheckerTexture", f"usemtl {mat}") + lit,
                                       lamp + proc)
        images.append(render_scene(load_scene(objs, mtls), CAMERA, settings).image)
    assert images[0].max() > 0 and np.array_equal(images[0], images[1])


def test_checker_builtin_matches_the_seed_reference():
    uv = np.random.default_rng(1).uniform(-3, 3, (257, 2)).astype(np.float32)
    uv[:4] = [[0.0, 0.0], [1e30, 1e30], [-1e30, 1e30], [np.nan, 0.5]]
    refs = [proctex.proc_texture("checker"), proctex.proc_texture("grid", cells=4.0, width=0.5)]
    out = proctex.evaluate(refs, uv, np.zeros((len(uv), 3)), np.tile([0.0, 0.0, 1.0], (len(uv), 1)))
    np.testing.assert_array_equal(out[:, 0], checker_np(uv))
    # grid: lines of relative width 0.5 at every 1/4 in u and v (line colour 0.05, fill 0.9)
    f = np.mod(uv[4:] * 4.0, 1.0)
    on_line = ((f < 0.25) | (f > 0.75)).any(axis=1)
    np.testing.assert_allclose(out[4:, 1, 0], np.where(on_line, 0.05, 0.9), rtol=1e-6)


def test_noise_marble_wood_are_finite_and_bounded():
    rng = np.random.default_rng(2)
    p = rng.uniform(-50, 50, (512, 3))
    refs = [proctex.proc_texture(k) for k in ("noise", "marble", "wood")]
    out = proctex.evaluate(refs, rng.uniform(0, 1, (512, 2)), p, np.tile([0.0, 0.0, 1.0], (512, 1)))
    assert np.isfinite(out).all() and out.min() >= 0.0 and out.max() <= 1.0
    # noise is 0 (colour 0.5) at lattice points and varies between them
    lattice = proctex.evaluate(refs[:1], np.zeros((8, 2)), np.arange(24).reshape(8, 3) / 4.0, np.zeros((8, 3)))
    np.testing.assert_allclose(lattice[:, 0], 0.5, atol=1e-6)
    assert out[:, 0, 0].std() > 0.05


def test_mtl_syntax_errors_name_file_and_line():
    ok = parse_mtl_bytes(b"newmtl m\nmap_Kd proc:t_const color=0.25,0.5,1\n", "a.mtl")["m"]
    assert ok.base_color_map.name == "t_const" and ok.base_color_map.params[:3] == (0.25, 0.5, 1.0)
    assert ok.reflect_map == ok.diffuse_map
    for text, want in ((b"map_Kd proc:nope", "unknown procedural texture 'nope'"),
                       (b"map_Kd proc:t_const colour=1", "keys: color"),
                       (b"map_Kl proc:t_const color=1,2", "expected 3 finite"),
                       (b"map_Kt proc:t_const color=1,nan,2", "expected 3 finite"),
                       (b"map_Kd proc:t_const color", "key=value"),
                       (b"map_Kd proc:t_const color=1,2,3", "fills 'map_Kd'")):      # reflectance: at most 1
        with pytest.raises(SceneError, match=want) as err:
            parse_mtl_bytes(b"newmtl m\n\n" + text + b"\n", "b.mtl")
        assert err.value.path == "b.mtl" and err.value.line == 3


def test_registration_rejects_bad_declarations():
    with pytest.raises(ValueError, match="RGB triple"):
        proctex.register_texture("bad_params", t_const, color=(1, 2))
    with pytest.raises(ValueError, match="at most"):
        proctex.register_texture("too_many", t_const, **{f"c{i}": (1, 1, 1) for i in range(6)})
    with pytest.raises(ValueError, match="no parameter"):
        proctex.proc_texture("t_const", colour=1.0)


def test_scene_without_procedural_textures_compiles_the_same_kernel():
    """Registering textures changes nothing for scenes that do not use them; using one does."""
    plain = replace(Features.general(), lights=("environment.seen", "punctual", "sphere", "triangle", "triangle.texels",
                                                "triangle.tree"))   # every light kind but the sky's
    assert plain.procedural == ()
    step, start = get_step("seed", "independent", plain)
    h0 = make_kernel(step, start).module.hash_module()

    @warp_spt.texture("t_unused_by_plain")
    def unused(uv: wp.vec2, p: wp.vec3, n: wp.vec3) -> wp.vec3:
        return wp.vec3(3.0)

    step, start = get_step("seed", "independent", replace(plain))
    assert make_kernel(step, start).module.hash_module() == h0
    used = replace(plain, procedural=proctex.features_key(["t_unused_by_plain"]))
    step, start = get_step("seed", "independent", used)
    assert make_kernel(step, start).module.hash_module() != h0


USER_MODULE = '''
import warp as wp
import warp_spt

@warp_spt.texture("{name}", level=0.5)
def user_tex(uv: wp.vec2, p: wp.vec3, n: wp.vec3, prm: warp_spt.ProcParams) -> wp.vec3:
    return wp.vec3(prm[0], 2.0 * prm[0], {body})
'''


def _cli_scene(tmp_path, proc: str) -> tuple[str, str]:
    objs, mtls = write_scene_files(tmp_path, "cli", quad_obj(_quad(-30, 30)), _emitter("quad", proc))
    return objs[0], mtls[0]


def test_user_module_from_the_cli(tmp_path):
    module = tmp_path / "my_textures.py"
    module.write_text(USER_MODULE.format(name="t_cli_user", body="0.125"))
    obj, mtl = _cli_scene(tmp_path, "t_cli_user level=0.75")
    out = tmp_path / "out.npy"
    assert main(["--textures", str(module), "-obj", obj, "-mtl", mtl, "-res", "4", "2", "-sr", "1",
                 "-depth", "1", "--quiet", "-out", str(out), "-cam", "0", "-10", "0", "0", "1", "0", "90", "10", "0"]) == 0
    assert np.array_equal(np.load(out), np.broadcast_to(np.float32([0.75, 1.5, 0.125]), (2, 4, 3)))


def test_texture_that_fails_to_compile_names_texture_and_file(tmp_path, capsys):
    module = tmp_path / "broken_textures.py"
    module.write_text(USER_MODULE.format(name="t_broken", body="no_such_function(uv)"))
    obj, mtl = _cli_scene(tmp_path, "t_broken")
    status = main(["--textures", str(module), "-obj", obj, "-mtl", mtl, "-res", "2", "2", "-sr", "1",
                   "--quiet", "-out", str(tmp_path / "never.npy")])
    err = capsys.readouterr().err.strip()
    assert status == 1 and len(err.splitlines()) == 1
    assert "t_broken" in err and "failed to compile" in err and f"{module}:5" in err, err
    assert not (tmp_path / "never.npy").exists()


def test_texture_module_that_fails_to_import_names_the_file(tmp_path, capsys):
    module = tmp_path / "raising.py"
    module.write_text("import warp_spt\n\nraise RuntimeError('boom')\n")
    assert main(["--textures", str(module), "--quiet", "-out", str(tmp_path / "x.npy")]) == 1
    err = capsys.readouterr().err
    assert f"{module}:3" in err and "boom" in err


def test_parameter_gradients_match_finite_differences(tmp_path):
    """d(sum of image)/d(noise parameters) through a differentiable render of an emitter seen directly.

    ``noise`` (one octave, smooth) rather than marble: marble's 32x octave makes central differences
    need steps below float32's resolution of the image sum."""
    from warp_spt.diff.gradients import render_differentiable
    objs, mtls = write_scene_files(tmp_path, "grad", quad_obj(_quad(-10, 10)),
                                   _emitter("quad", "noise scale=0.35 color1=0.1,0.2,0.3"))
    dev = DeviceScene(load_scene(objs, mtls))
    params = proctex.enable_texture_gradients(dev)

    def loss() -> tuple[float, object]:
        r = render_differentiable(dev, CAMERA, width=6, height=3, spp=2, max_depth=1, seed=3)
        return float(r.numpy().astype(np.float64).sum()), r

    value, r = loss()
    r.tape.backward(grads={r.image: wp.ones(r.image.shape, dtype=wp.vec3)})
    grad = params.grad.numpy()[0].astype(np.float64)
    base = params.numpy().copy()
    layout = proctex.get_texture("noise").layout()
    for key in ("scale", "color1", "color2"):
        k = layout[key][0]                    # the first value of each parameter
        h = 1e-2 * abs(base[0, k]) if key == "scale" else 0.05
        sums = []
        for sign in (1, -1):
            bumped = base.copy()
            bumped[0, k] += sign * h
            params.assign(bumped)
            sums.append(loss()[0])
        params.assign(base)
        fd = (sums[0] - sums[1]) / (2 * h)
        assert abs(grad[k] - fd) <= 0.02 * abs(fd) + 1e-3, (key, grad[k], fd)
    assert abs(grad[layout["color1"][0]]) > 1.0      # the test is not vacuous


# ---- numpy transcription of the built-ins' noise (an independent implementation to check against)

def _np_perlin(q: np.ndarray) -> np.ndarray:
    """Improved Perlin noise with the same lattice hash and gradient set, in float64."""
    q = np.asarray(q, dtype=np.float64)
    cell = np.floor(q)
    f = q - cell
    i = cell.astype(np.int64)

    def hashed(dx, dy, dz):
        x, y, z = ((i[:, k] + d).astype(np.uint32) for k, d in enumerate((dx, dy, dz)))
        with np.errstate(over="ignore"):
            h = (x * np.uint32(73856093)) ^ (y * np.uint32(19349663)) ^ (z * np.uint32(83492791))
            h = (h ^ (h >> np.uint32(16))) * np.uint32(0x45D9F3B)
        return ((h ^ (h >> np.uint32(16))) & np.uint32(15)).astype(np.int64)

    def grad(h, x, y, z):
        u = np.where(h < 8, x, y)
        v = np.where(h < 4, y, np.where((h == 12) | (h == 14), x, z))
        return np.where(h & 1, -u, u) + np.where(h & 2, -v, v)

    fade = f * f * f * (f * (f * 6 - 15) + 10)
    corner = {}
    for dx in (0, 1):
        for dy in (0, 1):
            for dz in (0, 1):
                corner[dx, dy, dz] = grad(hashed(dx, dy, dz), f[:, 0] - dx, f[:, 1] - dy, f[:, 2] - dz)
    lerp = lambda a, b, t: a + (b - a) * t  # noqa: E731
    x = {(dy, dz): lerp(corner[0, dy, dz], corner[1, dy, dz], fade[:, 0]) for dy in (0, 1) for dz in (0, 1)}
    return lerp(lerp(x[0, 0], x[1, 0], fade[:, 1]), lerp(x[0, 1], x[1, 1], fade[:, 1]), fade[:, 2])


def test_noise_marble_wood_match_a_numpy_transcription():
    rng = np.random.default_rng(5)
    p = rng.uniform(-20, 20, (300, 3))
    refs = [proctex.proc_texture("noise", scale=1.3, color1=(0, 0, 0), color2=(1, 1, 1)),
            proctex.proc_texture("marble", scale=0.8, turbulence=2.0, color1=(1, 1, 1), color2=(0, 0, 0)),
            proctex.proc_texture("wood", scale=0.5, rings=3.0, color1=(0, 0, 0), color2=(1, 1, 1))]
    out = proctex.evaluate(refs, np.zeros((300, 2)), p, np.tile([0.0, 0.0, 1.0], (300, 1)))[..., 0]
    p32 = p.astype(np.float32).astype(np.float64)
    np.testing.assert_allclose(out[:, 0], np.clip(0.5 + 0.5 * _np_perlin(p32 * 1.3), 0, 1), atol=2e-5)
    q = p32 * 0.8
    turb = sum(np.abs(_np_perlin(q * 2.0**k)) / 2.0**k for k in range(proctex.TURBULENCE_OCTAVES))
    np.testing.assert_allclose(out[:, 1], 0.5 + 0.5 * np.sin(q[:, 0] + 2.0 * turb), atol=1e-4)
    q = p32 * 0.5
    t = (np.hypot(q[:, 0], q[:, 2]) + 0.1 * _np_perlin(q)) * 3.0
    t -= np.floor(t)
    near_ring = np.minimum(t, 1 - t) < 1e-4          # float32 may put these on the other side of a ring
    np.testing.assert_allclose(out[~near_ring, 2], (t * t)[~near_ring], atol=2e-4)


def test_reregistering_a_name_with_new_source_changes_the_cache_key():
    first = proctex.features_key(["t_const"])
    try:
        proctex.register_texture("t_const", t_ramp_u)
        assert proctex.features_key(["t_const"]) != first
    finally:    # the same function and parameters again: the same key
        proctex.register_texture("t_const", t_const, color=(0.2, 0.4, 0.6))
    assert proctex.features_key(["t_const"]) == first


def test_procedural_emitter_under_light_sampling_matches_the_constant_emitter(tmp_path):
    """nee picks procedural emitters by area alone (the host cannot evaluate them); for a texture that
    is constant this is the same choice as for the constant emission, so the images agree."""
    floor = quad_obj([(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)], material="floor")
    lamp = "\n".join(["v -1 -1 3", "v 1 -1 3", "v 1 1 3", "v -1 1 3", "usemtl lamp", "f 5 6 7", "f 5 7 8"]) + "\n"
    camera = Camera(position=(0.0, -6.0, 4.0), direction=(0.0, 1.0, -0.6), fov=60.0, aperture=0.0, focus=6.0)
    # no sky light: the lamp is the only light, so the light choice itself cannot differ
    settings = RenderSettings(width=8, height=8, spp=4, max_depth=2, integrator="nee", seed=11,
                              sky=Sky.constant(0.0, 0.0, 0.0))
    images = []
    for name, emission in (("const", "Kl 2 2 2"), ("proc", "map_Kl proc:t_const color=2,2,2")):
        mtl = material("floor", Kd=(0.5, 0.5, 0.5), Roughness=1) + f"newmtl lamp\nKd 0 0 0\n{emission}\n"
        objs, mtls = write_scene_files(tmp_path, name, floor + lamp, mtl)
        images.append(render_scene(load_scene(objs, mtls), camera, settings).image)
    assert images[0].mean() > 0.01
    np.testing.assert_allclose(images[1], images[0], rtol=1e-5, atol=1e-7)


@pytest.mark.parametrize("integrator", ["seed", "nee"])
def test_nan_emission_texture_is_dropped_and_named(tmp_path, integrator):
    """A NaN *emission* value reaches the film guard (nee used to skip it as 'max(Le) > 0' is false)."""
    obj = quad_obj(_quad(-10, 10), material="e")
    mtl = material("e", Kd=(0, 0, 0), Roughness=1) + "map_Kl proc:t_nan\n"
    objs, mtls = write_scene_files(tmp_path, "nan_emitter", obj, mtl)
    with pytest.warns(RuntimeWarning, match="t_nan"):
        result = render_scene(load_scene(objs, mtls), CAMERA,
                              RenderSettings(width=4, height=2, spp=4, max_depth=2, integrator=integrator))
    assert result.stats.dropped_samples == 4 * 2 * 4
    assert result.stats.nonfinite_textures == ("t_nan",)
