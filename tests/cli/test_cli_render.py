"""warp-spt end to end: small renders through main(), the seed's demo command, atomic output, Ctrl-C."""

from __future__ import annotations

import sys
import types
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from warp_spt.cli.main import main
from warp_spt.scene.sky import Sky

from tests.support.fakes import fake_renderer
from tests.support.reference import literal_seed_search

SHARED = Path(__file__).resolve().parents[2].parent / "shared"
SEED_DEMO = SHARED / "seed" / "demo"
SKY = (0.25, 0.5, 1.0)


def sky_only_scene(tmp_path: Path) -> Path:
    """A scene whose only object, a sphere, is behind the default camera: every pixel sees the sky."""
    obj = tmp_path / "behind.obj"
    obj.write_text("b 4 -100 16 1\n")
    return obj


def lit_scene(tmp_path: Path) -> tuple[Path, Path]:
    """A floor, a light and a glass ball: enough to exercise every part of the engine a little."""
    mtl = tmp_path / "s.mtl"
    mtl.write_text("newmtl lamp\nKl 2 2 2\nKd 1 1 1\nnewmtl floor\nKd 0.8 0.8 0.8\n"
                   "newmtl glass\nKd 1 1 1\nKt 1 1 1\nRoughness 0\nFuzz 0\nKn 1.5\nRefractable\n")
    obj = tmp_path / "s.obj"
    obj.write_text("v -20 -20 0\nv 20 -20 0\nv 20 20 0\nv -20 20 0\n"
                   "v -5 -5 30\nv 5 -5 30\nv 5 5 30\nv -5 5 30\n"
                   "usemtl floor\nf 1 2 3 4\nusemtl lamp\nf 5 6 7 8\nusemtl glass\nb 4 0 6 5\n")
    return obj, mtl


def srgb8(x: float) -> int:
    c = 12.92 * x if x <= 0.0031308 else 1.055 * x ** (1 / 2.4) - 0.055
    return int(round(min(max(c, 0.0), 1.0) * 255))


def read_pfm(path: Path) -> np.ndarray:
    """A colour PFM, read from the format's definition: 'PF', size, scale (<0: little-endian), rows bottom up."""
    data = path.read_bytes()
    fields = data.split(b"\n", 3)
    assert fields[0] == b"PF"
    w, h = map(int, fields[1].split())
    scale = float(fields[2])
    dtype = "<f4" if scale < 0 else ">f4"
    return np.frombuffer(fields[3], dtype=dtype, count=w * h * 3).reshape(h, w, 3)[::-1]


def render_sky(tmp_path: Path, out: str, *extra: str) -> Path:
    obj = sky_only_scene(tmp_path)
    path = tmp_path / out
    # the seed's default camera, given explicitly: without -cam, a scene it cannot see would be framed
    status = main(["-obj", str(obj), "-cam", *"4 -55 16 0 1 0 38 27 0.001".split(),
                   "-res", "16", "12", "-sr", "2", "-depth", "3", "--quiet",
                   "--sky-color", *map(str, SKY), "-out", str(path), *extra])
    assert status == 0
    return path


# ---------------------------------------------------------------- real renders (need the engine)

def test_npy_is_linear_radiance_of_the_sky(tmp_path):
    img = np.load(render_sky(tmp_path, "sky.npy"))
    assert img.shape == (12, 16, 3) and img.dtype == np.float32
    np.testing.assert_allclose(img, np.broadcast_to(SKY, img.shape), rtol=1e-6)


def test_pfm_is_linear_radiance_of_the_sky(tmp_path):
    img = read_pfm(render_sky(tmp_path, "sky.pfm"))
    assert img.shape == (12, 16, 3)
    np.testing.assert_allclose(img, np.broadcast_to(SKY, img.shape), rtol=1e-6)


@pytest.mark.parametrize("tonemap, curve", [("seed", literal_seed_search), ("srgb", srgb8)])
def test_png_is_tone_mapped(tmp_path, tonemap, curve):
    with Image.open(render_sky(tmp_path, "sky.png", "--tonemap", tonemap)) as im:
        assert im.mode == "RGB" and im.size == (16, 12)
        pixels = np.asarray(im)
    expected = [curve(x) for x in SKY]   # seed: 128, 182, 224; srgb: 137, 188, 255
    assert (pixels == np.array(expected, dtype=np.uint8)).all()


