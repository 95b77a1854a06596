"""Noise and tone at the defaults (issue 43, item 5): a standard file's first image is tone mapped
with the filmic curve and denoised when Open Image Denoise is installed; the seed's own scenes keep
the seed's curve and are never denoised (their images stay bit-identical: tests/house)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from tests.support.models import write_model
from tests.support.scenes import material
from tests.support.stability_scenes import quads_obj
from warp_spt.cli.main import run
from warp_spt.cli.options import parse_args
from warp_spt.images.files import filmic_curve, tonemap_filmic, tonemap_seed, tonemap_srgb

SUN = ["--sun", "-0.6", "1.5", "0.4"]
SIZE = ["-res", "48", "36", "-sr", "4"]


def cli(argv: list[str]) -> str:
    err = io.StringIO()
    assert run(parse_args(argv), stderr=err) == 0, err.getvalue()
    return err.getvalue()


@pytest.fixture(scope="module")
def bunny(tmp_path_factory) -> str:
    return str(write_model(tmp_path_factory.mktemp("tone") / "bunny.obj", "bunny", up="y"))


@pytest.fixture(scope="module")
def seed_file(tmp_path_factory) -> list[str]:
    """A scene in the seed's dialect (its Roughness tag) under the seed's sky."""
    d = tmp_path_factory.mktemp("seed_tone")
    (d / "s.obj").write_text(quads_obj([("floor", [(-8, -8, 0), (8, -8, 0), (8, 8, 0), (-8, 8, 0)])],
                                       spheres=[("ball", (0.0, 0.0, 1.0), 1.0)]))
    (d / "s.mtl").write_text(material("floor", Kd=(0.6, 0.6, 0.6), Roughness=1)
                             + material("ball", Kd=(0.8, 0.3, 0.2), Roughness=1))
    return ["-obj", str(d / "s.obj"), "-mtl", str(d / "s.mtl"), "-cam", "0", "-7", "2", "0", "1", "-0.2", "50", "7",
            "0"]


# --- the curve, against its defining numbers ----------------------------------------------------------

def test_filmic_curve_meets_its_published_numbers():
    grey = 0.18
    assert filmic_curve(np.array(grey)) == pytest.approx(0.5, abs=1e-12)           # middle grey at half
    assert filmic_curve(np.array(grey * 2.0 ** -10)) == pytest.approx(0.0, abs=1e-12)   # 10 stops below: black
    assert filmic_curve(np.array(grey * 2.0 ** 6.5)) == pytest.approx(1.0, abs=1e-12)   # 6.5 stops above: white
    assert filmic_curve(np.array([1e-9, 0.0, -1.0, np.nan])).tolist() == [0.0] * 4
    assert filmic_curve(np.array([17.0, 1e9])).tolist() == [1.0, 1.0]
    # the slope at middle grey, per unit of the log-encoded range (16.5 stops), is sRGB's there:
    # d/dt srgb(0.18 * 2^(16.5 t)) = 1.055 / 2.4 * x^(1/2.4) * ln 2 * 16.5 at x = 0.18
    srgb_slope = 1.055 / 2.4 * grey ** (1 / 2.4) * np.log(2) * 16.5
    h = 1e-6
    up = (filmic_curve(np.array(grey * 2 ** (16.5 * h))) - 0.5) / h
    down = (0.5 - filmic_curve(np.array(grey * 2 ** (-16.5 * h)))) / h
    assert up == pytest.approx(srgb_slope, rel=1e-4) and down == pytest.approx(srgb_slope, rel=1e-4)  # no kink
    x = grey * 2.0 ** np.linspace(-12, 8, 4001)
    y = filmic_curve(x)
    assert np.all(np.diff(y) >= 0) and np.all(np.diff(y)[(x[1:] > grey * 2 ** -10) & (x[:-1] < 16.2)] > 0)


def test_filmic_keeps_highlights_that_srgb_and_the_seed_curve_push_to_white():
    bright = np.array([[[2.0, 4.0, 8.0]]], np.float32)             # 3.5 to 5.5 stops over middle grey
    assert tonemap_srgb(bright).tolist() == [[[255, 255, 255]]]
    assert tonemap_filmic(bright).max() < 250 and np.all(np.diff(tonemap_filmic(bright)[0, 0].astype(int)) > 5)
    assert tonemap_filmic(bright).max() < tonemap_seed(bright).max()


# --- the rule, through the command line ---------------------------------------------------------------

def test_a_standard_file_gets_the_filmic_curve_and_says_so(tmp_path, bunny):
    said = cli(["-obj", bunny, *SIZE, "--no-denoise", "-out", str(tmp_path / "a.png")])
    cli(["-obj", bunny, *SIZE, "-out", str(tmp_path / "a.npy")])
    assert "tone map: filmic" in said and "--tonemap seed" in said
    png = np.asarray(Image.open(tmp_path / "a.png").convert("RGB"))
    assert np.array_equal(png, tonemap_filmic(np.load(tmp_path / "a.npy")))
    chosen = cli(["-obj", bunny, *SIZE, "--no-denoise", "--tonemap", "seed", "-out", str(tmp_path / "b.png")])
    assert "tone map" not in chosen
    assert np.array_equal(np.asarray(Image.open(tmp_path / "b.png").convert("RGB")),
                          tonemap_seed(np.load(tmp_path / "a.npy")))


def test_the_seeds_dialect_keeps_the_seeds_curve_and_is_never_denoised(tmp_path, seed_file, monkeypatch):
    calls = fake_denoiser(monkeypatch)
    said = cli([*seed_file, *SIZE, "-out", str(tmp_path / "s.png")])
    cli([*seed_file, *SIZE, "-out", str(tmp_path / "s.npy")])
    assert "tone map" not in said and "denoised" not in said and not calls
    png = np.asarray(Image.open(tmp_path / "s.png").convert("RGB"))
    assert np.array_equal(png, tonemap_seed(np.load(tmp_path / "s.npy")))


def test_a_sunlit_bare_model_keeps_its_highlights_below_white(tmp_path, bunny):
    """Nearly white: within 10% of the curve's white (>= 230 of 255). A sun of 16 (a bright day: the
    sunlit ground 1.9, 3.4 stops over middle grey) on a bare model; one render, the curves applied to
    the same linear image. Measured: the seed's curve 87% nearly white, filmic 2.6%, sRGB 89% at 255."""
    cli(["-obj", bunny, *SUN, "--sun-color", "16", "16", "16", "-res", "64", "48", "-sr", "4",
         "-out", str(tmp_path / "sun.npy")])
    image = np.load(tmp_path / "sun.npy")
    white = lambda rgb, level=230: float((rgb.max(axis=2) >= level).mean())          # noqa: E731
    seed, filmic = white(tonemap_seed(image)), white(tonemap_filmic(image))
    assert seed > 0.5, seed                       # the seed's curve: the sunlit ground goes white
    assert white(tonemap_srgb(image), 255) > 0.5  # and sRGB clips it
    assert filmic < 0.05, (filmic, seed)
    assert white(tonemap_filmic(image), 250) == 0.0


