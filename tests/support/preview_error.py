"""How well a moving preview shows the view: the error of the picture the page draws (the preview
tone mapped, then stretched over the view as the canvas does) against a converged image of the view,
at a given number of samples (equal samples: equal time, measured by scripts/measure_viewer_preview.py).

The reference is two renders of independent seeds; their mean is the converged image, and half of
their difference's mean square estimates the reference's own noise in that mean, which is taken
off each preview's mean square error (it adds the same to every plan).
"""

from __future__ import annotations

import statistics
import time

import numpy as np

import warp_spt


def shown(image: np.ndarray, view: tuple[int, int], tonemap: str = "seed", despeckle: bool = False) -> np.ndarray:
    """float (H, W, 3) in [0, 1]: ``image`` tone mapped to 8 bits (``despeckle``: through the
    session's preview filter), stretched to ``view`` = (width, height) bilinearly (the canvas's
    smoothing), as the page shows it."""
    from PIL import Image

    from warp_spt.viewer.display import despeckled

    rgb8 = warp_spt.to_display(image, tonemap, 0.0)
    if despeckle:
        rgb8 = despeckled(rgb8)
    if rgb8.shape[1] != view[0] or rgb8.shape[0] != view[1]:
        rgb8 = np.asarray(Image.fromarray(rgb8).resize(view, Image.BILINEAR))
    return rgb8.astype(np.float64) / 255.0


def render(dev, camera, view: tuple[int, int], spp: int, seed: int, **settings) -> tuple[np.ndarray, float]:
    """(linear image, seconds) of one render of ``view`` pixels at ``spp``."""
    rs = warp_spt.RenderSettings(width=view[0], height=view[1], spp=spp, seed=seed, **settings)
    start = time.perf_counter()
    image = warp_spt.render_scene(dev, camera, rs).image
    return image, time.perf_counter() - start


class Reference:
    """The converged view: two renders of ``spp`` each, independent seeds."""

    def __init__(self, dev, camera, view: tuple[int, int], spp: int, tonemap: str = "seed", **settings):
        a, b = (render(dev, camera, view, spp, 10_000 + k, **settings)[0] for k in range(2))
        self.view, self.tonemap = view, tonemap
        sa, sb = shown(a, view, tonemap), shown(b, view, tonemap)
        self.image = 0.5 * (sa + sb)
        self.noise_ms = float(np.mean((sa - sb) ** 2)) / 4.0     # mean square noise of the mean of two

    def rmse(self, preview: np.ndarray, despeckle: bool = False) -> float:
        """RMS error of the shown ``preview`` (linear, any size), the reference's noise taken off."""
        ms = float(np.mean((shown(preview, self.view, self.tonemap, despeckle) - self.image) ** 2)) - self.noise_ms
        return float(np.sqrt(max(ms, 0.0)))


def plan_error(dev, camera, reference: Reference, size: tuple[int, int], spp: int, trials: int,
               **settings) -> dict:
    """A preview plan's error over ``trials`` seeds: mean RMSE and its standard error, drawn as it
    renders ("raw") and through the session's filter ("shown"), and the median seconds."""
    errors: dict = {"raw": [], "shown": []}
    seconds = []
    for seed in range(trials):
        image, took = render(dev, camera, size, spp, seed, **settings)
        errors["raw"].append(reference.rmse(image))
        errors["shown"].append(reference.rmse(image, despeckle=True))
        seconds.append(took)
    out = {"size": size, "spp": spp, "samples": size[0] * size[1] * spp, "seconds": statistics.median(seconds)}
    for kind, values in errors.items():
        out[kind] = statistics.fmean(values)
        out[kind + "_se"] = statistics.stdev(values) / np.sqrt(trials) if trials > 1 else float("nan")
    return out