def test_a_lit_scene_renders_finite_non_negative_radiance(tmp_path):
    obj, mtl = lit_scene(tmp_path)
    out = tmp_path / "lit.npy"
    assert main(["-mtl", str(mtl), "-obj", str(obj), "-res", "16", "16", "-sr", "2", "-depth", "4",
                 "--threads", "2", "--seed", "7", "--filter", "bilinear", "--quiet", "-out", str(out)]) == 0
    img = np.load(out)
    assert img.shape == (16, 16, 3) and np.isfinite(img).all() and (img >= 0).all() and img.max() > 0


def test_the_builtin_demo_renders_with_no_scene_arguments(tmp_path):
    out = tmp_path / "demo.png"
    assert main(["-res", "16", "16", "-sr", "1", "-depth", "2", "--quiet", "-out", str(out)]) == 0
    with Image.open(out) as im:
        assert im.size == (16, 16)


@pytest.mark.skipif(not SEED_DEMO.is_dir(), reason="../shared/seed/demo is not available")
def test_the_seeds_demo_command_renders(tmp_path, monkeypatch):
    monkeypatch.chdir(SEED_DEMO)   # the seed's MTL names its textures relative to the working directory
    out = tmp_path / "512p16s.png"
    argv = ["-mtl", "testMiku.mtl", "-obj", "cornell_export.obj", "-obj", "baller.obj",
            "-sky", "1", "-res", "32", "32", "-sr", "2", "-depth", "8", "--quiet", "-out", str(out)]
    assert main(argv) == 0
    with Image.open(out) as im:
        pixels = np.asarray(im)
    assert pixels.shape == (32, 32, 3) and pixels.min() >= 1 and pixels.max() <= 254   # the seed's range (Q13)
    # The left wall is Kd (1, 0, 0): any path that meets it first carries no green or blue, which the seed's
    # curve writes as 1 (its own 512p16s.png has G = B = 1 there too).
    wall = pixels[10:22, 1:4]
    assert (wall[..., 1] == 1).all() and (wall[..., 2] == 1).all() and (wall[..., 0] > 1).mean() > 0.5


# ---------------------------------------------------------------- atomic output and Ctrl-C (engine stubbed)

def stub_view(monkeypatch) -> None:
    """No framing, probes or upload for a stubbed engine: the CLI renders its own camera and sky."""
    monkeypatch.setattr("warp_spt.cli.render.prepare_view", lambda opts, scene, say, **kw: (scene, opts.camera, opts.sky))


class FakeEngine:
    """Stands in for loader, render and film so the CLI's wiring can be checked on its own."""

    def __init__(self, monkeypatch, render_effect=None):
        self.calls: dict[str, object] = {}
        self.render_effect = render_effect
        scene = types.SimpleNamespace(warnings=["a warning"], num_triangles=2, spheres=np.zeros((1, 4)),
                                      bounds=np.zeros((2, 3)), meshes=[], dropped_degenerate=0,
                                      lights=[], fog=None, interiors={}, instanced=False,
                                      seed_dialect=True)   # the seed's curve, no denoiser: the plain path
        stub_view(monkeypatch)
        fakes = {
            "warp_spt.io.loader": types.SimpleNamespace(load_scene=lambda objs, mtls, **kw: self._record("load", (objs, mtls), scene)),
            "warp_spt.rendering.tiles": fake_renderer(self._render),
            "warp_spt.images.files": types.SimpleNamespace(save_image=self._save),
        }
        for name, module in fakes.items():
            monkeypatch.setitem(sys.modules, name, module)

    def _record(self, key, value, result=None):
        self.calls[key] = value
        return result

    def _render(self, scene, camera, **kw):
        self.calls["render"] = (camera, kw)
        if kw["progress"]:
            for done in range(1, 5):
                kw["progress"](done, 4)
        if self.render_effect is not None:
            raise self.render_effect
        return np.zeros((kw["height"], kw["width"], 3), np.float32)

    def _save(self, path, img, tonemap="seed", exposure=0.0):
        self.calls["save"] = (path, img.shape, tonemap)
        Path(path).write_bytes(b"image")


def test_flags_reach_the_engine(tmp_path, monkeypatch, capsys):
    engine = FakeEngine(monkeypatch)
    obj, mtl = lit_scene(tmp_path)
    out = str(tmp_path / "o.png")
    assert main(["-obj", str(obj), "-mtl", str(mtl), "-res", "8", "4", "-sr", "3", "-depth", "5", "-sky", "2",
                 "-cam", "1", "2", "3", "0", "1", "0", "50", "12", "0.25", "--threads", "2", "--seed", "9",
                 "--filter", "bilinear", "--tonemap", "srgb", "-out", out]) == 0
    assert engine.calls["load"] == ([str(obj)], [str(mtl)])
    camera, kw = engine.calls["render"]
    assert (camera.position, camera.fov, camera.focus, camera.aperture) == ((1.0, 2.0, 3.0), 50.0, 12.0, 0.25)
    assert {k: kw[k] for k in ("width", "height", "spp", "max_depth", "seed", "threads", "texture_filter")} == \
        {"width": 8, "height": 4, "spp": 3, "max_depth": 5, "seed": 9, "threads": 2, "texture_filter": "bilinear"}
    assert kw["sky"] == Sky.pink() and callable(kw["progress"])
    assert engine.calls["save"] == (out, (4, 8, 3), "srgb")
    err = capsys.readouterr().err
    assert "a warning" in err and "wrote" in err


