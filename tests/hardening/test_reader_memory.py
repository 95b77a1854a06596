"""Memory bombs in the readers (issue 42, item 4): each reader's peak memory against a stated budget
in bytes per input (a subprocess's peak RSS, or tracemalloc), sizes checked from headers before
anything is allocated, compressed data inflated within a bound, only regular files read."""

from __future__ import annotations

import os
import struct
import subprocess
import sys
import tracemalloc
import zlib

import numpy as np
import pytest

from warp_spt.images.environment import READ_BYTES_PER_TEXEL, read_environment_image
from warp_spt.scene.errors import SceneError
from warp_spt.scene.media import MAX_GRID_BYTES, Medium

from tests.support.format_files import FakeBlosc, blosc_grid

# The peak resident size of reading one map, in a process of its own: /proc's high-water mark reset
# first (ru_maxrss would carry the parent's across fork and exec), after the imports
PEAK = """
import sys
from warp_spt.images.environment import read_environment_image
from warp_spt.io.loader import load_scene
def kib(key):
    with open("/proc/self/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith(key))
with open("/proc/self/clear_refs", "w") as f:
    f.write("5")
before = kib("VmRSS:")
if sys.argv[1].endswith(".obj"):     # a scene whose one texture is 2048 x 1024
    load_scene([sys.argv[1]])
    texels = 2048 * 1024
else:
    img = read_environment_image(sys.argv[1])
    texels = img.shape[0] * img.shape[1]
print((kib("VmHWM:") - before) * 1024 / texels)
"""


@pytest.fixture(scope="module")
def maps(tmp_path_factory):
    """A 2048 x 1024 map (2 million texels) in each format, of noise (no run-length savings)."""
    from PIL import Image

    from warp_spt.images.hdr import write_hdr

    d = tmp_path_factory.mktemp("maps")
    rng = np.random.default_rng(42)
    img = rng.random((1024, 2048, 3)).astype(np.float32) * 4
    write_hdr(d / "m.hdr", img)
    Image.fromarray((rng.random((1024, 2048, 3)) * 255).astype(np.uint8)).save(d / "m.png", compress_level=1)
    np.save(d / "m.npy", img.astype(np.float64))
    return d


@pytest.mark.skipif(not os.path.exists("/proc/self/clear_refs"), reason="measures Linux's /proc high-water mark")
@pytest.mark.parametrize("ext", [".hdr", ".png", ".npy"])
def test_reading_an_environment_map_peaks_within_its_budget_per_texel(maps, ext):
    per_texel = _peak_per_texel(maps / f"m{ext}")
    # before: .hdr 68, .png 107, .npy (float64) 36 bytes a texel
    assert per_texel <= READ_BYTES_PER_TEXEL[ext], (ext, per_texel)


def _peak_per_texel(path) -> float:
    out = subprocess.run([sys.executable, "-c", PEAK, str(path)], capture_output=True, text=True,
                         timeout=120, env={**os.environ, "PYTHONPATH": os.getcwd()})
    assert out.returncode == 0, out.stderr
    return float(out.stdout)


