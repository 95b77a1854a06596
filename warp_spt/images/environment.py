"""Environment maps from files: ``load_environment(path, ...) -> Sky``.

Formats, by extension: Radiance ``.hdr`` (our reader, ``images.hdr``), ``.pfm`` and ``.exr`` (the
optional ``exr`` extra) as float32 radiance; ``.npy`` (an (H, W, 3) float array); an 8-bit ``.png``
or ``.jpg`` is accepted as a low-dynamic-range map with a warning (decoded from sRGB to linear, so at
most 1: a sun clipped to white lights a scene far too little). Every map is checked by
``scene.environment`` (2:1, within the texel budget, finite, non-negative), the file named in each
error.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

import numpy as np

from warp_spt.scene.atlas_layout import TEXEL_BUDGET
from warp_spt.scene.environment import EnvironmentMap
from warp_spt.scene.sky import Sky

FORMATS = (".hdr", ".exr", ".pfm", ".npy", ".png", ".jpg", ".jpeg")
LDR = (".png", ".jpg", ".jpeg")


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB transfer function inverted (values in [0, 1])."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def read_environment_image(path: str | os.PathLike, warn: Callable[[str], None] | None = None) -> np.ndarray:
    """The image of an environment map file as (H, W, 3) float32 radiance, row 0 the top (ValueError
    naming the file and what was expected)."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in FORMATS:
        raise ValueError(f"{path}: unsupported environment map extension {ext or '(none)'!r}; expected one of "
                         f"{', '.join(FORMATS)}")
    if not p.is_file():
        raise ValueError(f"{path}: no such environment map file")
    try:
        if ext == ".hdr":
            from warp_spt.images.hdr import read_hdr
            return read_hdr(p)
        if ext == ".pfm":
            from warp_spt.images.files import read_pfm
            return read_pfm(p, max_texels=TEXEL_BUDGET)
        if ext == ".npy":
            return _read_npy(p)
        if ext == ".exr":
            return _read_exr(path, p, warn)
        from PIL import Image

        try:
            opened = Image.open(p)
        except Image.DecompressionBombError as err:     # Pillow's own guard, at twice its own limit
            raise ValueError(f"{path}: more texels than the texel budget of {TEXEL_BUDGET:,} "
                             f"({' '.join(str(err).split())})") from None
        with opened as im:
            _check_size(path, *im.size)              # from the header, before anything is decoded
            rgb = im if im.mode == "RGB" else im.convert("RGB")
            img = np.asarray(rgb, dtype=np.uint8)
            del rgb
        if warn is not None:
            warn(f"{path}: an 8-bit image is a low-dynamic-range environment (radiance at most 1, its bright "
                 "parts clipped): lighting from it is flatter than from an .hdr or .exr map")
        return _SRGB_LUT[img]           # a table of the 256 values: 12 bytes a texel, not float64 temporaries
    except ValueError as err:
        if str(err).startswith((f"{path}: ", f"{p}: ")):     # ours, already naming the file
            raise
        raise ValueError(f"{path}: cannot read the environment map: {' '.join(str(err).split())}") from None
    except Exception as err:        # the image libraries' own (OpenEXR's RuntimeError, PIL's bomb guard...)
        text = " ".join(str(err).split()) or type(err).__name__
        raise ValueError(f"{path}: cannot read the environment map: {text}") from None


def _read_exr(path, p: Path, warn) -> np.ndarray:
    """An OpenEXR file's RGB image. OpenEXR's C core prints its own account of a damaged file to
    stdout and stderr before the binding raises a vaguer one ("Unable to open ... for read"): that
    output is caught, and its first line is the error (or, for a file that still reads, a warning)."""
    try:
        import OpenEXR
    except ImportError:
        from warp_spt.runtime.extras import install_hint
        raise ValueError(f"{path}: reading .exr needs the optional 'openexr' package: "
                         f"{install_hint('exr')}") from None
    from warp_spt.runtime.warp_init import native_output

    said = bytearray()
    try:
        with native_output() as said:
            with OpenEXR.File(str(p), header_only=True) as head:     # the size before any pixel is decoded
                (x0, y0), (x1, y1) = head.header()["dataWindow"]
            _check_size(path, int(x1) - int(x0) + 1, int(y1) - int(y0) + 1)
            with OpenEXR.File(str(p)) as exr:
                channels = exr.channels()
                if "RGB" not in channels:
                    raise ValueError(f"{path}: expected an RGB (or R, G, B) image, found channels "
                                     f"{', '.join(sorted(channels))}")
                img = np.asarray(channels["RGB"].pixels, dtype=np.float32)
    except Exception as err:        # OpenEXR's RuntimeError or ValueError; ours name the file already
        if isinstance(err, ValueError) and str(err).startswith(f"{path}: "):
            raise
        raise ValueError(f"{path}: cannot read the environment map: {_first_line(said, p) or err}") from None
    if said and warn is not None:
        warn(f"{path}: {_first_line(said, p)}")
    return img


