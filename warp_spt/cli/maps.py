"""The --error-map and --spp-map files: the linear map (.npy/.pfm/.exr) or a false-colour PNG with a legend.

A PNG map is the map itself, pixel for pixel, in the image's top-left corner, with a legend strip
below it: what the map shows, the colour bar, and the values at its quarter marks (the bar's colour
stops). A map narrower than LEGEND_MIN_WIDTH is padded on its right with the legend's background, so
the labels fit. Without the legend the colours had no values and docs/error.md described them wrongly
(black to white); the scale is the map's own maximum, which differs from file to file.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

# black -> blue -> red -> yellow -> white over 0 .. the maximum, evenly spaced
STOPS = ((0, 0, 0), (0, 0, 255), (255, 0, 0), (255, 255, 0), (255, 255, 255))
LEGEND_MIN_WIDTH = 240     # pixels the legend's title and five labels need
BACKGROUND, INK = (255, 255, 255), (0, 0, 0)
PAD, BAR_HEIGHT = 4, 10


def save_error_map(path: str, std_error: np.ndarray, image: np.ndarray) -> None:
    """--error-map: the standard error (linear; NaN where there is no estimate), or the relative error in
    false colour (per pixel, with the floor of :func:`warp_spt.rendering.result.relative_error`)."""
    _save(path, std_error, relative_map(std_error, image), "relative error", 100.0, "%")


def save_spp_map(path: str, spp: np.ndarray) -> None:
    """--spp-map: the samples per pixel (linear, the count in all three channels), or in false colour."""
    import numpy as np

    counts = spp.astype(np.float32)
    _save(path, np.repeat(counts[..., None], 3, axis=2), counts, "samples per pixel", 1.0, "")


def relative_map(std_error: np.ndarray, image: np.ndarray) -> np.ndarray:
    """Per-pixel relative error (RMS over channels), with the floor of rendering.result.relative_error;
    0 where there is no estimate."""
    import numpy as np

    from warp_spt.rendering.result import ERROR_FLOOR_FRACTION

    floor = max(ERROR_FLOOR_FRACTION * float(np.mean(image)), 1e-12)
    rel = np.nan_to_num(std_error / np.maximum(image, floor), nan=0.0)
    return np.sqrt(np.mean(rel**2, axis=2))


def false_colour(x: np.ndarray, vmax: float | None = None) -> np.ndarray:
    """A scalar map (H, W) as uint8 RGB: the STOPS over [0, vmax] (default: its maximum), linear between."""
    import numpy as np

    vmax = float(np.max(x)) if vmax is None else vmax
    t = np.clip(np.nan_to_num(x / vmax if vmax > 0 else x * 0.0), 0.0, 1.0)
    stops = np.array(STOPS, dtype=np.float64)
    pos = t * (len(stops) - 1)
    i = np.minimum(pos.astype(int), len(stops) - 2)
    f = (pos - i)[..., None]
    return (stops[i] * (1 - f) + stops[i + 1] * f + 0.5).astype(np.uint8)


def with_legend(img8: np.ndarray, vmax: float, title: str, scale: float = 1.0, unit: str = "") -> np.ndarray:
    """``img8`` (a false colour of 0 .. ``vmax``) above its legend: ``title``, the colour bar, and the
    values (times ``scale``, then ``unit``) at the colour stops, each under a tick on the bar."""
    import numpy as np
    from PIL import Image, ImageDraw, ImageFont

    font = ImageFont.load_default()
    text_height = font.getbbox("0123456789%Ay")[3]
    h, w = img8.shape[:2]
    width = max(w, LEGEND_MIN_WIDTH)
    canvas = Image.new("RGB", (width, h + 4 * PAD + BAR_HEIGHT + 2 * text_height), BACKGROUND)
    canvas.paste(Image.fromarray(img8), (0, 0))
    draw = ImageDraw.Draw(canvas)
    draw.text((PAD, h + PAD), title, fill=INK, font=font)
    x0, x1, y = PAD, width - PAD, h + 2 * PAD + text_height
    bar = false_colour(np.tile(np.linspace(0.0, 1.0, x1 - x0)[None, :], (BAR_HEIGHT, 1)), 1.0)
    canvas.paste(Image.fromarray(bar), (x0, y))
    y += BAR_HEIGHT
    for k, text in enumerate(tick_labels(scale * vmax, unit)):
        tick = x0 + round(k / (len(STOPS) - 1) * (x1 - x0 - 1))
        left = min(max(tick - draw.textlength(text, font=font) / 2, 0), width - draw.textlength(text, font=font))
        draw.line([(tick, y), (tick, y + PAD - 2)], fill=INK)
        draw.text((left, y + PAD), text, fill=INK, font=font)
    return np.asarray(canvas)


def tick_labels(top: float, unit: str = "") -> list[str]:
    """The values at the colour stops, 0 .. ``top``: as many decimals as give ``top`` three significant
    digits, fewer when every label would end in 0 (spp 0, 4, 8, 12, 16; errors 0.0% .. 11.2%)."""
    import math

    fractions = [k / (len(STOPS) - 1) for k in range(len(STOPS))]
    decimals = max(0, 2 - math.floor(math.log10(top))) if top > 0 else 0
    while decimals > 0 and all(f"{f * top:.{decimals}f}".endswith("0") for f in fractions):
        decimals -= 1
    return [f"{f * top:.{decimals}f}{unit}" for f in fractions]


def _save(path: str, linear: np.ndarray, scalar: np.ndarray, title: str, scale: float, unit: str) -> None:
    """``.png``: false colour of ``scalar`` over 0 .. its maximum, with the legend; else the linear map."""
    import numpy as np
    from PIL import Image

    from warp_spt.images.files import atomic_write, save_image

    if Path(path).suffix.lower() == ".png":
        vmax = float(np.max(scalar)) if scalar.size else 0.0
        img8 = with_legend(false_colour(scalar, vmax), vmax, title, scale, unit)
        atomic_write(path, lambda f: Image.fromarray(img8).save(f, format="PNG"))
    else:
        save_image(path, np.asarray(linear, dtype=np.float32))     # NaN where there is no estimate yet