# --- the denoiser at the defaults ---------------------------------------------------------------------

def fake_denoiser(monkeypatch) -> list:
    """pyoidn stood in for (available, and ``denoise`` records its call and returns the colour)."""
    from warp_spt.rendering import denoise as dn

    calls: list = []

    def denoise(color, albedo=None, normal=None):
        assert albedo.shape == normal.shape == color.shape        # the feature buffers come along
        calls.append(color.shape)
        return np.asarray(color, np.float32)

    monkeypatch.setattr(dn, "available", lambda: True)
    monkeypatch.setattr(dn, "denoise", denoise)
    return calls


def test_the_first_image_is_denoised_when_the_denoiser_is_installed(tmp_path, bunny, monkeypatch):
    calls = fake_denoiser(monkeypatch)
    said = cli(["-obj", bunny, *SIZE, "-out", str(tmp_path / "d.png")])
    assert calls == [(36, 48, 3)]
    line = [s for s in said.splitlines() if "denoised" in s]
    assert len(line) == 1 and "--no-denoise" in line[0]
    for argv in (["--no-denoise", "-out", str(tmp_path / "n.png")],      # asked not to
                 ["-out", str(tmp_path / "n.npy")]):                      # a linear output: the render's own
        said = cli(["-obj", bunny, *SIZE, *argv])
        assert calls == [(36, 48, 3)] and "denoised" not in said


def test_without_the_denoiser_the_first_image_renders_as_before(tmp_path, bunny, monkeypatch):
    from warp_spt.rendering import denoise as dn

    monkeypatch.setattr(dn, "available", lambda: False)
    said = cli(["-obj", bunny, *SIZE, "-out", str(tmp_path / "p.png")])
    hint = [s for s in said.splitlines() if "not denoised" in s]        # one line naming the extra
    assert len(hint) == 1 and 'pip install ".[denoise]"' in hint[0] and "error:" not in said
    for argv in (["--no-denoise", "-out", str(tmp_path / "n.png")], ["-out", str(tmp_path / "n.npy")]):
        assert "denoised" not in cli(["-obj", bunny, *SIZE, *argv])


def test_opendenoise_brings_a_16_spp_first_image_close_to_the_reference(tmp_path, bunny):
    """With pyoidn itself: the denoised 16-spp image's RMSE against a 256-spp reference is well below
    the raw 16-spp image's (benchmarks/bench_first_image.py measures it at a larger size: 0.27 times at
    192x144). At 48x36 it is not: the denoiser blurs edges that make up most of so small an image."""
    from warp_spt.rendering import denoise as dn

    if not dn.available():
        pytest.skip("pyoidn is not installed (extra [denoise])")
    size = ["-res", "96", "72"]       # a reference with samples of its own (another seed), not the 16's prefix
    cli(["-obj", bunny, *size, "-sr", "256", "--seed", "7", "-out", str(tmp_path / "ref.npy")])
    cli(["-obj", bunny, *size, "-sr", "16", "-out", str(tmp_path / "raw.npy")])
    cli(["-obj", bunny, *size, "-sr", "16", "--denoise", "-out", str(tmp_path / "den.npy")])
    ref = np.load(tmp_path / "ref.npy")
    rmse = {k: float(np.sqrt(np.mean((np.load(tmp_path / f"{k}.npy") - ref) ** 2))) for k in ("raw", "den")}
    assert rmse["den"] < 0.6 * rmse["raw"], rmse


def test_the_live_view_shows_every_curve():
    """warp_spt.notebook's PNG goes through the one display transform (filmic was the seed's there)."""
    from warp_spt.notebook import _png

    image = np.array([[[0.05, 0.18, 2.0]]], np.float32)
    for curve, mapping in (("filmic", tonemap_filmic), ("seed", tonemap_seed), ("srgb", tonemap_srgb)):
        assert np.array_equal(np.asarray(Image.open(io.BytesIO(_png(image, curve, 1))).convert("RGB")),
                              mapping(image))
