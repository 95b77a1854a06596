"""The one result type of every render, and the one definition of an image's error.

:class:`RenderResult` holds the image, the per-pixel standard error and sample counts, the float64
film and :class:`RenderStats`. :func:`relative_error` is the one definition of "relative error of
the image" (docs/error.md), used by the CLI, target errors, the convergence report and the
benchmarks; :func:`batch_statistics` estimates per-pixel standard errors from independent batches.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from warp_spt.device.structs import Features
from warp_spt.rendering.film import Film
from warp_spt.rendering.settings import RenderSettings


@dataclass
class RenderStats:
    """What a render did (:func:`render_scene` and :func:`warp_spt.rendering.progressive.render_progressive`).

    ``seconds`` is wall time: for render_scene the launches (kernel compile excluded), for
    render_progressive the time since its ``started`` (upload and compile included);
    ``render_seconds`` is the launches only, for both. ``passes``, ``stopped_by`` and the per-pass
    lists describe progressive renders (a plain render is one pass stopped by its spp).
    """

    features: Features | None = None
    integrator: str = ""
    sampler: str = ""
    seconds: float = 0.0
    rays: int = 0             # closest-hit rays traced (shadow rays not counted)
    dropped_samples: int = 0  # non-finite samples discarded (should always be 0)
    tiles: int = 0
    threads: int = 1
    nonfinite_textures: tuple[str, ...] = ()   # procedural textures found returning NaN/inf (see proctex)
    passes: int = 1
    pixel_samples: int = 0
    render_seconds: float = 0.0
    stopped_by: str = "spp"   # "spp", "time", "error", "samples", "callback", "interrupt"
    setup_seconds: float = 0.0   # progressive: from ``started`` to the first launch (load, upload, compile)
    launches: int = 0
    pass_errors: list[float] = field(default_factory=list)   # estimated relative error after each pass
    pass_seconds: list[float] = field(default_factory=list)  # ``seconds`` at the end of each pass


@dataclass
class RenderResult:
    """Every render's result: the image, per-pixel standard error and sample counts, the sums, stats.

    ``image`` float32 (H, W, 3) linear radiance; ``std_error`` float32 (H, W, 3), the estimated
    standard error of each pixel's mean (NaN where there is no estimate: a plain :func:`render_scene`
    has one random stream per pixel and gives none; render_progressive gives one wherever two batches
    have samples); ``spp`` int64 (H, W) samples per pixel; ``relative_error`` the image's estimated
    relative error (docs/error.md; NaN without an estimate). ``film`` holds the float64 sums and
    sample count, which merge exactly (None when pixels have different counts: adaptive sampling).
    ``sums``/``counts`` are render_progressive's batch buffers, (B, H, W, 3) and (B, H, W).
    """

    film: Film | None
    stats: RenderStats
    settings: RenderSettings | None = field(repr=False, default=None)
    image: np.ndarray | None = field(repr=False, default=None)
    std_error: np.ndarray | None = field(repr=False, default=None)
    spp: np.ndarray | None = field(repr=False, default=None)
    relative_error: float = float("nan")
    sums: np.ndarray | None = field(repr=False, default=None)
    counts: np.ndarray | None = field(repr=False, default=None)

    def __post_init__(self) -> None:
        if self.image is None:
            self.image = self.film.image()
        h, w = self.image.shape[:2]
        if self.spp is None:
            self.spp = np.full((h, w), self.film.spp, dtype=np.int64)
        if self.std_error is None:
            self.std_error = np.full((h, w, 3), np.nan, dtype=np.float32)

    @property
    def spp_total(self) -> int:
        """Samples per pixel when every pixel has the same count, else the largest count."""
        return int(self.spp.max())

    @classmethod
    def from_batches(cls, sums: np.ndarray, counts: np.ndarray, stats: RenderStats,
                     settings: RenderSettings | None = None) -> "RenderResult":
        """A result from batch buffers (:func:`warp_spt.rendering.result.result_from_batches`)."""

        return result_from_batches(sums, counts, stats, settings)


ERROR_FLOOR_FRACTION = 0.1   # relative error divides by max(value, 0.1 x mean of the image)


def relative_error(error: np.ndarray, value: np.ndarray, floor_fraction: float = ERROR_FLOOR_FRACTION) -> float:
    """The relative error of an image: RMS over pixels and channels of ``error / max(value, floor)``.

    ``error`` is a standard-error map (the estimate) or ``image - reference`` (the measurement);
    ``value`` is the image (estimate) or the reference (measurement). ``floor`` is ``floor_fraction``
    (0.1) times the mean of ``value`` over all pixels and channels, so black and nearly black pixels
    count with the error they have relative to a typical pixel instead of dominating the RMS.
    Non-finite errors (pixels without an estimate) are skipped. Returns NaN when no pixel has one.
    """
    err = np.asarray(error, dtype=np.float64)
    val = np.asarray(value, dtype=np.float64)
    floor = max(floor_fraction * float(np.mean(val)), 1e-12)
    rel = err / np.maximum(val, floor)
    ok = np.isfinite(rel)
    return float(np.sqrt(np.mean(rel[ok] ** 2))) if ok.any() else float("nan")


STATS_BLOCK_PIXELS = 1 << 15   # pixels per block of batch_statistics: its temporaries stay in the cache


def batch_statistics(sums: np.ndarray, counts: np.ndarray, batches: slice | None = None):
    """Mean image and standard error of the mean from per-batch sums.

    ``sums`` (B, H, W, 3) float64, ``counts`` (B, H, W) samples per batch. The variance estimate is
    the between-batch mean square ``sum_b n_b (m_b - m)^2 / (k - 1)`` (k batches with samples),
    which is unbiased for the per-sample variance even with unequal batch sizes; divided by the
    pixel's sample count it estimates the variance of the mean. Pixels with fewer than two
    non-empty batches get NaN. Returns (mean, std_error, samples), float64.

    Computed in blocks of STATS_BLOCK_PIXELS pixels, a batch at a time: over the whole image at once,
    each step made a temporary as large as the batch buffers (1.2 GB at 2560 x 2560 with 8 batches)
    and a snapshot took 7-10 s, which is what --save-partial waited for after a Ctrl-C. The sums are
    formed in the same order, so the result is the same bit for bit.
    """
    if batches is not None:
        sums, counts = sums[batches], counts[batches]
    shape = counts.shape[1:]
    s, c = sums.reshape(len(sums), -1, 3), counts.reshape(len(counts), -1)
    mean, se, n = np.empty((c.shape[1], 3)), np.empty((c.shape[1], 3)), np.empty(c.shape[1], np.int64)
    for lo in range(0, c.shape[1], STATS_BLOCK_PIXELS):
        block = slice(lo, lo + STATS_BLOCK_PIXELS)
        mean[block], se[block], n[block] = _block_statistics(s[:, block], c[:, block])
    return mean.reshape(*shape, 3), se.reshape(*shape, 3), n.reshape(shape)


def _block_statistics(sums: np.ndarray, counts: np.ndarray):
    """:func:`batch_statistics` of (B, P, 3) sums and (B, P) counts, one batch at a time."""
    c = counts.astype(np.float64)[..., None]
    n = c.sum(axis=0)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = sums.sum(axis=0) / n
        between, d, k = np.zeros_like(mean), np.empty_like(mean), np.zeros(n.shape, np.int64)
        for s_b, c_b in zip(sums, c):
            has = c_b > 0
            if not has.any():       # adds exact zeros (a Ctrl-C in the first pass: 6 batches of 8 empty)
                continue
            d.fill(0.0)
            np.divide(s_b, c_b, out=d, where=has)       # the batch's mean, 0 where it has no samples
            d -= mean
            d *= d
            d *= c_b
            between += d
            k += has
        var = between / (k - 1) / n
        se = np.where(k >= 2, np.sqrt(var), np.nan)
    return np.nan_to_num(mean, nan=0.0), se, n[:, 0].astype(np.int64)


# The one result type is renderer.RenderResult (with RenderStats); these names stay for existing callers.
ProgressiveResult = RenderResult


ProgressiveStats = RenderStats


def result_from_batches(sums: np.ndarray, counts: np.ndarray, stats: RenderStats,
                        settings: RenderSettings | None = None) -> RenderResult:
    """A :class:`RenderResult` from batch buffers: mean image, standard errors, counts, relative error.

    ``film`` is the merged sums when every pixel has the same count (else None: adaptive sampling)."""
    mean, se, n = batch_statistics(sums, counts)
    film = Film(sums.sum(axis=0), int(n.flat[0])) if n.min() == n.max() else None
    return RenderResult(film, stats, settings, mean.astype(np.float32), se.astype(np.float32), n,
                        relative_error(se, mean), sums, counts)
