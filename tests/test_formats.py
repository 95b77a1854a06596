"""EXR (optional openexr package) and JPEG output (issue 10)."""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.io.images import load_image, save_image, tonemap_srgb


def test_exr_holds_linear_float32_exactly(tmp_path):
    pytest.importorskip("OpenEXR")
    rng = np.random.default_rng(3)
    img = (rng.random((7, 5, 3)) * 1e3).astype(np.float32)
    img[0, 0] = (0.0, 1e-30, 6e4)
    save_image(tmp_path / "a.exr", img)
    import OpenEXR
    with OpenEXR.File(str(tmp_path / "a.exr")) as f:          # read back by the library, not by our reader
        assert set(f.channels()) == {"RGB"} and f.channels()["RGB"].pixels.dtype == np.float32
    assert np.array_equal(load_image(tmp_path / "a.exr"), img)
    assert [p.name for p in tmp_path.iterdir()] == ["a.exr"]      # no temporary file left behind


def test_jpeg_is_the_tone_mapped_image_up_to_compression(tmp_path):
    ramp = np.linspace(0, 1, 64, dtype=np.float32)
    img = np.stack(np.broadcast_arrays(ramp[None, :], ramp[:, None], 0.5 * np.ones((64, 64), np.float32)), -1)
    save_image(tmp_path / "a.jpg", img, tonemap="srgb")
    got = load_image(tmp_path / "a.jpg").astype(int)
    assert got.shape == (64, 64, 3) and np.abs(got - tonemap_srgb(img).astype(int)).mean() < 2.0
