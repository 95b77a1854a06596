"""Image files: tone maps and writers (PNG, JPEG, NPY, PFM, EXR, GIF), written atomically.

Tone maps: :func:`tonemap_seed` is the seed's curve (SEMANTICS §4) bit for bit, :func:`tonemap_srgb`
the standard sRGB transfer function, :func:`tonemap_filmic` a filmic curve (a log-encoded S-curve with
a highlight shoulder, the first image's curve for standard files). File formats by extension: ``.png`` (8-bit, tone mapped),
``.jpg`` (8-bit, tone mapped), ``.npy``, ``.pfm`` and ``.exr`` (float32 linear radiance; EXR needs the
optional ``openexr`` package). Every file is written to a hidden temporary file beside the target
and renamed (:func:`atomic_write`), so a failed or interrupted write never leaves a truncated file.
"""

from __future__ import annotations

import errno
import io
import math
import os
import uuid
from pathlib import Path
from typing import BinaryIO, Callable, Sequence

import numpy as np


def seed_lut() -> np.ndarray:
    """The seed's 256-entry float32 LUT: (i/256)^2 up to i = 204, then 0.128 / (1 - i/256).

    Computed in float64 and rounded once to float32 (the seed stores floats).
    """
    x = np.arange(256, dtype=np.float64) / 256.0
    with np.errstate(divide="ignore"):
        lut = np.where(np.arange(256) <= 204, x * x, 0.128 / (1.0 - x))
    return lut.astype(np.float32)


def _seed_search_result(below: int) -> int:
    """The seed's binary search, run for an input x with exactly ``below`` LUT entries < x.

    Since the LUT is strictly increasing, ``LUT[M] < x`` is the same as ``M < below``, so the whole
    search path (and the returned last midpoint) depends on ``below`` only.
    """
    lo, hi, mid = 0, 255, 128
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if mid < below:
            lo = mid
        else:
            hi = mid
    return mid


_LUT = seed_lut()


_SEARCH_RESULT = np.array([_seed_search_result(j) for j in range(257)], dtype=np.uint8)


def tonemap_seed(img: np.ndarray) -> np.ndarray:
    """The seed's tone curve per channel, exactly: float32 input, uint8 (H, W, 3) in [1, 254].

    NaN and negative values give 1 (every comparison fails or succeeds the same way as for 0).
    """
    x = np.asarray(img, dtype=np.float32)
    below = np.searchsorted(_LUT, x, side="left")      # count of LUT entries < x
    below = np.where(np.isnan(x), 0, below)             # NaN < LUT[M] is false at every step
    return _SEARCH_RESULT[below]


def tonemap_srgb(img: np.ndarray, exposure: float = 1.0) -> np.ndarray:
    """sRGB encoding of linear radiance times ``exposure``, clamped to [0, 1], rounded to uint8.

    NaN gives 0.
    """
    x = np.nan_to_num(np.asarray(img, dtype=np.float64) * exposure, nan=0.0)
    x = np.clip(x, 0.0, 1.0)
    y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1.0 / 2.4) - 0.055)
    return np.floor(y * 255.0 + 0.5).astype(np.uint8)


# The filmic curve's published numbers: the range Blender's Filmic view covers, 10 stops below and 6.5
# above scene middle grey 0.18 (16.5 stops, white at 0.18 * 2^6.5 = 16.3), middle grey shown at half
# the display range, and there the slope of the sRGB curve at 0.18 (so mid-tones keep sRGB's contrast
# and only the ends are compressed): d sRGB(0.18 * 2^(16.5 t)) / dt = 2.46 at middle grey.
FILMIC_GREY, FILMIC_STOPS_BELOW, FILMIC_STOPS_ABOVE = 0.18, 10.0, 6.5
FILMIC_MID = 0.5
FILMIC_SLOPE = (1.055 / 2.4 * FILMIC_GREY ** (1 / 2.4)       # sRGB's derivative, times dx/dt
                * math.log(2.0) * (FILMIC_STOPS_BELOW + FILMIC_STOPS_ABOVE))


