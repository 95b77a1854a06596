"""examples/inverse_lighting.py in its reduced mode (16 x 16 pixels, 8 spp, 100 iterations):
gradient descent recovers the environment's tint and the sun's direction from a rendered image.

Tolerances from the run's own noise: over seeds 0..4 the recovered tint was within 2.1% of the true
one per channel (errors' spread about 0.8%) and the sun within 0.39 degrees; 5% and 1.5 degrees are
about four times those, while the start (tint 1 1 1, the sun overhead) is 122% and 51 degrees off."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]


def test_inverse_lighting_recovers_the_tint_and_the_sun(monkeypatch):
    spec = importlib.util.spec_from_file_location("inverse_lighting", ROOT / "examples" / "inverse_lighting.py")
    mod = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "inverse_lighting", mod)      # its dataclass looks its module up
    spec.loader.exec_module(mod)
    r = mod.recover(quick=True)
    assert r.losses[-1] < 0.05 * r.losses[0]
    assert np.all(np.abs(r.tint / mod.TRUE_TINT - 1) < 0.05), r.tint
    assert r.sun_error_deg < 1.5, (r.sun, r.sun_error_deg)