@pytest.mark.skipif(not os.path.exists("/proc/self/clear_refs"), reason="measures Linux's /proc high-water mark")
def test_reading_a_png_texture_peaks_within_its_budget_per_texel(maps):
    from warp_spt.io.loader import TEXTURE_READ_BYTES_PER_TEXEL

    (maps / "t.mtl").write_text("newmtl m\nKd 1 1 1\nmap_Kd m.png\n")
    (maps / "t.obj").write_text("mtllib t.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                "f 1/1 2/2 3/3\n")
    per_texel = _peak_per_texel(maps / "t.obj")
    assert per_texel <= TEXTURE_READ_BYTES_PER_TEXEL, per_texel            # before: 58


@pytest.mark.parametrize("mode", ["RGB", "RGBA", "L", "P"])
def test_8_bit_textures_decode_to_the_values_of_whole_image_arithmetic(tmp_path, mode):
    from PIL import Image

    from warp_spt.io.loader import _to_rgb, srgb_to_linear

    rng = np.random.default_rng(7)
    img = Image.fromarray((rng.random((37, 301, 3)) * 256).astype(np.uint8)).convert(mode)
    raw = np.asarray(img.convert("RGB"), dtype=np.float32) / np.float32(255.0)     # the reader's arithmetic before
    assert np.array_equal(_to_rgb(img), raw)
    assert np.array_equal(_to_rgb(img, srgb=True), srgb_to_linear(raw))


def test_environment_maps_are_read_as_before(maps):
    from warp_spt.images.environment import srgb_to_linear
    from PIL import Image

    png = read_environment_image(maps / "m.png")
    raw = np.asarray(Image.open(maps / "m.png"))
    assert png.dtype == np.float32 and np.allclose(png, srgb_to_linear(raw / 255.0), atol=1e-7)
    npy = read_environment_image(maps / "m.npy")
    assert np.array_equal(npy, np.load(maps / "m.npy").astype(np.float32))
    from warp_spt.images.hdr import decode_rgbe, encode_rgbe
    hdr = read_environment_image(maps / "m.hdr")
    assert np.array_equal(hdr, decode_rgbe(encode_rgbe(npy)))


def test_sizes_are_checked_from_headers_before_reading(tmp_path):
    pfm = tmp_path / "huge.pfm"
    pfm.write_bytes(b"PF\n1000000 500000\n-1.0\n" + b"\0" * 64)
    with pytest.raises(ValueError, match=r"huge\.pfm: 1000000x500000 = 500,000,000,000 texels, more than the texel"):
        read_environment_image(pfm)
    from warp_spt.images.files import read_pfm
    with pytest.raises(ValueError, match=r"huge\.pfm: the PFM header declares 1000000x500000x3 floats: "
                                         r"expected 6000000000000 bytes of data after it, the file holds 64"):
        read_pfm(pfm)
    hdr = tmp_path / "huge.hdr"
    hdr.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 60000 +X 60000\n" + b"\0" * 64)
    tracemalloc.start()
    with pytest.raises(ValueError, match=r"huge\.hdr: 60000x60000 = 3,600,000,000 texels, more than the texel"):
        read_environment_image(hdr)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 1 << 20, peak                     # before: 14 GB of RGBE pixels allocated first


# ------------------------------------------------------------------------------------------- NanoVDB

def _grid_file(tmp_path, codec: str = "zip"):
    import warp as wp

    a = np.zeros((8, 8, 8), np.float32)
    a[2:5, 2:5, 2:5] = 1.0
    path = tmp_path / f"{codec}.nvdb"
    wp.Volume.load_from_numpy(a, bg_value=0.0, device="cpu").save_to_nvdb(str(path), codec=codec)
    return path


def _load(path):
    from warp_spt.media.grid import load_grid

    return load_grid(Medium(sigma_s=1.0, density=str(path)), "cpu", "density")


def test_a_zip_compressed_grid_reads_as_the_uncompressed_one(tmp_path):
    _, ijk, vals = _load(_grid_file(tmp_path, "zip"))
    _, ijk0, vals0 = _load(_grid_file(tmp_path, "none"))
    assert np.array_equal(ijk, ijk0) and np.array_equal(vals, vals0) and vals.sum() == 27


def _bomb_refused(path) -> int:
    """The peak of Python's allocations while ``path`` (bomb.nvdb) is refused for inflating too much."""
    tracemalloc.start()
    with pytest.raises(SceneError, match=r"bomb\.nvdb: the compressed grids inflate to more than the [\d,]+ bytes "
                                         "their header declares"):
        _load(path)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    return peak


def test_a_zip_bomb_grid_is_refused_within_its_declared_size(tmp_path):
    data = _grid_file(tmp_path, "zip").read_bytes()
    start = 16 + 176 + struct.unpack("<I", data[16 + 136:16 + 140])[0]
    packer = zlib.compressobj(9)
    bomb = b"".join(packer.compress(bytes(1 << 20)) for _ in range(256)) + packer.flush()   # 256 MB of zeros
    bad = tmp_path / "bomb.nvdb"
    head = bytearray(data[:start])
    head[16 + 8:16 + 16] = struct.pack("<Q", 8 + len(bomb))          # the chunk's size as stored
    bad.write_bytes(bytes(head) + struct.pack("<Q", len(bomb)) + bomb)
    peak = _bomb_refused(bad)
    declared = struct.unpack("<Q", data[16:24])[0]
    assert peak < 4 * declared + 2 * bad.stat().st_size, peak        # before: Warp inflated all 256 MB
    head[16:24] = struct.pack("<Q", MAX_GRID_BYTES + 1)              # a header declaring too much: not inflated
    bad.write_bytes(bytes(head) + struct.pack("<Q", len(bomb)) + bomb)
    with pytest.raises(SceneError, match=rf"the grids hold {MAX_GRID_BYTES + 1:,} bytes, over the budget"):
        _load(bad)


def test_a_density_grid_that_is_a_device_or_too_large_is_refused_unread(tmp_path):
    with pytest.raises(SceneError, match=r"/dev/zero: cannot read density grid file: it is a character device"):
        _load("/dev/zero")
    big = tmp_path / "big.nvdb"
    with open(big, "wb") as f:
        f.truncate(MAX_GRID_BYTES + 1)                               # sparse: no disk used
    with pytest.raises(SceneError, match=r"big\.nvdb: density grid file is larger than the"):
        _load(big)


def _blosc_file(tmp_path, name: str, declared: int | None = None):
    """The 8^3 grid's file as one stored blosc chunk (``blosc_grid``)."""
    path = tmp_path / name
    path.write_bytes(blosc_grid(_grid_file(tmp_path, "none").read_bytes(), declared))
    return path


def test_a_blosc_compressed_grid_reads_as_the_uncompressed_one(tmp_path, monkeypatch):
    fake = FakeBlosc()
    monkeypatch.setitem(sys.modules, "blosc", fake)
    _, ijk, vals = _load(_blosc_file(tmp_path, "b.nvdb"))
    _, ijk0, vals0 = _load(_grid_file(tmp_path, "none"))
    assert np.array_equal(ijk, ijk0) and np.array_equal(vals, vals0) and vals.sum() == 27 and len(fake.asked) == 1


def test_a_blosc_bomb_grid_is_refused_from_its_chunk_header_before_blosc_allocates(tmp_path, monkeypatch):
    fake = FakeBlosc()
    monkeypatch.setitem(sys.modules, "blosc", fake)
    bomb = _blosc_file(tmp_path, "bomb.nvdb", declared=(1 << 31) - 1)    # a small file, a 2 GiB chunk
    peak = _bomb_refused(bomb)
    assert fake.asked == [] and peak < 4 * bomb.stat().st_size + (1 << 20), (fake.asked, peak)  # before: Warp asked 2 GiB


def test_without_blosc_a_blosc_grid_names_the_file_and_the_package(tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "blosc", None)                  # import blosc: ImportError
    with pytest.raises(SceneError, match=r"b\.nvdb: the grids are blosc-compressed, which needs the 'blosc' package"):
        _load(_blosc_file(tmp_path, "b.nvdb"))