def _filmic_side(t: np.ndarray, width: float) -> np.ndarray:
    """One half of the S-curve: u / sqrt(1 + u^2) (slope 1 at 0, tending to 1), scaled so that it
    reaches 1 at ``width`` (the end of the range) with slope FILMIC_SLOPE / FILMIC_MID at 0; ``t`` >= 0
    is the distance from middle grey in the log-encoded range. The scale ``a`` solves
    0.5 * a / sig(a * width) = FILMIC_SLOPE in closed form, so the two halves meet without a kink."""
    a = np.sqrt((FILMIC_SLOPE * width / FILMIC_MID) ** 2 - 1.0) / width
    sig = lambda u: u / np.sqrt(1.0 + u * u)            # noqa: E731
    return sig(a * t) / sig(a * width)


def filmic_curve(x: np.ndarray) -> np.ndarray:
    """The filmic display value in [0, 1] (display-encoded, like an sRGB code value) of linear
    radiance ``x``: log2(x / 0.18) over [-10, 6.5] stops mapped to [0, 1], then an S-curve through
    (middle grey, 0.5) with a toe to 0 and a shoulder to 1. Monotone; 0 at and below 0.18 * 2^-10,
    1 at and above 0.18 * 2^6.5 = 16.3; NaN gives 0."""
    span = FILMIC_STOPS_BELOW + FILMIC_STOPS_ABOVE
    x = np.nan_to_num(np.asarray(x, dtype=np.float64), nan=0.0)
    with np.errstate(divide="ignore"):
        stops = np.log2(np.maximum(x, 0.0) / FILMIC_GREY)
    t = np.clip((stops + FILMIC_STOPS_BELOW) / span, 0.0, 1.0)
    grey = FILMIC_STOPS_BELOW / span
    above = FILMIC_MID + (1.0 - FILMIC_MID) * _filmic_side(np.maximum(t - grey, 0.0), 1.0 - grey)
    below = FILMIC_MID - FILMIC_MID * _filmic_side(np.maximum(grey - t, 0.0), grey)
    return np.where(t >= grey, above, below)


def tonemap_filmic(img: np.ndarray) -> np.ndarray:
    """:func:`filmic_curve` per channel, rounded to uint8 (H, W, 3) in [0, 255]."""
    return np.floor(filmic_curve(img) * 255.0 + 0.5).astype(np.uint8)


def atomic_write(path: str | os.PathLike, write: Callable[[BinaryIO], None]) -> None:
    """Call ``write(f)`` on an in-memory buffer, then write it to a temporary file next to ``path``
    and rename that over ``path``.

    On any exception (KeyboardInterrupt included) the temporary file is removed and ``path`` is
    untouched, so a failed write never leaves a partial file or clobbers an existing one. SIGINT and
    SIGTERM are held while the file is written and renamed (see :func:`warp_spt.runtime.signals.deferred_signals`),
    so a signal can never land in the middle of the cleanup. A symbolic link at ``path`` is written
    through (its target is replaced, the link stays); an existing ``path`` that is not a regular
    file (a device, a FIFO, a directory) is refused. Failures raise OSError whose message names
    ``path`` and the reason, e.g. "cannot write out.png: no space left on device".
    """
    from warp_spt.runtime.signals import deferred_signals

    target = _output_target(Path(path))
    buffer = io.BytesIO()
    write(buffer)            # encode first: only OS errors can happen below, and they carry an errno
    data = buffer.getbuffer()
    with deferred_signals():
        tmp = target.with_name(f".{target.name}.{uuid.uuid4().hex}.tmp")
        try:
            # os.open with mode 0o666 lets the umask decide the permissions, as for a plain open()
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | getattr(os, "O_BINARY", 0), 0o666)
            try:
                _write_all(fd, data)
                os.fsync(fd)
            finally:
                os.close(fd)
            os.replace(tmp, target)
        except BaseException as err:
            tmp.unlink(missing_ok=True)
            if isinstance(err, OSError):
                raise _cannot_write(path, err) from None
            raise


def _output_target(path: Path) -> Path:
    """The file to replace: a symlink's target (write-through); anything but a regular file is refused."""
    if path.is_symlink():
        path = Path(os.path.realpath(path))
    if path.exists() and not path.is_file():
        raise OSError(errno.EINVAL, f"cannot write {path}: it exists and is not a regular file")
    return path


def _write_all(fd: int, data: memoryview) -> None:
    view = memoryview(data).cast("B")
    while view:
        n = os.write(fd, view)
        view = view[n:]


def _cannot_write(path, err: OSError) -> OSError:
    reason = err.strerror or str(err)
    reason = reason[:1].lower() + reason[1:]
    return OSError(err.errno, f"cannot write {path}: {reason}")


