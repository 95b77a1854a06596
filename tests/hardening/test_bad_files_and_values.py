"""Issue 11, parts 2-4 and 6: special files, size bounds, errors that name file and line, values
that could overflow in a kernel, and the smaller command-line promises. One test per class."""

from __future__ import annotations

import errno
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import warp_spt.io.tokens as tokens
from warp_spt.cli.common import UsageError
from warp_spt.cli.main import main
from warp_spt.cli.options import parse_args
from warp_spt.images.files import save_image
from warp_spt.io.loader import load_scene
from warp_spt.scene.errors import SceneError
from warp_spt.scene.sky import SKY_CONSTANT, Sky
from warp_spt.scene.validate import MAX_RADIANCE

from tests.support.fakes import fake_renderer

REPO = Path(__file__).resolve().parents[2]
TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"


def write(tmp_path: Path, name: str, data: str | bytes) -> Path:
    p = tmp_path / name
    p.write_bytes(data.encode() if isinstance(data, str) else data)
    return p


def scene_error(objs, mtls=()) -> SceneError:
    with pytest.raises(SceneError) as info:
        load_scene([str(o) for o in objs], [str(m) for m in mtls], warn=lambda m: None)
    return info.value


# ---------------------------------------------------------------- part 2: special files and bounds

@pytest.mark.parametrize("kind", ["obj", "mtl"])
def test_a_fifo_is_refused_without_blocking(tmp_path, kind):
    fifo = tmp_path / f"f.{kind}"
    os.mkfifo(fifo)
    objs, mtls = ([fifo], []) if kind == "obj" else ([write(tmp_path, "a.obj", TRI)], [fifo])
    err = scene_error(objs, mtls)
    assert err.path == str(fifo) and "FIFO" in err.message


@pytest.mark.parametrize("device", ["/dev/zero", "/dev/urandom"])
def test_devices_are_refused(device):
    if not os.path.exists(device):
        pytest.skip(f"{device} does not exist here")
    assert "character device" in scene_error([device]).message


def test_the_cli_refuses_a_fifo_at_once(tmp_path, capsys):
    fifo = tmp_path / "f.obj"
    os.mkfifo(fifo)
    assert main(["-obj", str(fifo), "--quiet", "-out", str(tmp_path / "o.png")]) == 1
    assert "FIFO" in capsys.readouterr().err


def test_line_and_file_size_bounds(tmp_path, monkeypatch):
    monkeypatch.setattr(tokens, "MAX_LINE_BYTES", 64)
    err = scene_error([write(tmp_path, "long.obj", TRI + "v " + "1 " * 60 + "\n")])
    assert (err.line, "limit" in err.message) == (5, True)
    monkeypatch.setattr(tokens, "MAX_FILE_BYTES", 16)
    assert "larger than" in scene_error([write(tmp_path, "big.obj", TRI)]).message


# ---------------------------------------------------------------- part 3: file and line in every error

def test_classic_mac_line_ends_are_line_ends(tmp_path):
    write(tmp_path, "a.mtl", b"newmtl m\rKd 0.5 0.25 1\r")
    obj = write(tmp_path, "cr.obj", b"mtllib a.mtl\r" + b"v 0 0 0\r" * 40 + b"v 1 0 0\rv 0 1 0\rusemtl m\rf 40 41 42\r")
    scene = load_scene([str(obj)], warn=lambda m: None)
    assert scene.num_triangles == 1 and scene.materials.names == ["Inner_CheckerTexture", "m"]
    assert scene.materials.base_color[1].tolist() == [0.5, 0.25, 1.0]
    err = scene_error([write(tmp_path, "bad.obj", b"v 0 0 0\rv 1 0 0\r\nv x 0 0\r")])
    assert err.line == 3


def test_a_too_long_mtllib_name_is_a_warning_with_its_line(tmp_path):
    obj = write(tmp_path, "a.obj", "# c\nmtllib " + "x" * 300 + ".mtl\n" + TRI)
    warned = []
    load_scene([str(obj)], warn=warned.append)
    assert len(warned) == 1 and warned[0].startswith(f"{obj}:2: mtllib") and "too long" in warned[0]


