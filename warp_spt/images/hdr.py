"""Radiance RGBE (``.hdr``) images: a reader and a writer of our own (the format is small).

A file is a text header (``#?RADIANCE`` or ``#?RGBE``, ``KEY=value`` lines, a blank line), a
resolution line (``-Y H +X W``: rows top to bottom; ``+Y H +X W`` is read bottom-up and flipped) and
H scanlines of W pixels of four bytes (R, G, B mantissas and a shared exponent E: a channel is
(c + 0.5) 2^(E - 136), 0 where E is 0). A scanline of 8 to 32767 pixels may be run-length encoded
("new" RLE: the bytes 2 2 and the width, then each of the four channels as runs, a count byte over
128 repeating the next byte count - 128 times, else that many literal bytes); otherwise it is flat.
The older RLE (repeat pixels 1 1 1 n) and other orientations are refused by name. ``EXPOSURE`` is
not applied (as most readers): the values are taken as they are.
"""

from __future__ import annotations

import os

import numpy as np

MAX_SIDE = 1 << 16


class HdrError(ValueError):
    """A malformed .hdr file (the message names the file and what was expected)."""


def _header(data: bytes, path) -> tuple[int, int, bool, int]:
    """(height, width, bottom_up, offset of the pixels) from the header and resolution line."""
    if not (data.startswith(b"#?RADIANCE") or data.startswith(b"#?RGBE")):
        raise HdrError(f"{path}: not a Radiance .hdr file (expected it to begin with '#?RADIANCE' or '#?RGBE')")
    pos = 0
    while True:
        end = data.find(b"\n", pos)
        if end < 0:
            raise HdrError(f"{path}: the header never ends (expected a blank line, then '-Y height +X width')")
        line = data[pos:end].strip()
        pos = end + 1
        if not line:
            break
        if line.startswith(b"FORMAT=") and line[7:] not in (b"32-bit_rle_rgbe",):
            raise HdrError(f"{path}: pixel format {line[7:].decode(errors='replace')!r} is not supported "
                           "(expected FORMAT=32-bit_rle_rgbe; XYZE is not read)")
    end = data.find(b"\n", pos)
    if end < 0:
        raise HdrError(f"{path}: missing resolution line after the header (expected '-Y height +X width')")
    parts = data[pos:end].split()
    if len(parts) != 4 or parts[0] not in (b"-Y", b"+Y") or parts[2] != b"+X":
        raise HdrError(f"{path}: resolution line {data[pos:end][:60].decode(errors='replace')!r} is not supported "
                       "(expected '-Y height +X width' or '+Y height +X width')")
    try:
        h, w = int(parts[1]), int(parts[3])
    except ValueError:
        raise HdrError(f"{path}: resolution line {data[pos:end][:60].decode(errors='replace')!r}: "
                       "height and width must be integers") from None
    if not (1 <= h <= MAX_SIDE and 1 <= w <= MAX_SIDE):
        raise HdrError(f"{path}: size {w}x{h} out of range (each side 1 to {MAX_SIDE})")
    return h, w, parts[0] == b"+Y", end + 1


def _rle_line(data: bytes, pos: int, w: int, path, row: int) -> tuple[np.ndarray, int]:
    """One new-style RLE scanline starting at ``pos`` (after its four-byte marker): (w, 4) bytes and
    the offset after it."""
    out = np.empty((4, w), dtype=np.uint8)
    n = len(data)
    for ch in range(4):
        x = 0
        while x < w:
            if pos >= n:
                raise HdrError(f"{path}: truncated at scanline {row} (expected {w} pixels of run-length data)")
            count = data[pos]
            pos += 1
            if count > 128:
                count -= 128
                if x + count > w or pos >= n:
                    raise HdrError(f"{path}: scanline {row}: a run of {count} overruns the width {w} or the file")
                out[ch, x:x + count] = data[pos]
                pos += 1
            else:
                if count == 0 or x + count > w or pos + count > n:
                    raise HdrError(f"{path}: scanline {row}: a literal run of {count} bytes overruns the width "
                                   f"{w} or the file (or is empty)")
                out[ch, x:x + count] = np.frombuffer(data, dtype=np.uint8, count=count, offset=pos)
                pos += count
            x += count
    return out.T, pos


def decode_rgbe(rgbe: np.ndarray) -> np.ndarray:
    """(..., 4) uint8 RGBE to (..., 3) float32 radiance."""
    e = rgbe[..., 3].astype(np.int32)
    scale = np.where(e == 0, 0.0, np.ldexp(1.0, e - 136))
    return ((rgbe[..., :3].astype(np.float64) + 0.5) * scale[..., None]).astype(np.float32)


# the RGBE pixels are decoded to float32 this many texels at a time (the temporaries take 60 bytes a
# texel; decoding the whole image at once made the reader's peak 68 bytes a texel, now 20: see
# images.environment.READ_BYTES_PER_TEXEL)
DECODE_BLOCK_TEXELS = 1 << 16