def _check_rgb(img: np.ndarray) -> np.ndarray:
    a = np.asarray(img)
    if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError(f"image must be (H, W, 3), got shape {a.shape}")
    return a


def _write_png(f: BinaryIO, img8: np.ndarray) -> None:
    from PIL import Image

    Image.fromarray(np.ascontiguousarray(img8, dtype=np.uint8)).save(f, format="PNG")


def _write_npy(f: BinaryIO, img: np.ndarray) -> None:
    np.save(f, np.ascontiguousarray(img, dtype=np.float32))


def _write_pfm(f: BinaryIO, img: np.ndarray) -> None:
    h, w = img.shape[:2]
    f.write(f"PF\n{w} {h}\n-1.0\n".encode("ascii"))       # negative scale: little-endian
    f.write(np.ascontiguousarray(img[::-1], dtype="<f4").tobytes())   # rows bottom to top


def _write_jpeg(f: BinaryIO, img8: np.ndarray) -> None:
    from PIL import Image

    Image.fromarray(np.ascontiguousarray(img8, dtype=np.uint8)).save(f, format="JPEG", quality=95)


def _write_exr(f: BinaryIO, img: np.ndarray) -> None:
    """Linear float32 RGB OpenEXR (ZIP compressed), through the optional ``openexr`` package.

    OpenEXR writes to a file name only, so the image goes to a private temporary file whose bytes
    are then copied into ``f`` (which :func:`atomic_write` renames into place).
    """
    import tempfile

    try:
        import OpenEXR
    except ImportError:
        from warp_spt.runtime.extras import install_hint
        raise ValueError(f"writing .exr needs the optional 'openexr' package: {install_hint('exr')}") from None
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with tempfile.TemporaryDirectory() as tmp:
        name = os.path.join(tmp, "image.exr")
        OpenEXR.File(header, {"RGB": np.ascontiguousarray(img, dtype=np.float32)}).write(name)
        with open(name, "rb") as src:
            f.write(src.read())


_TONE_MAPPED = (".png", ".jpg", ".jpeg")


_TONEMAPS = {"seed": tonemap_seed, "srgb": tonemap_srgb, "filmic": tonemap_filmic}


def to_display(img: np.ndarray, curve: str = "seed", exposure: float = 0.0) -> np.ndarray:
    """uint8 (H, W, 3): the linear image scaled by 2 ** ``exposure`` (stops), then tone mapped with
    ``curve`` ("seed", "srgb" or "filmic"). The one display transform of every front end."""
    if curve not in _TONEMAPS:
        raise ValueError(f"unknown tone map {curve!r}; expected one of {', '.join(_TONEMAPS)}")
    if not np.isfinite(exposure):
        raise ValueError(f"exposure must be a finite number of stops, got {exposure!r}")
    img = np.asarray(img, dtype=np.float32)
    return _TONEMAPS[curve](img if exposure == 0 else img * np.float32(2.0 ** exposure))


def save_image(path: str | os.PathLike, img: np.ndarray, tonemap: str = "seed", exposure: float = 0.0) -> None:
    """Save a linear (H, W, 3) image; the format follows the extension (.png, .jpg, .npy, .pfm, .exr).

    ``.png`` and ``.jpg`` are tone mapped with ``tonemap`` ("seed", "srgb" or "filmic") after ``exposure``
    stops; ``.npy``, ``.pfm`` and ``.exr`` (optional ``openexr`` package) keep float32 linear
    radiance (no exposure: they hold the scene's light). The write is atomic (see :func:`atomic_write`).
    """
    ext = Path(path).suffix.lower()
    if ext not in _WRITERS:
        raise ValueError(f"{path}: unsupported image extension {ext!r}; supported: {', '.join(_WRITERS)}")
    if tonemap not in _TONEMAPS:
        raise ValueError(f"unknown tone map {tonemap!r}; expected one of {', '.join(_TONEMAPS)}")
    data = _check_rgb(img)
    if ext in _TONE_MAPPED:
        data = to_display(data, tonemap, exposure)
    atomic_write(path, lambda f: _WRITERS[ext](f, data))


def _pfm_header(f: BinaryIO, path) -> list[bytes]:
    """The four whitespace-separated header tokens (type, width, height, scale) of a PFM file."""
    tokens: list[bytes] = []
    tok = b""
    while len(tokens) < 4:
        c = f.read(1)
        if not c:
            raise ValueError(f"{path}: truncated PFM header")
        if c.isspace():
            if tok:
                tokens.append(tok)
                tok = b""
        else:
            tok += c
            if len(tok) > 32:
                raise ValueError(f"{path}: malformed PFM header")
    return tokens      # exactly one whitespace byte follows the scale, as the spec requires


