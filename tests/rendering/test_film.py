"""Film accumulation and merging, the seed and sRGB tone maps, image files and atomic writes."""

from __future__ import annotations

import struct
from pathlib import Path

import numpy as np
import pytest

from warp_spt.images import files as film_mod
from warp_spt.images.files import (
    load_image,
    read_pfm,
    save_image,
    tonemap_seed,
    tonemap_srgb,
)
from warp_spt.rendering.film import Film

from tests.support.reference import literal_seed_search

# ------------------------------------------------------------------ seed tone map


SEED_SAMPLES = {0.01: 26, 0.1: 80, 0.25: 128, 0.5: 182, 0.64: 204, 0.7: 210, 1.0: 224, 1.5: 234,
                2.0: 240, 5.0: 250, 10.0: 252, 20.0: 254}


def test_seed_tonemap_sample_values():
    x = np.array(list(SEED_SAMPLES), dtype=np.float32)
    got = tonemap_seed(x.reshape(1, -1, 1).repeat(3, axis=2))
    assert got.dtype == np.uint8
    assert got[0, :, 0].tolist() == list(SEED_SAMPLES.values())
    assert (got[..., 0] == got[..., 1]).all() and (got[..., 1] == got[..., 2]).all()


def test_seed_tonemap_matches_literal_search():
    rng = np.random.default_rng(2)
    # many values, including every LUT entry and its float32 neighbours (the bracket boundaries)
    lut = film_mod.seed_lut()
    x = np.concatenate([rng.exponential(0.5, 3000), rng.uniform(-1, 40, 500), lut,
                        np.nextafter(lut, np.float32(np.inf)), np.nextafter(lut, np.float32(-np.inf))])
    x = x.astype(np.float32)
    got = tonemap_seed(x)
    want = np.array([literal_seed_search(v) for v in x])
    assert np.array_equal(got, want)


def test_seed_tonemap_range_nan_negative_monotone():
    x = np.array([np.nan, -np.inf, -5.0, -0.0, 0.0, 1e-12, 16.0, 16.5, 1e9, np.inf], dtype=np.float32)
    got = tonemap_seed(x)
    assert got.tolist() == [1, 1, 1, 1, 1, 1, 254, 254, 254, 254]
    assert got.tolist() == [literal_seed_search(v) for v in x]
    ramp = np.linspace(0, 40, 200_001, dtype=np.float32)
    out = tonemap_seed(ramp).astype(int)
    assert (np.diff(out) >= 0).all() and out.min() == 1 and out.max() == 254


def test_seed_tonemap_outputs_only_one_and_even_values():
    """The last midpoint of this search is always even (or 1); the seed's demo PNGs agree."""
    values = set(np.unique(tonemap_seed(np.linspace(-1, 40, 400_001, dtype=np.float32))).tolist())
    assert values == SEED_OUTPUT_VALUES


SEED_OUTPUT_VALUES = {1} | set(range(2, 255, 2))


@pytest.mark.parametrize("name", ["512p16s.png", "512p32s.png", "512p128s.png"])
def test_seed_demo_pngs_use_only_those_values(name):
    demo = Path(__file__).resolve().parents[2].parent / "shared" / "seed" / "demo" / name
    if not demo.exists():
        pytest.skip("seed demo images not available")
    assert set(np.unique(load_image(demo)).tolist()) <= SEED_OUTPUT_VALUES


# ------------------------------------------------------------------ sRGB


def test_srgb_known_values():
    x = np.array([0.0, 1.0, 0.0031308, 0.5, 2.0, -1.0, np.nan, 0.001, 0.25], dtype=np.float64)
    got = tonemap_srgb(x)
    # 0.0031308 * 12.92 * 255 = 10.31; 0.5 -> 1.055 * 0.5**(1/2.4) - 0.055 = 0.7354 -> 187.5 -> 188
    # 0.001 -> 12.92e-3 * 255 = 3.29 -> 3; 0.25 -> 0.5371 * 255 = 136.97 -> 137
    assert got.tolist() == [0, 255, 10, 188, 255, 0, 0, 3, 137]
    assert tonemap_srgb(np.array([0.25]), exposure=2.0).tolist() == [188]


# ------------------------------------------------------------------ files


def test_pfm_round_trip_and_orientation(tmp_path):
    img = np.arange(2 * 3 * 3, dtype=np.float32).reshape(2, 3, 3) - 4.5
    save_image(tmp_path / "a.pfm", img)
    raw = (tmp_path / "a.pfm").read_bytes()
    assert raw.startswith(b"PF\n3 2\n-1.0\n")
    body = np.frombuffer(raw[len(b"PF\n3 2\n-1.0\n"):], dtype="<f4").reshape(2, 3, 3)
    assert np.array_equal(body[0], img[1])                 # the file starts with the bottom row
    assert np.array_equal(read_pfm(tmp_path / "a.pfm"), img)


def test_read_hand_built_pfm(tmp_path):
    # 2 wide, 2 high, big-endian (positive scale), rows stored bottom first, single-space header
    bottom = [(1, 2, 3), (4, 5, 6)]
    top = [(7, 8, 9), (10, 11, 12)]
    data = b"".join(struct.pack(">3f", *px) for px in bottom + top)
    (tmp_path / "h.pfm").write_bytes(b"PF 2 2 1.0\n" + data)
    got = read_pfm(tmp_path / "h.pfm")
    assert got.dtype == np.float32 and got.shape == (2, 2, 3)
    assert got.tolist() == [[list(map(float, p)) for p in top], [list(map(float, p)) for p in bottom]]
    # greyscale "Pf", little-endian
    (tmp_path / "g.pfm").write_bytes(b"Pf\n1 2\n-1\n" + struct.pack("<2f", 0.25, 0.75))
    assert load_image(tmp_path / "g.pfm")[:, 0].tolist() == [[0.75] * 3, [0.25] * 3]