def read_hdr(path: str | os.PathLike, max_texels: int | None = None) -> np.ndarray:
    """A .hdr file as (H, W, 3) float32 radiance, row 0 the top (HdrError naming the file otherwise).
    Only a regular file is read; its size from the header is checked against ``max_texels``
    (default the texel budget) before anything is allocated."""
    from warp_spt.io.tokens import read_file
    from warp_spt.scene.atlas_layout import TEXEL_BUDGET
    from warp_spt.scene.errors import SceneError

    budget = TEXEL_BUDGET if max_texels is None else max_texels
    try:    # run-length lines are at most 1/128 longer than flat ones, plus a marker each
        data = read_file(str(path), "Radiance .hdr", binary=True,
                         limit=(4 * budget * 129) // 128 + 4 * MAX_SIDE + (1 << 20))
    except SceneError as err:
        raise HdrError(str(err)) from None
    h, w, bottom_up, pos = _header(data, path)
    if h * w > budget:
        raise HdrError(f"{path}: {w}x{h} = {h * w:,} texels, more than the texel budget of {budget:,}")
    pixels = np.empty((h, w, 4), dtype=np.uint8)
    for row in range(h):
        rle = 8 <= w <= 32767 and data[pos:pos + 2] == b"\x02\x02" and (len(data) > pos + 2 and data[pos + 2] < 128)
        if rle:
            if (data[pos + 2] << 8) | data[pos + 3] != w:
                raise HdrError(f"{path}: scanline {row} declares width {(data[pos + 2] << 8) | data[pos + 3]}, "
                               f"expected {w}")
            pixels[row], pos = _rle_line(data, pos + 4, w, path, row)
            continue
        flat = data[pos:pos + 4 * w]
        if len(flat) != 4 * w:
            raise HdrError(f"{path}: truncated at scanline {row} (expected {4 * w} bytes of pixels, "
                           f"found {len(flat)})")
        line = np.frombuffer(flat, dtype=np.uint8).reshape(w, 4)
        if np.any((line[:, 0] == 1) & (line[:, 1] == 1) & (line[:, 2] == 1)):
            raise HdrError(f"{path}: scanline {row} uses the old run-length encoding (pixels 1 1 1 n), which is "
                           "not read; re-save the file with a current tool")
        pixels[row] = line
        pos += 4 * w
    del data
    img = np.empty((h, w, 3), dtype=np.float32)
    rows = max(1, DECODE_BLOCK_TEXELS // w)
    for r in range(0, h, rows):                    # decoded a block at a time: see READ_BYTES_PER_TEXEL
        block = decode_rgbe(pixels[r:r + rows])
        if bottom_up:                              # flipped as it is written: no second image
            img[h - r - len(block):h - r] = block[::-1]
        else:
            img[r:r + len(block)] = block
    return img


def encode_rgbe(img: np.ndarray) -> np.ndarray:
    """(..., 3) float radiance (>= 0) to (..., 4) uint8 RGBE (Radiance's rounding: truncation of the
    mantissa, so ``decode_rgbe`` returns the bin's middle)."""
    v = np.asarray(img, dtype=np.float64)
    m = v.max(axis=-1)
    mant, exp = np.frexp(m)
    ok = m >= 1e-32
    scale = np.where(ok, mant * 256.0 / np.where(ok, m, 1.0), 0.0)
    out = np.zeros(v.shape[:-1] + (4,), dtype=np.uint8)
    out[..., :3] = np.clip(np.floor(v * scale[..., None]), 0, 255).astype(np.uint8)
    out[..., 3] = np.where(ok, exp + 128, 0).astype(np.uint8)
    return out


def _rle_channel(b: np.ndarray) -> bytes:
    """One channel of a scanline as new-style runs (repeats of 4 or more, else literals)."""
    out = bytearray()
    n, x = len(b), 0
    while x < n:
        run = 1
        while x + run < n and run < 127 and b[x + run] == b[x]:
            run += 1
        if run >= 4:
            out += bytes((128 + run, int(b[x])))
            x += run
            continue
        start = x
        while x < n and x - start < 128:
            if x + 3 < n and b[x] == b[x + 1] == b[x + 2] == b[x + 3]:
                break
            x += 1
        out += bytes((x - start,)) + bytes(b[start:x].tolist())
    return bytes(out)


def write_hdr(path: str | os.PathLike, img: np.ndarray, rle: bool = True) -> None:
    """Write (H, W, 3) float radiance as a .hdr file, run-length encoded where the width allows."""
    from warp_spt.images.files import atomic_write

    rgbe = encode_rgbe(img)
    h, w = rgbe.shape[:2]
    body = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n" + f"-Y {h} +X {w}\n".encode())
    for row in range(h):
        if rle and 8 <= w <= 32767:
            body += bytes((2, 2, w >> 8, w & 255))
            for ch in range(4):
                body += _rle_channel(rgbe[row, :, ch])
        else:
            body += rgbe[row].tobytes()
    atomic_write(path, lambda f: f.write(bytes(body)))
