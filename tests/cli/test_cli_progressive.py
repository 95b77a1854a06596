"""The CLI's error, budget and adaptive flags (issue 9): maps, the error line, --save-partial on SIGINT."""

from __future__ import annotations

import io
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from warp_spt.cli.common import process_start
from warp_spt.cli.main import main
from warp_spt.cli.maps import LEGEND_MIN_WIDTH, false_colour, with_legend
from warp_spt.cli.options import parse_args
from warp_spt.cli.progressive import EXIT_SECONDS, finish_seconds
from warp_spt.images.files import load_image

from tests.support.scenes import material
from tests.support.stability_scenes import quads_obj

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def lit_files(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli_prog")
    (d / "s.obj").write_text(quads_obj([("floor", [(-8, -8, 0), (8, -8, 0), (8, 8, 0), (-8, 8, 0)])],
                                       spheres=[("ball", (0.0, 0.0, 1.0), 1.0)]))
    (d / "s.mtl").write_text(material("floor", Kd=(0.6, 0.6, 0.6), Roughness=1)
                             + material("ball", Kd=(0.8, 0.3, 0.2), Roughness=1))
    return ["-obj", str(d / "s.obj"), "-mtl", str(d / "s.mtl"), "-cam", "0", "-7", "2", "0", "1", "-0.2", "50", "7", "0",
            "--sky-color", "1", "1", "1", "-depth", "3"]


def test_flags_parse_and_validate():
    o = parse_args(["--time-budget", "2.5", "--target-error", "1%", "--adaptive", "--min-spp", "8",
                    "--error-map", "e.png", "--spp-map", "s.npy", "--progressive", "p.png", "--save-partial"])
    b = o.budget
    assert (b.time_budget, b.target_error, b.adaptive, b.min_spp, b.save_partial) == (2.5, 0.01, True, 8, True)
    assert b.active and not b.spp_given and not parse_args([]).budget.active
    for bad in (["--time-budget", "0"], ["--target-error", "-1"], ["--error-map", "e.jpg"], ["--min-spp", "0"],
                ["--progressive", "p.txt"], ["--adaptive", "--adaptive-metric", "mse"]):
        with pytest.raises(Exception):
            parse_args(bad)
    assert main(["--time-budget", "nan"]) == 2
    assert parse_args(["--adaptive", "--adaptive-metric", "rmse"]).budget.adaptive_metric == "rmse"
    assert parse_args(["--adaptive"]).budget.adaptive_metric is None      # the API's default applies
    assert main(["--adaptive-metric", "rmse"]) == 2                       # needs --adaptive


def test_budgeted_render_writes_image_maps_and_the_error_line(tmp_path, lit_files, capsys):
    out, err_png, err_npy, spp_png = (tmp_path / n for n in ("o.png", "e.png", "e.npy", "s.png"))
    args = lit_files + ["-res", "16", "12", "-sr", "40", "--adaptive", "--min-spp", "16", "--target-error", "2%"]
    assert main(args + ["--error-map", str(err_png), "--spp-map", str(spp_png), "-out", str(out)]) == 0
    log = capsys.readouterr().err
    assert "estimated relative error of the image:" in log and "pass 1: 2 spp" in log
    assert load_image(out).shape == (12, 16, 3)
    for png in (err_png, spp_png):           # the map in the top-left corner, its legend below
        h, w, _ = load_image(png).shape
        assert h > 12 + 20 and w == LEGEND_MIN_WIDTH
    assert main(args + ["--error-map", str(err_npy), "--quiet", "-out", str(tmp_path / "o.npy")]) == 0
    se, img = np.load(err_npy), np.load(tmp_path / "o.npy")
    assert se.shape == img.shape and np.all(se[np.isfinite(se)] >= 0)
    assert capsys.readouterr().err == ""


def test_the_start_up_line_says_what_a_budget_renders(tmp_path, lit_files, capsys):
    """Budget runs announced "16 spp" (the -sr default) and rendered 18 to 853."""
    assert parse_args([]).budget.samples(16) == "16 spp"
    assert parse_args(["--time-budget", "10"]).budget.samples(16) == "until --time-budget 10 s"
    assert parse_args(["--target-error", "1%", "-sr", "64"]).budget.samples(64) == \
        "until --target-error 1% (at most 64 spp)"
    assert parse_args(["--target-error", "0.025", "--time-budget", "5"]).budget.samples(16) == \
        "until --target-error 2.5% or --time-budget 5 s"
    assert parse_args(["--adaptive"]).budget.samples(16) == "up to 16 spp per pixel (--adaptive)"
    out = tmp_path / "o.png"
    assert main(lit_files + ["-res", "8", "6", "--target-error", "20%", "-out", str(out)]) == 0
    start = capsys.readouterr().err.splitlines()[0]
    assert "rendering 8x6, until --target-error 20%, depth 3" in start and "16 spp" not in start


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_target_error_shows_one_updating_line_with_the_time_to_go(tmp_path, lit_files, monkeypatch):
    """On a terminal the passes rewrite one line (they were dozens of "pass N" lines with no end in sight)."""
    monkeypatch.setattr(sys, "stderr", _Terminal())
    assert main(lit_files + ["-res", "16", "12", "--target-error", "4%", "-out", str(tmp_path / "o.png")]) == 0
    lines = sys.stderr.getvalue().split("\n")
    progress = [line for line in lines if "pass 1:" in line]
    assert len(progress) == 1 and progress[0].count("\r") == progress[0].count("pass ") >= 3
    assert "(target 4.00%), about" in progress[0] and "to go" in progress[0]
    assert lines[lines.index(progress[0]) + 1].startswith("warp-spt: wrote ")     # the line was ended


def test_the_time_to_go_follows_the_one_over_sqrt_spp_law():
    from types import SimpleNamespace

    from warp_spt.cli.progressive import PassLine, pass_status, time_to_go
    from warp_spt.rendering.result import RenderStats

    stats = RenderStats(passes=4, seconds=3.0, setup_seconds=1.0)         # 16 spp in 2 s: 0.125 s per spp
    res = SimpleNamespace(stats=stats, spp=np.full((2, 2), 16), relative_error=0.02)
    assert time_to_go(res, 0.01, None, None) == (6.0, "--target-error")   # 16 x (2% / 1%)^2 = 64 spp: 48 more
    assert time_to_go(res, 0.01, None, 5.0) == (2.0, "--time-budget")    # the budget ends it first
    assert time_to_go(res, None, 24, None) == (1.0, "-sr 24")
    assert pass_status(res, 0.01, None, None) == "pass 4: 16 spp, 3.0 s, error 2.00% (target 1.00%), about 6.0 s to go"
    assert pass_status(res, 0.01, None, 5.0).endswith("about 2.0 s to go (--time-budget)")
    said, log = [], io.StringIO()
    line = PassLine(said.append, log, live=True)          # not a terminal: a line per pass, as --verbose
    line.show("a")
    line.show("b")
    line.close()
    assert said == ["a", "b"] and log.getvalue() == ""
    term = _Terminal()
    line = PassLine(said.append, term, live=True)
    line.show("a")
    line.show("b")
    line.close()
    assert term.getvalue() == "\rwarp-spt: a\x1b[K\rwarp-spt: b\x1b[K\n" and said == ["a", "b"]


def test_false_colour_ends():
    c = false_colour(np.array([[0.0, 1.0, 2.0]]))
    assert c[0, 0].tolist() == [0, 0, 0] and c[0, 2].tolist() == [255, 255, 255]
    stops = false_colour(np.array([[0.0, 0.25, 0.5, 0.75, 1.0]]), 1.0)[0].tolist()
    assert stops == [[0, 0, 0], [0, 0, 255], [255, 0, 0], [255, 255, 0], [255, 255, 255]]   # docs/error.md


def test_a_png_map_has_a_legend_with_the_values_of_its_colours():
    from warp_spt.cli.maps import BAR_HEIGHT, PAD, tick_labels

    img8 = false_colour(np.linspace(0.0, 1.0, 300 * 20).reshape(20, 300))
    out = with_legend(img8, 0.112, "relative error", 100.0, "%")
    assert out.shape[1] == 300 and out.shape[0] > 20 + BAR_HEIGHT and np.array_equal(out[:20], img8)
    # the colour bar: rows of the strip black at its left end and white at its right
    rows = [r for r in out[20:] if r[PAD].tolist() == [0, 0, 0] and r[-PAD - 1].tolist() == [255, 255, 255]]
    assert len(rows) == BAR_HEIGHT
    assert tick_labels(11.2, "%") == ["0.0%", "2.8%", "5.6%", "8.4%", "11.2%"]
    assert tick_labels(16) == ["0", "4", "8", "12", "16"]
    narrow = with_legend(img8[:3, :5], 1.0, "samples per pixel")
    assert narrow.shape[1] == LEGEND_MIN_WIDTH and np.array_equal(narrow[:3, :5], img8[:3, :5])


def test_process_start_is_in_the_past():
    assert 0.0 <= time.perf_counter() - process_start() < 24 * 3600


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT to a child process is POSIX")
def test_save_partial_leaves_a_valid_image_on_sigint(tmp_path, lit_files):
    # A render that would take minutes; interrupt it once the first progressive image exists.
    out, prog = tmp_path / "partial.png", tmp_path / "progress.png"
    env = dict(os.environ, PYTHONPATH=str(REPO))
    cmd = [sys.executable, "-m", "warp_spt", *lit_files, "-res", "32", "24", "-sr", "1000000", "--threads", "1",
           "--save-partial", "--progressive", str(prog), "-out", str(out)]
    # A runner started in the background (nohup, &) ignores SIGINT, and so would the child: give it
    # the default disposition back, so that Python installs its KeyboardInterrupt handler.
    proc = subprocess.Popen(cmd, env=env, stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    try:
        deadline = time.monotonic() + 120
        while not prog.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.05)
        assert prog.exists(), "no pass finished"
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, err
    assert "saved the partial image" in err and "Traceback" not in err
    with Image.open(out) as im:
        im.load()
        assert im.size == (32, 24)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["partial.png", "progress.png"]   # no temp files


def test_a_partial_save_names_the_pixels_without_samples_and_a_plausible_rate(tmp_path, lit_files, monkeypatch,
                                                                              capsys):
    """Ctrl-C in the first pass of a 128 x 128 render (4 launches of 4,096 pixels per batch), after 3
    launches: the image is saved, its unsampled pixels counted, and the rate is the samples rendered
    over the time spent (it was divided by the finished passes' time, 0 here: "749568000.00 M samples/s")."""
    import re

    from warp_spt.rendering import progressive

    launched, real = [], progressive._Driver._launch

    def launch(self, *args, **kw):
        real(self, *args, **kw)
        launched.append(args)
        if len(launched) == 3:
            os.kill(os.getpid(), signal.SIGINT)

    monkeypatch.setattr(progressive._Driver, "_launch", launch)
    out = tmp_path / "partial.png"
    assert main(lit_files + ["-res", "128", "128", "--threads", "1", "--save-partial", "-out", str(out)]) == 130
    err = capsys.readouterr().err
    assert "4,096 of 16,384 pixels have no samples yet (black)" in err and len(launched) == 3
    rate = float(re.search(r"([0-9.e+-]+) M samples/s", err).group(1))
    assert 0 < rate < 1000               # a CPU path tracer renders millions of samples a second, not 1e15
    assert load_image(out).shape == (128, 128, 3)


def test_denoise_is_explicit_and_says_so(tmp_path, lit_files, capsys, monkeypatch):
    from warp_spt.rendering import denoise as dn

    out = tmp_path / "d.npy"
    args = lit_files + ["-res", "16", "12", "-sr", "8", "--denoise", "-out", str(out)]
    if dn.available():
        assert main(args) == 0
        assert "denoised with Intel Open Image Denoise" in capsys.readouterr().err
        assert np.load(out).shape == (12, 16, 3)
    monkeypatch.setattr(dn, "available", lambda: False)
    assert main(args) == 1
    err = capsys.readouterr().err        # one line, before loading: it was "internal error: RuntimeError"
    assert err.count("\n") == 1 and err.startswith("warp-spt: error: --denoise needs Intel Open Image Denoise")
    assert 'pip install ".[denoise]"' in err and '"warp-spt[denoise]"' in err


def fake_denoiser(monkeypatch, seconds_per_pixel: float) -> list:
    """pyoidn stood in for: ``available()`` is True and ``denoise`` sleeps ``seconds_per_pixel`` per pixel,
    checks its inputs and returns the colour. Returns the list of image shapes it was called with."""
    from warp_spt.rendering import denoise as dn

    calls = []

    def denoise(color, albedo=None, normal=None):
        assert color.shape[2] == 3 and albedo.shape == normal.shape == color.shape
        calls.append(color.shape)
        time.sleep(seconds_per_pixel * color.shape[0] * color.shape[1])
        return np.asarray(color, np.float32)

    monkeypatch.setattr(dn, "available", lambda: True)
    monkeypatch.setattr(dn, "denoise", denoise)
    return calls


def test_the_save_reserve_counts_the_denoiser(tmp_path, monkeypatch):
    from warp_spt.rendering import denoise as dn

    monkeypatch.setattr(dn, "available", lambda: False)     # no pyoidn: the documented conservative figure
    assert dn.seconds(200, 100) == dn.SECONDS_FIXED + dn.SECONDS_PER_PIXEL * 20000
    calls = fake_denoiser(monkeypatch, 20e-6)               # pyoidn: measured on a probe, scaled per pixel
    est = dn.seconds(200, 100)
    assert calls == [(dn.PROBE_SIZE, dn.PROBE_SIZE, 3)] * 2 and est >= dn.FIRST_CALL_FACTOR * 20e-6 * 20000
    monkeypatch.setattr(dn, "seconds", lambda w, h: 1000.0 + w * h)
    assert finish_seconds(str(tmp_path / "o.png"), 200, 100, "seed", 1, denoise=True) >= 21000 + EXIT_SECONDS


def test_a_time_budget_leaves_room_for_the_denoiser(tmp_path, lit_files, monkeypatch):
    from warp_spt.rendering import aux_buffers, progressive

    calls = fake_denoiser(monkeypatch, 1e-3)     # 0.19 s for 16 x 12: more than saving a small PNG
    shape = (12, 16, 3)
    monkeypatch.setattr(aux_buffers, "feature_buffers", lambda *a, **k: (np.full(shape, 0.5, np.float32),
                                                                         np.zeros(shape, np.float32)))
    budgets, real = [], progressive.render_progressive

    def spy(*a, **kw):
        budgets.append(kw["time_budget"])
        return real(*a, **kw)

    monkeypatch.setattr(progressive, "render_progressive", spy)
    out = tmp_path / "d.npy"
    assert main(lit_files + ["-res", "16", "12", "--time-budget", "20", "--denoise", "-out", str(out)]) == 0
    assert calls[-1] == shape and np.load(out).shape == shape
    assert budgets[0] <= 20 - 1.6 * 1e-3 * 16 * 12      # the render's deadline leaves the denoiser its time


def test_denoiser_reduces_noise_on_a_smooth_image():
    from warp_spt.rendering import denoise as dn

    if not dn.available():
        pytest.skip("pyoidn is not installed (extra [denoise])")
    rng = np.random.default_rng(0)
    clean = np.tile(np.linspace(0.1, 1.0, 48, dtype=np.float32)[None, :, None], (48, 1, 3))
    noisy = np.clip(clean + rng.normal(0, 0.1, clean.shape), 0, None).astype(np.float32)
    out = dn.denoise(noisy)
    assert np.sqrt(np.mean((out - clean) ** 2)) < 0.5 * np.sqrt(np.mean((noisy - clean) ** 2))
    with pytest.raises(ValueError):
        dn.denoise(np.full((4, 4, 3), np.nan, np.float32))


def test_a_budget_shorter_than_start_up_says_so_in_one_line(tmp_path, lit_files, capsys):
    out = tmp_path / "o.png"
    assert main(lit_files + ["-res", "16", "12", "--time-budget", "0.001", "-out", str(out)]) == 0
    lines = [line for line in capsys.readouterr().err.splitlines() if "is less than start-up" in line]
    assert len(lines) == 1 and "first pass's 2 spp" in lines[0]
    assert load_image(out).shape == (12, 16, 3)


def test_finish_seconds_counts_every_output_and_the_exit(tmp_path):
    one = finish_seconds(str(tmp_path / "o.png"), 64, 48, "seed", 1)
    assert one >= EXIT_SECONDS and finish_seconds(str(tmp_path / "o.npy"), 64, 48, "seed", 3) >= EXIT_SECONDS
    assert not list(tmp_path.iterdir())           # measured in memory: nothing written