def test_read_pfm_rejects_garbage(tmp_path):
    (tmp_path / "t.pfm").write_bytes(b"PF\n4 4\n-1.0\n" + b"\0" * 10)
    with pytest.raises(ValueError, match="expected 192"):
        read_pfm(tmp_path / "t.pfm")
    (tmp_path / "m.pfm").write_bytes(b"P6\n1 1\n255\n\0\0\0")
    with pytest.raises(ValueError, match="not a PFM"):
        read_pfm(tmp_path / "m.pfm")


def test_npy_and_png_round_trip(tmp_path):
    rng = np.random.default_rng(0)
    img = rng.exponential(0.5, size=(5, 7, 3)).astype(np.float32)
    save_image(tmp_path / "a.npy", img)
    assert np.array_equal(load_image(tmp_path / "a.npy"), img)
    save_image(tmp_path / "a.png", img, tonemap="srgb")
    assert np.array_equal(load_image(tmp_path / "a.png"), tonemap_srgb(img))
    save_image(tmp_path / "b.png", img)
    assert np.array_equal(load_image(tmp_path / "b.png"), tonemap_seed(img))


def test_bad_extension_and_arguments(tmp_path):
    img = np.zeros((2, 2, 3), dtype=np.float32)
    with pytest.raises(ValueError, match=r"\.png, \.npy, \.pfm"):
        save_image(tmp_path / "a.gif", img)
    with pytest.raises(ValueError, match="tone map"):
        save_image(tmp_path / "a.png", img, tonemap="aces")
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        save_image(tmp_path / "a.npy", np.zeros((2, 2)))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("ext", [".pfm", ".npy", ".png"])
def test_atomic_write_failure_leaves_nothing(tmp_path, monkeypatch, ext):
    def failing_writer(f, data):
        f.write(b"partial data")
        raise RuntimeError("disk on fire")

    monkeypatch.setitem(film_mod._WRITERS, ext, failing_writer)
    img = np.ones((3, 4, 3), dtype=np.float32)
    with pytest.raises(RuntimeError, match="disk on fire"):
        save_image(tmp_path / f"new{ext}", img)
    assert list(tmp_path.iterdir()) == []                  # no output, no temporary file
    old = tmp_path / f"old{ext}"
    old.write_bytes(b"previous contents")
    with pytest.raises(RuntimeError):
        save_image(old, img)
    assert old.read_bytes() == b"previous contents"
    assert [p.name for p in tmp_path.iterdir()] == [old.name]


def test_atomic_write_replaces_existing(tmp_path):
    target = tmp_path / "x.npy"
    target.write_bytes(b"old")
    save_image(target, np.full((1, 1, 3), 2.0))
    assert load_image(target).tolist() == [[[2.0, 2.0, 2.0]]]
    assert [p.name for p in tmp_path.iterdir()] == ["x.npy"]


# ------------------------------------------------------------------ film


def sample_blocks(rng, n_blocks: int, shape=(4, 5, 3)):
    """Per-block radiance sums and sample counts, as render passes over sample ranges produce."""
    return [(rng.exponential(1.0, size=shape) * k, k) for k in rng.integers(1, 5, size=n_blocks)]


def test_split_films_merge_exactly(tmp_path):
    """Two machines render sample ranges [0, 3) and [3, 6) blocks; merging equals one film exactly."""
    blocks = sample_blocks(np.random.default_rng(4), 6)
    machines = []
    for part in (blocks[:3], blocks[3:]):
        f = Film.empty(4, 5)
        for s, n in part:
            f.accumulate(s, n)
        f.save(tmp_path / f"part{len(machines)}.npz")      # shipped as files: sums stay exact
        machines.append(tmp_path / f"part{len(machines)}.npz")
    merged = Film.load(machines[0])
    merged.add(Film.load(machines[1]))
    # one film accumulating the same float64 additions in the same order (sum per range, then merge)
    (a0, n0), (a1, n1), (a2, n2), (b0, m0), (b1, m1), (b2, m2) = blocks
    expected = (np.zeros((4, 5, 3)) + a0 + a1 + a2) + (np.zeros((4, 5, 3)) + b0 + b1 + b2)
    assert merged.spp == n0 + n1 + n2 + m0 + m1 + m2
    assert np.array_equal(merged.sum, expected)
    assert np.array_equal(merged.image(), (expected / merged.spp).astype(np.float32))


def test_film_validation(tmp_path):
    f = Film.empty(2, 3)
    with pytest.raises(ValueError, match="no samples"):
        f.image()
    with pytest.raises(ValueError, match="shape"):
        f.add(Film.empty(3, 2))
    with pytest.raises(ValueError, match="shape"):
        f.accumulate(np.zeros((2, 3)), 1)
    with pytest.raises(ValueError, match="spp"):
        Film(np.zeros((2, 3, 3)), -1)
    with pytest.raises(ValueError, match=r"\(H, W, 3\)"):
        Film(np.zeros((2, 3)), 1)
    assert Film(np.ones((1, 2, 3), dtype=np.float32), 2).image().tolist() == [[[0.5] * 3] * 2]
    np.savez(tmp_path / "bad.npz", something=np.zeros(3))
    with pytest.raises(ValueError, match="not a film file"):
        Film.load(tmp_path / "bad.npz")
