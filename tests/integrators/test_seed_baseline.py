"""The seed integrator with the independent sampler reproduces the pre-restructure renderer bit for bit.

The expected images were rendered by commit 2f89ff6 (before integrators, samplers and light sampling
existed) with tests/data/make_seed_baseline.py; see its docstring for the command.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from warp_spt import render

DATA = Path(__file__).parents[1] / "data"
_spec = importlib.util.spec_from_file_location("make_seed_baseline", DATA / "make_seed_baseline.py")
baseline = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(baseline)


@pytest.fixture(scope="module")
def cases(tmp_path_factory):
    return list(baseline.cases(tmp_path_factory.mktemp("baseline")))


@pytest.mark.parametrize("name", ["demo", "demo_bilinear", "spheres"])
def test_seed_independent_is_bit_identical_to_the_old_renderer(cases, name):
    (_, scene, cam, kw), = [c for c in cases if c[0] == name]
    expected = np.load(DATA / f"seed_baseline_{name}.npy")
    img = render(scene, cam, integrator="seed", sampler="independent", **kw)
    assert img.dtype == expected.dtype and img.shape == expected.shape
    assert np.array_equal(img, expected), f"max |diff| {np.abs(img - expected).max()}"