def test_quiet_prints_nothing_and_passes_no_progress(tmp_path, monkeypatch, capsys):
    engine = FakeEngine(monkeypatch)
    assert main(["-res", "4", "4", "--quiet", "-out", str(tmp_path / "o.png")]) == 0
    assert engine.calls["render"][1]["progress"] is False
    assert capsys.readouterr() == ("", "")


def test_no_arguments_loads_the_builtin_demo(tmp_path, monkeypatch):
    engine = FakeEngine(monkeypatch)
    monkeypatch.chdir(tmp_path)
    assert main(["--quiet"]) == 0
    objs, mtls = engine.calls["load"]
    assert [Path(p).name for p in objs] == ["cornell.obj", "sculpture.obj", "spheres.obj"]
    assert [Path(p).name for p in mtls] == ["demo.mtl"] and all(Path(p).is_file() for p in objs + mtls)
    assert engine.calls["save"][0] == "output.png" and (tmp_path / "output.png").exists()


@pytest.mark.parametrize("effect, status, message", [(RuntimeError("kernel exploded"), 1, "kernel exploded"),
                                                     (KeyboardInterrupt(), 130, "interrupted"),
                                                     (MemoryError(), 1, "out of memory")])
def test_a_failed_render_leaves_no_file_and_keeps_an_old_one(tmp_path, monkeypatch, capsys, effect, status, message):
    FakeEngine(monkeypatch, render_effect=effect)
    fresh = tmp_path / "fresh.png"
    assert main(["-res", "4", "4", "-out", str(fresh)]) == status
    assert not fresh.exists() and list(tmp_path.iterdir()) == []
    old = tmp_path / "old.png"
    old.write_bytes(b"previous render")
    assert main(["-res", "4", "4", "--quiet", "-out", str(old)]) == status
    assert old.read_bytes() == b"previous render" and list(tmp_path.iterdir()) == [old]
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_scene_errors_are_one_line(tmp_path, monkeypatch, capsys):
    from warp_spt.scene.errors import SceneError

    FakeEngine(monkeypatch)

    def bad_load(objs, mtls, **kw):
        raise SceneError("room.obj", 12, "expected 3 numbers after 'v'")

    monkeypatch.setattr(sys.modules["warp_spt.io.loader"], "load_scene", bad_load)
    assert main(["-res", "4", "4", "-out", str(tmp_path / "o.png")]) == 1
    assert capsys.readouterr().err == "warp-spt: error: room.obj:12: expected 3 numbers after 'v'\n"
    assert not (tmp_path / "o.png").exists()


def test_real_interrupt_during_save_leaves_no_partial_file(tmp_path, monkeypatch):
    """With the real film writer: a Ctrl-C while the file is written leaves nothing behind."""
    import warp_spt.images.files as film

    real_save = film.save_image
    monkeypatch.setitem(sys.modules, "warp_spt.io.loader",
                        types.SimpleNamespace(load_scene=lambda o, m, **kw: types.SimpleNamespace(
                            warnings=[], num_triangles=0, spheres=np.zeros((0, 4)), bounds=np.zeros((2, 3)),
                            meshes=[], dropped_degenerate=0, lights=[], fog=None, interiors={},
                            instanced=False)))
    stub_view(monkeypatch)
    monkeypatch.setitem(sys.modules, "warp_spt.rendering.tiles",
                        fake_renderer(lambda scene, camera, **kw: np.full((kw["height"], kw["width"], 3), 0.5, np.float32)))

    def interrupted_write(*args, **kwargs):
        raise KeyboardInterrupt

    # Interrupt inside the writer: PIL's and numpy's savers are what save_image calls to fill the file.
    monkeypatch.setattr(Image.Image, "save", interrupted_write)
    monkeypatch.setattr(np, "save", interrupted_write)
    for name in ("o.png", "o.npy"):
        assert main(["-res", "8", "8", "--quiet", "-out", str(tmp_path / name)]) == 130
    assert list(tmp_path.iterdir()) == [], "a partial or temporary file was left behind"
    assert real_save is film.save_image
