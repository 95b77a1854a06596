"""Images of a fixed set of commands and API calls, bit for bit as the commit before the restructure
made them (issue 20). The hashes were made from that commit by tests/data/make_house_hashes.py,
which this test imports for the cases, so old and new run exactly the same calls.

One case is numbers, not a hash: the sky's gradient, which the lights' restructure sums in another
order (the sky's colours became a device array aliased like a material colour): it agrees with the
old commit to 1e-6 relative (4.6e-7 measured); the image and the other gradients stay bit-identical.

Since then, issue 22 changed the studio look on purpose (CHANGED below) and a bare model's
defaults (the bare-model case passes flags that ask for the old ones, make_house_hashes.py).

The two seams fixed on purpose (--frames/--workers rendering what a single render renders, and
positions kept in float64 until recentring) change no image here: their own tests cover them
(tests/test_seams.py).
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

DATA = Path(__file__).parent / "data"
_spec = importlib.util.spec_from_file_location("make_house_hashes", DATA / "make_house_hashes.py")
hashes = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(hashes)
EXPECTED = json.loads((DATA / "house_hashes.json").read_text())


# Images changed on purpose since that commit: why, and the hash of the new image (made by this
# file's case on the commit that changed it, after the independent checks named).
CHANGED = {
    "cli_bare_model_studio": (
        "issue 22: the studio's levels (sky 0.2, ground 0.4, key light 2.0: a white model is not washed "
        "out, the backdrop is darker than the clay); checked by tests/test_first_image.py",
        "d861d4b8b89f153a349beb69b85d9beb49c1c036d2af2c647a0a8d522c3448da"),
}


@pytest.mark.parametrize("name,fn", hashes.cli_cases(), ids=[n for n, _ in hashes.cli_cases()])
def test_cli_images_unchanged(name, fn, tmp_path):
    got = fn(tmp_path)
    if got is None:
        pytest.skip("needs ../shared/seed/demo")
    if name in CHANGED:
        assert got != EXPECTED[name] and got == CHANGED[name][1], f"{name}: the image changed ({CHANGED[name][0]})"
        return
    assert got == EXPECTED[name], f"{name}: the image changed"


@pytest.mark.parametrize("name,fn", hashes.api_cases(), ids=[n for n, _ in hashes.api_cases()])
def test_api_images_unchanged(name, fn):
    if name not in EXPECTED:     # the cases cover every registered integrator: one added since has no old image
        pytest.skip(f"{name}: a plugin newer than the hashes (no image to keep)")
    if name == "api_cluster":
        pytest.importorskip("dask.distributed")
    got = fn()
    if got is None:
        pytest.skip("needs dask.distributed")
    if isinstance(EXPECTED[name], list):     # numbers whose summation order changed on purpose
        np.testing.assert_allclose(got, EXPECTED[name], rtol=1e-6, err_msg=name)
        return
    assert got == EXPECTED[name], f"{name}: the image changed"