def _first_line(text: bytes, p: Path) -> str:
    """The first non-blank line a library printed, without the file name it starts with."""
    for line in text.decode("utf-8", "replace").splitlines():
        line = " ".join(line.split())
        for name in (str(p), p.name):
            if line.startswith(f"{name}: "):
                line = line[len(name) + 2:]
        if line:
            return line
    return ""


_SRGB_LUT = srgb_to_linear(np.arange(256) / 255.0).astype(np.float32)

# The budgets of peak memory while a map is read, in bytes a texel, the float32 RGB result's 12
# included (tests/hardening/test_reader_memory.py measures a subprocess's peak RSS for 2 million
# texels): .hdr 24 (measured 19: the file, its RGBE pixels and the image, decoded a block of rows at a
# time; 68 when decoded at once), an 8-bit PNG 24 (20: Pillow's decoded image and a uint8 copy beside
# the result, through a table; 107 through float64 arithmetic), .npy 20 whatever its dtype (16: read a
# block of rows at a time; a float64 map read whole, then converted, took 36)
READ_BYTES_PER_TEXEL = {".hdr": 24, ".png": 24, ".npy": 20}
NPY_BLOCK_BYTES = 1 << 22
NPY_HEADER_BYTES = 1 << 16      # numpy writes headers of about 128 bytes


def _read_npy(p: Path) -> np.ndarray:
    """An .npy map as float32, its shape and dtype checked from the header and its data read a block
    of rows at a time (a float64 map is never whole in memory as float64)."""
    with open(p, "rb") as f:
        shape, fortran, dtype = _npy_header(f, p)
        if fortran or dtype.hasobject:
            raise ValueError(f"{p}: expected a C-ordered numeric (H, W, 3) array")
        h, w = shape[0], shape[1]
        out = np.empty((h, w, 3), dtype=np.float32)
        rows = max(1, NPY_BLOCK_BYTES // max(1, w * 3 * dtype.itemsize))
        for r in range(0, h, rows):
            n = min(rows, h - r)
            block = np.fromfile(f, dtype=dtype, count=n * w * 3)
            if block.size != n * w * 3:
                raise ValueError(f"{p}: the array's data ends at row {r + block.size // (w * 3)} of {h}")
            with np.errstate(over="ignore"):     # beyond float32: infinite, which the map's check refuses by name
                out[r:r + n] = block.reshape(n, w, 3)
    return out


def _check_size(path, width: int, height: int) -> None:
    """The texel budget, from the size a header gives (a PNG of 220 KB once decoded to 3.9 GB)."""
    if width * height > TEXEL_BUDGET:
        raise ValueError(f"{path}: {width}x{height} = {width * height:,} texels, more than the texel budget of "
                         f"{TEXEL_BUDGET:,}")


def _npy_header(f, p: Path):
    """An .npy map's (shape, fortran order, dtype) from its header, checked before its data is read."""
    try:
        version = np.lib.format.read_magic(f)
        # numpy reads a header of the length it declares before it checks that length (4 GB for
        # four forged bytes): the version and the length are checked here first
        size = 2 if version == (1, 0) else 4
        start = f.tell()
        length = int.from_bytes(f.read(size), "little")
        if version not in ((1, 0), (2, 0), (3, 0)) or length > NPY_HEADER_BYTES:
            raise ValueError(f"version {version[0]}.{version[1]} with a header of {length:,} bytes (expected "
                             f"1.0, 2.0 or 3.0 and at most {NPY_HEADER_BYTES:,})")
        f.seek(start)
        shape, fortran, dtype = (np.lib.format.read_array_header_1_0(f) if version == (1, 0)
                                 else np.lib.format.read_array_header_2_0(f))
    except ValueError as err:
        raise ValueError(f"{p}: not an .npy array: {' '.join(str(err).split())}") from None
    if len(shape) != 3 or shape[2] != 3:
        raise ValueError(f"{p}: an environment map must be an RGB image (height, width, 3), got shape {shape}")
    if not np.issubdtype(dtype, np.number):
        raise ValueError(f"{p}: expected a numeric (H, W, 3) array, got dtype {dtype}")
    _check_size(p, shape[1], shape[0])
    return shape, fortran, dtype


def load_environment(path: str | os.PathLike, rotate: float = 0.0, strength: float = 1.0, background=None,
                     up=None, warn: Callable[[str], None] | None = None, sampling: str = "importance") -> Sky:
    """An environment sky from an equirectangular map file (see :meth:`warp_spt.Sky.environment` for
    ``rotate`` (degrees about the up axis), ``strength``, ``background`` and ``up``); ``warn`` is
    called with a warning (an 8-bit map); ``sampling``: ``scene.environment.SAMPLINGS``."""
    img = read_environment_image(path, warn)
    env = EnvironmentMap(img, str(path), sampling)
    return Sky.environment(env, rotate=rotate, strength=strength, background=background, up=up)