def read_pfm(path: str | os.PathLike, max_texels: int | None = None) -> np.ndarray:
    """Read a PFM file ("PF" colour or "Pf" grey, either byte order) as float32 (H, W, 3), row 0 = top.
    The size its header declares is checked against the file's bytes (and ``max_texels``) before
    anything is read or allocated."""
    with open(path, "rb") as f:
        kind, w, h, scale = _pfm_header(f, path)
        if kind not in (b"PF", b"Pf"):
            raise ValueError(f"{path}: not a PFM file (magic {kind!r}, expected b'PF' or b'Pf')")
        try:
            width, height, s = int(w), int(h), float(scale)
        except ValueError:
            raise ValueError(f"{path}: malformed PFM header {w!r} {h!r} {scale!r}") from None
        if width < 1 or height < 1 or s == 0.0:
            raise ValueError(f"{path}: invalid PFM size {width}x{height} or scale {s}")
        channels = 3 if kind == b"PF" else 1
        count = width * height * channels
        if max_texels is not None and width * height > max_texels:
            raise ValueError(f"{path}: {width}x{height} = {width * height:,} texels, more than the texel budget "
                             f"of {max_texels:,}")
        left = os.fstat(f.fileno()).st_size - f.tell()
        if left < 4 * count:          # a header of 10^6 x 5x10^5 was read as 6 TB: "out of memory"
            raise ValueError(f"{path}: the PFM header declares {width}x{height}x{channels} floats: expected "
                             f"{4 * count} bytes of data after it, the file holds {left:,}")
        raw = f.read(4 * count)
    if len(raw) != 4 * count:
        raise ValueError(f"{path}: PFM data holds {len(raw)} bytes, expected {4 * count} ({width}x{height}x{channels} floats)")
    data = np.frombuffer(raw, dtype="<f4" if s < 0 else ">f4")
    img = data.reshape(height, width, channels)[::-1].astype(np.float32)
    return np.repeat(img, 3, axis=2) if channels == 1 else img


def load_image(path: str | os.PathLike) -> np.ndarray:
    """Read .npy / .pfm (float32 linear) or .png (uint8 RGB) as an (H, W, 3) array."""
    ext = Path(path).suffix.lower()
    if ext == ".npy":
        return _check_rgb(np.load(path, allow_pickle=False))
    if ext == ".pfm":
        return read_pfm(path)
    if ext in _TONE_MAPPED:
        from PIL import Image

        with Image.open(path) as im:
            return np.asarray(im.convert("RGB"), dtype=np.uint8)
    if ext == ".exr":
        import OpenEXR

        with OpenEXR.File(str(path)) as exr:
            return np.asarray(exr.channels()["RGB"].pixels, dtype=np.float32)
    raise ValueError(f"{path}: unsupported image extension {ext!r}; supported: .png, .jpg, .npy, .pfm, .exr")


def save_gif(path: str | Path, images: Sequence[np.ndarray], *, fps: float = 12.0, tonemap: str = "seed",
             exposure: float = 0.0) -> None:
    """Write images as an animated GIF preview, one adaptive palette per frame, atomically.

    Linear float images are tone mapped with ``tonemap`` after ``exposure`` stops; uint8 ones are
    taken as they are.
    """
    from PIL import Image


    if not images:
        raise ValueError("a GIF needs at least one frame")
    if tonemap not in _TONEMAPS:
        raise ValueError(f"unknown tone map {tonemap!r}; expected one of {', '.join(_TONEMAPS)}")
    pictures = [Image.fromarray(im if im.dtype == np.uint8 else to_display(im, tonemap, exposure)
                                ).convert("P", palette=Image.Palette.ADAPTIVE, colors=256) for im in images]
    duration = max(20, round(1000.0 / fps))

    def write(f) -> None:
        pictures[0].save(f, format="GIF", save_all=True, append_images=pictures[1:], duration=duration,
                         loop=0, optimize=True)

    atomic_write(path, write)


_WRITERS: dict[str, Callable[[BinaryIO, np.ndarray], None]] = {
    ".png": _write_png, ".npy": _write_npy, ".pfm": _write_pfm, ".exr": _write_exr,
    ".jpg": _write_jpeg, ".jpeg": _write_jpeg,
}
