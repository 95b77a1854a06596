"""What the page shows: a linear image (or its error map) as 8-bit RGB, encoded for the wire.

Tone mapping is warp_spt's own (``tonemap_srgb`` / ``tonemap_seed``) after an exposure in stops,
so the view looks like the PNG the command line writes. Frames travel as JPEG: a noisy 512x384
frame is about 60 KB and 5 ms to encode, against 400 KB and 40 ms as PNG; saved images are exact.
"""

from __future__ import annotations

import io
import math

import numpy as np

JPEG_QUALITY = 90
ERROR_MAP_RANGE = (1e-2, 1.0)     # relative errors mapped to black .. white (log scale): 1% .. 100%
ERROR_FLOOR_FRACTION = 0.1        # as warp_spt.relative_error: divide by max(value, 0.1 x image mean)


def tonemapped(image: np.ndarray, exposure: float = 0.0, tonemap: str = "seed") -> np.ndarray:
    """uint8 (H, W, 3): the image after exposure (stops) and warp_spt's tone map ``"srgb"`` or ``"seed"``
    (:func:`warp_spt.images.files.to_display`, the CLI's --exposure too)."""
    import warp_spt

    return warp_spt.to_display(image, tonemap, exposure)


def relative_map(std_error: np.ndarray, image: np.ndarray) -> np.ndarray:
    """Per-pixel relative standard error (H, W), RMS over channels, with warp_spt.relative_error's
    floor; NaN where there is no estimate."""
    floor = max(ERROR_FLOOR_FRACTION * float(np.mean(image)), 1e-12)
    rel = np.asarray(std_error, dtype=np.float64) / np.maximum(image, floor)
    return np.sqrt(np.mean(rel ** 2, axis=2))


def error_colours(rel: np.ndarray) -> np.ndarray:
    """uint8 (H, W, 3) heat map of relative errors: black at ERROR_MAP_RANGE[0] through red and
    yellow to white at ERROR_MAP_RANGE[1], log scale; pixels without an estimate are dark blue."""
    lo, hi = (math.log10(v) for v in ERROR_MAP_RANGE)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = np.clip((np.log10(rel) - lo) / (hi - lo), 0.0, 1.0)
    rgb = np.stack([np.clip(3 * x, 0, 1), np.clip(3 * x - 1, 0, 1), np.clip(3 * x - 2, 0, 1)], axis=-1)
    rgb[~np.isfinite(rel)] = (0.1, 0.1, 0.35)
    return (rgb * 255 + 0.5).astype(np.uint8)


def despeckled(rgb8: np.ndarray) -> np.ndarray:
    """uint8 (H, W, 3): a 3x3 median per channel, which a moving preview is drawn through. A few
    samples per pixel leave lone black and white pixels (a path that found the light, or none);
    the median takes them out and keeps edges, where a blur would smear both (at equal samples it
    lowers the shown preview's RMS error by another 17%: docs/viewer.md)."""
    from PIL import Image, ImageFilter

    return np.asarray(Image.fromarray(np.ascontiguousarray(rgb8)).filter(ImageFilter.MedianFilter(3)))


def encode(rgb8: np.ndarray, fmt: str = "jpeg") -> bytes:
    """``rgb8`` as JPEG (frames) or PNG bytes."""
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(rgb8).save(buf, format=fmt.upper(), **({"quality": JPEG_QUALITY} if fmt == "jpeg" else {}))
    return buf.getvalue()
