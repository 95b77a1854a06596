"""``warp-spt convergence``: documented CSV/JSON columns, slope fit and its warning, plot, clear errors."""

from __future__ import annotations

import csv
import json
import sys

import numpy as np
import pytest

from warp_spt.cli.main import main
from warp_spt.rendering.convergence import (
    COLUMNS,
    MAX_REPEATS,
    default_configs,
    fit_slope,
    levels,
    parse_config,
    timed,
)

from tests.cli.test_cli_progressive import lit_files  # noqa: F401  (fixture)


def test_config_names():
    from warp_spt.rendering.settings import DEFAULT_INTEGRATOR, DEFAULT_SAMPLER

    assert parse_config("nee/sobol+adaptive") == ("nee", "sobol", {"adaptive"})
    assert parse_config("uniform") == (DEFAULT_INTEGRATOR, DEFAULT_SAMPLER, set())
    assert parse_config("denoised") == (DEFAULT_INTEGRATOR, DEFAULT_SAMPLER, {"denoised"})
    assert default_configs() == ["nee/independent", "nee/sobol", "nee/sobol-affine",
                                 "seed/independent", "seed/sobol", "seed/sobol-affine",
                                 f"{DEFAULT_INTEGRATOR}/{DEFAULT_SAMPLER}+adaptive"]
    for bad in ("nee", "nee/halton", "fancy/sobol", "seed/sobol+blurred"):
        with pytest.raises(ValueError):
            parse_config(bad)


def test_levels():
    assert levels(1) == [1] and levels(8) == [1, 2, 4, 8] and levels(12) == [1, 2, 4, 8, 12]


def test_slope_fit_and_warning():
    spp = np.array([1, 2, 4, 8, 16, 32])
    ok = fit_slope(spp, 0.3 * spp**-0.5)
    assert ok.slope == pytest.approx(-0.5) and ok.warning is None
    biased = fit_slope(spp, np.sqrt(0.09 / spp + 0.1**2))        # a bias of 0.1 flattens the curve
    assert biased.slope > -0.35 and "bias" in biased.warning
    assert fit_slope([1], [0.1]).warning


def test_short_renders_are_timed_over_repeats():
    """A render of a few ms is as long as the scheduler's noise: it is repeated and the mean taken."""
    calls = []
    value, seconds = timed(lambda: calls.append(1) or len(calls))
    assert value == 1 and 1 < len(calls) <= MAX_REPEATS and seconds > 0


def test_report_writes_the_documented_columns(tmp_path, lit_files, capsys):  # noqa: F811
    prefix = tmp_path / "conv"
    # Two configurations of one kernel (compiling every integrator x sampler would dominate CI time);
    # the default set's names are checked in test_config_names.
    configs = ["seed/independent", "seed/independent+adaptive"]
    args = ["convergence", *lit_files, "-res", "8", "6", "--max-spp", "8", "--reference-spp", "256",
            "--configs", ",".join(configs), "--prefix", str(prefix)]
    assert main(args) == 0
    with open(f"{prefix}.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    assert tuple(rows[0].keys()) == COLUMNS
    assert [(r["config"], int(r["spp"])) for r in rows] == [(c, s) for s in (1, 2, 4, 8) for c in configs]
    assert {(r["integrator"], r["sampler"]) for r in rows} == {("seed", "independent")}
    for r in rows:
        assert float(r["rmse"]) <= float(r["rmse_raw"]) and float(r["seconds"]) > 0
    doc = json.loads((tmp_path / "conv.json").read_text())
    assert doc["columns"] == list(COLUMNS) and len(doc["rows"]) == 8
    assert set(doc["fits"]) == set(configs) and doc["reference"]["spp"] == 256
    assert (tmp_path / "conv.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "log-log slope" in capsys.readouterr().err


def test_reference_from_a_file_and_a_size_mismatch(tmp_path, lit_files, capsys):  # noqa: F811
    ref = tmp_path / "ref.npy"
    np.save(ref, np.full((6, 8, 3), 0.5, np.float32))
    base = ["convergence", *lit_files, "--max-spp", "2", "--no-plot", "--quiet", "--configs", "uniform",
            "--reference", str(ref), "--prefix", str(tmp_path / "c")]
    assert main(base + ["-res", "8", "6"]) == 0
    doc = json.loads((tmp_path / "c.json").read_text())
    assert doc["reference"] == {"source": "file"} and len(doc["rows"]) == 2
    assert main(base + ["-res", "9", "6"]) == 1
    assert "reference is 8x6, the render 9x6" in capsys.readouterr().err


def test_missing_matplotlib_is_one_clear_line(tmp_path, lit_files, monkeypatch, capsys):  # noqa: F811
    monkeypatch.setitem(sys.modules, "matplotlib", None)       # makes `import matplotlib` fail
    assert main(["convergence", *lit_files, "-res", "4", "4", "--max-spp", "1", "--prefix", str(tmp_path / "c")]) == 1
    err = capsys.readouterr().err
    assert "warp-spt[plot]" in err and "--no-plot" in err and "Traceback" not in err
    assert main(["convergence", "--configs", "fancy"]) == 2