def test_a_too_long_texture_name_names_the_mtl_line(tmp_path):
    write(tmp_path, "a.mtl", "newmtl m\nmap_Kd " + "t" * 300 + ".png\n")
    err = scene_error([write(tmp_path, "a.obj", "mtllib a.mtl\nusemtl m\n" + TRI)])
    assert (err.path, err.line) == (str(tmp_path / "a.mtl"), 2) and "too long" in err.message


def test_a_sphere_whose_box_overflows_float32_is_an_error_at_its_line(tmp_path):
    err = scene_error([write(tmp_path, "b.obj", TRI + "b 3e38 0 0 3e38\n")])
    assert err.line == 5 and "range" in err.message
    assert scene_error([write(tmp_path, "v.obj", "v 1e16 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")]).line == 1


@pytest.mark.parametrize("data, why", [
    (b"", "no 'v', 'f' or 'b' lines"),
    (b"# only a comment\no thing\n", "no 'v', 'f' or 'b' lines"),
    (b"v 0 0 0\nv 1 0 0\n", "2 'v' lines but no faces"),
    ("v 0 0 0\nf 1 1 1\n".encode(), "zero area"),
    ("v 0 0 0\n".encode("utf-16"), "UTF-16"),
    (b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR", "PNG image"),
])
def test_a_scene_without_geometry_names_the_file_and_says_why(tmp_path, data, why):
    err = scene_error([write(tmp_path, "s.obj", data)])
    assert err.path == str(tmp_path / "s.obj") and why in err.message


def test_an_ior_that_is_zero_in_float32_names_the_mtl_line(tmp_path):
    write(tmp_path, "a.mtl", "newmtl m\nNi 1e-46\n")
    err = scene_error([write(tmp_path, "a.obj", "mtllib a.mtl\nusemtl m\n" + TRI)])
    assert (err.path, err.line) == (str(tmp_path / "a.mtl"), 2)


def test_a_full_disk_names_the_output_and_the_reason(tmp_path, monkeypatch, capsys):
    def full(fd, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(os, "write", full)
    out = tmp_path / "o.npy"
    with pytest.raises(OSError, match=f"cannot write {out}: no space left on device"):
        save_image(out, np.zeros((2, 2, 3), np.float32))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.skipif(os.geteuid() == 0, reason="root ignores directory permissions")
def test_a_read_only_directory_names_the_output(tmp_path):
    out = tmp_path / "o.png"
    tmp_path.chmod(0o555)
    try:
        with pytest.raises(OSError, match=f"cannot write {out}: permission denied"):
            save_image(out, np.zeros((2, 2, 3), np.float32))
    finally:
        tmp_path.chmod(0o755)


# ---------------------------------------------------------------- part 4: values that reach a kernel

@pytest.mark.parametrize("argv, message", [
    (["--sky-color", "1e39", "0", "0"], "sky colour"),
    (["-cam", "1e39", "0", "0", "0", "1", "0", "38", "27", "0.001"], "position"),
    (["-cam", "0", "0", "0", "1e308", "1e308", "1e308", "38", "27", "0.001"], "direction"),
    (["-cam", "0", "0", "0", "0", "1", "0", "38", "1e-320", "0.001"], "focus"),
    (["-cam", "0", "0", "0", "0", "1", "0", "38", "27", "1e300"], "aperture"),
])
def test_camera_and_sky_values_beyond_float32_products_are_refused(argv, message):
    with pytest.raises(UsageError, match=message):
        parse_args(argv)


@pytest.mark.parametrize("argv, message", [
    (["-cam", "0", "0", "0", "0", "1", "0", "179.99999999", "1e15", "0"], "image plane"),
    (["-obj", "x.obj", "--look-at", "1e300", "0", "0"], "target"),
    (["-obj", "x.obj", "--fov", "180"], "fov"),
])
def test_camera_overrides_beyond_float32_are_refused_in_one_line(argv, message, capsys):
    with warnings.catch_warnings():
        warnings.simplefilter("error")            # numpy's overflow warnings would print with --quiet
        with pytest.raises(UsageError, match=message):
            parse_args(argv)


@pytest.mark.parametrize("changes, message", [
    (dict(position=(1e39, 0, 0)), "position"), (dict(position=(0, 0, 1e18)), "position"),
    (dict(direction=(1e308, 1e308, 1e308)), "direction"), (dict(direction=(1e-320, 0, 0)), "direction"),
    (dict(direction=(0, float("nan"), 1)), "finite"), (dict(up=(0, 0, 1e300)), "up"),
    (dict(focus=1e-320), "focus"), (dict(focus=1e18), "focus"), (dict(aperture=1e300), "aperture"),
    (dict(aperture=-1e-3), "aperture"), (dict(fov=180.0), "fov"), (dict(fov=0.0), "fov"),
    (dict(fov=179.99999999, focus=1e15), "image plane"), (dict(position="abc"), "numbers"),
])
def test_the_api_camera_refuses_what_the_cli_refuses(tmp_path, changes, message):
    from dataclasses import replace

    from warp_spt.rendering.tiles import render
    from warp_spt.scene.camera import Camera

    cam = replace(Camera(), **changes)            # a frozen dataclass: construction itself does not check
    ball = load_scene([str(write(tmp_path, "b.obj", "b 0 0 0 1\n"))], warn=lambda m: None)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(ValueError, match=message):
            cam.validate()
        with pytest.raises(ValueError, match=message):
            render(ball, cam, width=2, height=2, spp=1)     # refused before the scene is uploaded
        with pytest.raises(ValueError, match=message):
            Camera().with_(**changes)


def test_a_tall_image_bounds_the_image_plane_too():
    from warp_spt.scene.camera import Camera

    cam = Camera(fov=179.99999, focus=1e10)     # half-width 1.1e17: fine for a wide image
    cam.image_plane(100, 10)
    with pytest.raises(ValueError, match="image plane"):
        cam.image_plane(10, 1000)                  # 100x taller than wide: 1.1e19


@pytest.mark.parametrize("make, message", [
    (lambda: Sky.constant(1e39, 0, 0), "colour"), (lambda: Sky.constant(0, float("inf"), 0), "colour"),
    (lambda: Sky.constant(-1e-9, 0, 0), "colour"), (lambda: Sky(SKY_CONSTANT, (float("nan"), 0, 0)), "colour"),
    (lambda: Sky(SKY_CONSTANT, (1, 2)), "colour"), (lambda: Sky(7, (0, 0, 0)), "kind"),
    (lambda: Sky.gradient(up=(0, 0, 0)), "up"), (lambda: Sky.gradient(up=(float("nan"), 0, 1)), "up"),
])
def test_the_api_sky_refuses_what_the_cli_refuses(make, message):
    with pytest.raises(ValueError, match=message):
        make()
    assert Sky.constant(MAX_RADIANCE, 0, 0).color == (MAX_RADIANCE, 0.0, 0.0)


@pytest.mark.parametrize("line, message", [("Kd 1e38", "[0, 1]"), ("Kl 1e31 0 0", "[0, 1e+30]"),
                                           ("Kn 1e-40", "[0.001, 1000]")])
def test_material_values_beyond_float32_products_name_the_line(tmp_path, line, message):
    write(tmp_path, "a.mtl", f"newmtl m\n{line}\n")
    err = scene_error([write(tmp_path, "a.obj", "mtllib a.mtl\nusemtl m\n" + TRI)])
    assert err.line == 2 and message in err.message


# ---------------------------------------------------------------- part 6: smaller promises

@pytest.mark.parametrize("argv", [["-sr", "1_0"], ["-sr", "\u0661\u0660"], ["-res", "\uff11\uff10", "8"],
                                  ["-cam", "0", "0", "1_0", "0", "1", "0", "38", "27", "0.001"],
                                  ["--sky-color", "\u0661", "0", "0"], ["-out", ""]])
def test_only_plain_ascii_numbers_and_real_file_names(argv):
    with pytest.raises(UsageError):
        parse_args(argv)


def test_a_symlinked_output_is_written_through(tmp_path):
    target = tmp_path / "real.npy"
    target.write_bytes(b"old")
    link = tmp_path / "link.npy"
    link.symlink_to(target)
    save_image(link, np.ones((2, 2, 3), np.float32))
    assert link.is_symlink() and np.load(target).shape == (2, 2, 3)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link.npy", "real.npy"]


def test_an_output_that_is_a_device_is_refused(tmp_path, capsys):
    obj = write(tmp_path, "a.obj", TRI)
    link = tmp_path / "null.png"
    link.symlink_to("/dev/null")
    assert main(["-obj", str(obj), "--quiet", "-out", str(link)]) == 1
    assert "character device" in capsys.readouterr().err and os.path.exists("/dev/null")


def run_cli(tmp_path: Path, *extra: str) -> subprocess.CompletedProcess:
    obj = write(tmp_path, "a.obj", "b 4 -100 16 1\n")
    env = dict(os.environ, PYTHONPATH=str(REPO))
    env.pop("WARP_SPT_VERBOSE", None)
    return subprocess.run([sys.executable, "-m", "warp_spt", "-obj", str(obj), "-res", "4", "4", "-sr", "1",
                           "-out", str(tmp_path / "o.npy"), *extra], capture_output=True, text=True, env=env,
                          timeout=300)


def test_warps_own_messages_only_with_verbose(tmp_path):
    plain = run_cli(tmp_path)
    assert plain.returncode == 0 and "Warp" not in plain.stderr + plain.stdout
    # every line is ours (loaded, framed: the sphere is behind the default camera, maybe compiling, wrote)
    prefixes = [line.split(":")[0] for line in plain.stderr.splitlines()]
    assert len(prefixes) >= 2 and set(prefixes) == {"warp-spt"}, plain.stderr
    verbose = run_cli(tmp_path, "--verbose")
    assert verbose.returncode == 0 and "Warp 1.19" in verbose.stdout + verbose.stderr


# ---------------------------------------------------------------- part 5: memory

def thin_texture_scene(tmp_path: Path, n: int) -> Path:
    """An OBJ whose two materials use a 1 x n and an n x 1 texture of random colours."""
    from PIL import Image

    rng = np.random.default_rng(n)
    for name, shape in (("tall.png", (n, 1, 3)), ("wide.png", (1, n, 3))):
        Image.fromarray(rng.integers(0, 256, shape, dtype=np.uint8)).save(tmp_path / name)
    write(tmp_path, "a.mtl", "newmtl a\nmap_Kd tall.png\nnewmtl b\nmap_Kd wide.png\n")
    return write(tmp_path, "a.obj", "mtllib a.mtl\n" + TRI + "usemtl a\nf 1 2 3\nusemtl b\nf 1 2 3\n")


@pytest.mark.parametrize("n", [20000, 40000])
def test_thin_textures_take_the_sum_of_their_areas_and_sample_right(tmp_path, n):
    from warp_spt.upload.device_scene import DeviceScene
    from warp_spt.device.textures import Atlas, sample_texture_np

    from tests.device.test_textures import run_sample

    scene = load_scene([str(thin_texture_scene(tmp_path, n))], warn=lambda m: None)
    dev = DeviceScene(scene)
    texels, tiles = dev.atlas_arrays()
    # memory: the device atlas holds 2n texels (it used to be n x n: 4.5 GiB at n = 20000)
    assert texels.shape == (2 * n,) and texels.capacity == 2 * n * 12 and tiles.shape == (2,)
    atlas = Atlas(texels.numpy(), tiles.numpy())
    rng = np.random.default_rng(3)
    uv = np.concatenate([rng.uniform(-2, 2, (3000, 2)), [[0, 0], [1, 1], [-1e-7, 1 - 1e-7], [0.5, np.nan]],
                         np.stack([np.arange(-2, n + 2) / n, np.arange(-2, n + 2)[::-1] / n], 1)]).astype(np.float32)
    for k, img in enumerate(scene.textures):
        assert np.array_equal(run_sample(atlas, k, uv, bilinear=False), sample_texture_np(img, uv))
        np.testing.assert_allclose(run_sample(atlas, k, uv, bilinear=True), sample_texture_np(img, uv, True),
                                   rtol=0, atol=1e-6)


def test_textures_beyond_the_budget_are_refused_from_the_header_naming_them(tmp_path, monkeypatch):
    import warp_spt.io.loader as loader

    monkeypatch.setattr(loader, "TEXEL_BUDGET", 30000)      # 1x20000 + 20000x1 fit 2**26, not this
    read = []
    real = loader._to_rgb
    monkeypatch.setattr(loader, "_to_rgb", lambda img, **kw: read.append(img.size) or real(img, **kw))
    err = scene_error([thin_texture_scene(tmp_path, 20000)])
    assert err.line == 4 and "tall.png" in err.message and "wide.png" in err.message and "budget" in err.message
    assert "40,000 texels" in err.message and read == [(1, 20000)]      # the second was never decoded


def test_a_texture_beyond_the_texel_budget_is_refused_before_decoding(tmp_path, recwarn):
    from PIL import Image

    Image.new("1", (12000, 12000)).save(tmp_path / "bomb.png")      # 144 Mtexel in a few kilobytes
    write(tmp_path, "a.mtl", "newmtl a\nmap_Kd bomb.png\n")
    err = scene_error([write(tmp_path, "a.obj", "mtllib a.mtl\nusemtl a\n" + TRI)])
    assert err.line == 2 and "12000x12000" in err.message and "budget" in err.message
    assert not [w for w in recwarn if issubclass(w.category, Image.DecompressionBombWarning)]


def test_a_16_bit_grey_texture_keeps_its_values(tmp_path):
    from PIL import Image

    values = np.array([[0, 16384], [32768, 65535]], np.uint16)
    Image.fromarray(values).save(tmp_path / "g.png")
    write(tmp_path, "a.mtl", "newmtl a\nmap_Kd g.png\nmap_Pr g.png\n")
    scene = load_scene([str(write(tmp_path, "a.obj", "mtllib a.mtl\nusemtl a\n" + TRI))], warn=lambda m: None)
    row = scene.materials.names.index("a")
    c = values / 65535.0
    srgb = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)    # a colour map: IEC 61966-2-1
    np.testing.assert_allclose(scene.textures[scene.materials.tex[row, 4]][..., 1], srgb, rtol=1e-5)
    np.testing.assert_allclose(scene.textures[scene.materials.tex[row, 6]][..., 1], c, rtol=1e-6)  # data: as stored


def test_out_of_memory_while_loading_names_the_scene(tmp_path, monkeypatch, capsys):
    import warp_spt.io.loader as loader

    def no_memory(*args, **kwargs):
        raise MemoryError

    monkeypatch.setattr(loader, "load_scene", no_memory)
    assert main(["-obj", str(write(tmp_path, "a.obj", TRI)), "-out", str(tmp_path / "o.png")]) == 1
    assert "out of memory while loading the scene" in capsys.readouterr().err


def test_an_unwritable_directory_names_the_output_not_the_temp_file(tmp_path, monkeypatch):
    real_open = os.open

    def denied(path, flags, mode=0o777):
        if str(path).endswith(".tmp"):
            raise PermissionError(errno.EACCES, os.strerror(errno.EACCES), str(path))
        return real_open(path, flags, mode)

    monkeypatch.setattr(os, "open", denied)
    out = tmp_path / "o.png"
    with pytest.raises(OSError) as info:
        save_image(out, np.zeros((2, 2, 3), np.float32))
    assert str(info.value) == f"[Errno {errno.EACCES}] cannot write {out}: permission denied"
    assert ".tmp" not in str(info.value)


def test_dropped_samples_are_reported_even_with_quiet(tmp_path, monkeypatch, capsys):

    monkeypatch.setitem(sys.modules, "warp_spt.rendering.tiles", fake_renderer(
        lambda scene, camera, **kw: np.zeros((kw["height"], kw["width"], 3), np.float32), dropped_samples=3))
    obj = write(tmp_path, "a.obj", TRI)
    assert main(["-obj", str(obj), "--quiet", "-res", "2", "2", "-out", str(tmp_path / "o.npy")]) == 0
    assert "3 samples were not finite" in capsys.readouterr().err
