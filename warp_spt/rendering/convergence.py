"""``warp-spt convergence``: how error falls with samples and time, per configuration, against a reference.

It renders (or reads) a high-sample reference, then renders at 1, 2, 4, ... N spp for each
configuration and reports, per row: RMSE and the relative error of the image (docs/error.md)
against the reference, the estimated relative error, seconds, and efficiency ``1 / (RMSE^2 x s)``;
per configuration: the fitted log-log slope of RMSE against spp, with a warning when it is far from
-0.5 (bias or a bug). It writes CSV and JSON, and a PNG plot when matplotlib is installed
(``pip install ".[plot]"`` in the clone).

Configurations are named ``INTEGRATOR/SAMPLER`` (``nee/sobol``; every pixel the same spp), with
``+adaptive`` (the same total number of samples, spent by adaptive sampling after a quarter of them
everywhere: equal work) or ``+denoised`` (the image through Open Image Denoise, when pyoidn is
installed: its RMSE shows the denoiser's error and bias, not a prettier picture). ``uniform``,
``adaptive`` and ``denoised`` alone mean the renderer's default integrator and sampler. The default
set is every integrator with every sampler, plus the default pair with ``+adaptive``.

The reference's own noise is estimated (its batches' standard error) and its mean square is
subtracted from each row's mean squared error, so the slope is not flattened by the reference
(``rmse`` is the corrected value, ``rmse_raw`` the plain one). A reference read from a file has
no error estimate; then nothing is subtracted.
"""

from __future__ import annotations

import csv
import io
import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

COLUMNS = ("config", "integrator", "sampler", "spp", "mean_spp", "seconds", "rmse", "rmse_raw", "relative_error",
           "estimated_relative_error", "efficiency")
SLOPE_TOLERANCE = 0.15      # |slope + 0.5| above this is reported as suspicious
MIN_TIMED_SECONDS = 0.05    # a row's render is repeated until this much time is measured (at most
                            # MAX_REPEATS times): one render of a small image takes a few ms, as long as
                            # the scheduler's noise, and the "error vs time" curve zig-zagged
MAX_REPEATS = 20
REF_SUFFIXES = (".npy", ".pfm")


@dataclass
class Row:
    """One render of one configuration (the CSV/JSON columns, documented in docs/error.md)."""

    config: str                      # INTEGRATOR/SAMPLER, with +adaptive or +denoised
    integrator: str
    sampler: str
    spp: int                         # nominal samples per pixel of this level
    mean_spp: float                  # samples actually taken, per pixel, on average
    seconds: float                   # render time (scene uploaded and kernel compiled beforehand)
    rmse: float                      # RMS error against the reference, its own noise subtracted
    rmse_raw: float                  # RMS error against the reference as it is
    relative_error: float            # progressive.relative_error(image - reference, reference)
    estimated_relative_error: float  # the renderer's own estimate (NaN for denoised, or below 2 spp)
    efficiency: float                # 1 / (rmse^2 * seconds)


@dataclass
class Fit:
    slope: float
    intercept: float
    warning: str | None


def fit_slope(spp: Sequence[float], error: Sequence[float]) -> Fit:
    """Least-squares line through (log spp, log error); a warning when the slope is far from -0.5."""
    x, y = np.log(np.asarray(spp, float)), np.log(np.asarray(error, float))
    ok = np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 2:
        return Fit(float("nan"), float("nan"), "fewer than two usable points")
    slope, intercept = np.polyfit(x[ok], y[ok], 1)
    warning = None
    if abs(slope + 0.5) > SLOPE_TOLERANCE:
        warning = (f"slope {slope:.2f} is far from -0.5: "
                   + ("error falls too slowly (bias, a reference that differs, or a bug)" if slope > -0.5
                      else "error falls faster than Monte Carlo allows (correlated samples or a denoiser)"))
    return Fit(float(slope), float(intercept), warning)


def levels(max_spp: int) -> list[int]:
    """1, 2, 4, ... up to max_spp (max_spp included even when not a power of two)."""
    out = [1 << k for k in range(max(1, max_spp).bit_length()) if (1 << k) <= max_spp]
    return out + ([max_spp] if out[-1] != max_spp else [])


def measure(config: str, integrator: str, sampler: str, spp: int, image: np.ndarray, reference: np.ndarray, ref_mse: float, seconds: float,
            mean_spp: float, estimated: float) -> Row:
    """The row for one image against the reference."""
    from warp_spt.rendering.result import relative_error

    diff = image.astype(np.float64) - reference
    raw = float(np.mean(diff**2))
    mse = max(raw - ref_mse, 0.0)
    rmse = math.sqrt(mse)
    eff = 1.0 / (mse * seconds) if mse > 0 and seconds > 0 else float("inf")
    return Row(config, integrator, sampler, spp, mean_spp, seconds, rmse, math.sqrt(raw), relative_error(diff, reference),
               estimated, eff)


def run_report(scene, camera, *, width: int, height: int, max_spp: int, reference_spp: int,
               reference: np.ndarray | None = None, configs: Sequence[str] | None = None,
               seed: int = 0, say=lambda msg: None, **render_kw) -> tuple[list[Row], dict[str, Fit], dict]:
    """Render the reference (unless given) and every configuration at every level; fit the slopes."""
    from warp_spt.upload.device_scene import DeviceScene
    from warp_spt.rendering.progressive import render_progressive

    dev = scene if isinstance(scene, DeviceScene) else DeviceScene(scene)
    configs = list(configs or default_configs())
    for c in configs:
        parse_config(c)
    kw = dict(width=width, height=height, **render_kw)
    ref_info: dict = {}
    if reference is None:
        t = time.perf_counter()
        ref = render_progressive(dev, camera, spp=reference_spp, seed=seed + 7919, **kw)
        reference = ref.image.astype(np.float64)
        ref_mse = float(np.nanmean(ref.std_error.astype(np.float64) ** 2))
        ref_info = dict(source="rendered", spp=reference_spp, seconds=time.perf_counter() - t,
                        estimated_relative_error=ref.relative_error, rms_std_error=math.sqrt(ref_mse))
        say(f"reference: {reference_spp} spp in {ref_info['seconds']:.1f} s, estimated relative error "
            f"{100 * ref.relative_error:.2f}%")
    else:
        ref_mse = 0.0
        ref_info = dict(source="file")
    if reference.shape != (height, width, 3):
        raise ValueError(f"reference is {reference.shape[1]}x{reference.shape[0]}, the render {width}x{height}")
    _warm_up(dev, camera, configs, kw)
    rows: list[Row] = []
    for i, spp in enumerate(levels(max_spp)):
        for config in configs:
            rows.append(_render_row(dev, camera, config, spp, seed + 1 + i, reference, ref_mse, kw))
            r = rows[-1]
            say(f"{config:>26} {spp:>6} spp: RMSE {r.rmse:.4g}, relative error {100 * r.relative_error:.2f}%, "
                f"{r.seconds:.3g} s")
    fits = {c: fit_slope([r.spp for r in rows if r.config == c], [r.rmse for r in rows if r.config == c])
            for c in configs}
    return rows, fits, ref_info


def parse_config(name: str) -> tuple[str, str, set[str]]:
    """``nee/sobol+adaptive`` -> ("nee", "sobol", {"adaptive"}); raises ValueError for unknown parts."""
    from warp_spt.integrators import DEFAULT_INTEGRATOR, INTEGRATORS
    from warp_spt.samplers import DEFAULT_SAMPLER, SAMPLERS

    base, *mods = name.split("+")
    if base in MODIFIERS or base == "uniform":
        mods, base = mods + ([base] if base in MODIFIERS else []), f"{DEFAULT_INTEGRATOR}/{DEFAULT_SAMPLER}"
    integrator, _, sampler = base.partition("/")
    if integrator not in INTEGRATORS or sampler not in SAMPLERS or not set(mods) <= set(MODIFIERS):
        raise ValueError(f"unknown configuration {name!r}: expected INTEGRATOR/SAMPLER[+adaptive|+denoised] with "
                         f"integrators {', '.join(sorted(INTEGRATORS))} and samplers {', '.join(sorted(SAMPLERS))}")
    return integrator, sampler, set(mods)


def default_configs() -> list[str]:
    """Every integrator the progressive renderer can render (not ``guided``, which trains over its
    own passes) with every sampler, and the renderer's default pair with +adaptive. Not ``volpath``
    (an integrator for media): on the scenes here, which have none, it renders nee's images."""
    from warp_spt.integrators import DEFAULT_INTEGRATOR, INTEGRATORS
    from warp_spt.samplers import DEFAULT_SAMPLER, SAMPLERS

    pairs = [f"{i}/{s}" for i in sorted(INTEGRATORS)
             if INTEGRATORS[i].render_passes is None and not INTEGRATORS[i].media for s in sorted(SAMPLERS)]
    return pairs + [f"{DEFAULT_INTEGRATOR}/{DEFAULT_SAMPLER}+adaptive"]


MODIFIERS = ("adaptive", "denoised")


def _warm_up(dev, camera, configs: Sequence[str], kw: dict) -> None:
    """Compile every configuration's kernels before anything is timed (a 2x2 render each)."""
    from warp_spt.rendering.progressive import render_progressive

    tiny = dict(kw, width=2, height=2)
    for config in configs:
        integrator, sampler, mods = parse_config(config)
        render_progressive(dev, camera, spp=2, **dict(tiny, integrator=integrator, sampler=sampler))
        if "denoised" in mods:
            from warp_spt.rendering.aux_buffers import feature_buffers

            feature_buffers(dev, camera, 2, 2, spp=1, features=kw.get("features"))


def _render_row(dev, camera, config: str, spp: int, seed: int, reference, ref_mse: float, kw) -> Row:
    from warp_spt.rendering.progressive import render_progressive

    integrator, sampler, mods = parse_config(config)
    kw = dict(kw, integrator=integrator, sampler=sampler)

    def render():
        if "adaptive" in mods:
            res = render_progressive(dev, camera, spp=16 * spp, sample_budget=spp * kw["width"] * kw["height"],
                                     adaptive=True, min_spp=max(1, spp // 4), seed=seed, **kw)
        else:
            res = render_progressive(dev, camera, spp=spp, seed=seed, **kw)
        image, estimated = res.image, res.relative_error
        if "denoised" in mods:
            from warp_spt.rendering.aux_buffers import feature_buffers
            from warp_spt.rendering.denoise import denoise

            aux = feature_buffers(dev, camera, kw["width"], kw["height"], seed=seed,
                                  texture_filter=kw.get("texture_filter", "nearest"), features=kw.get("features"))
            image, estimated = denoise(res.image, *aux), float("nan")
        return res, image, estimated

    (res, image, estimated), seconds = timed(render)
    return measure(config, integrator, sampler, spp, image, reference, ref_mse, seconds, float(res.spp.mean()),
                   estimated)


def timed(render):
    """(``render()``'s value, seconds per call): called again (the same seed: the same image) until
    MIN_TIMED_SECONDS are measured or MAX_REPEATS calls were made, and the mean taken."""
    t = time.perf_counter()
    value, calls = render(), 1
    while time.perf_counter() - t < MIN_TIMED_SECONDS and calls < MAX_REPEATS:
        render()
        calls += 1
    return value, (time.perf_counter() - t) / calls


# ---------------------------------------------------------------------------------------------
# Output


def write_csv(path: str | Path, rows: Sequence[Row]) -> None:
    from warp_spt.images.files import atomic_write

    buf = io.StringIO()
    w = csv.writer(buf)
    w.writerow(COLUMNS)
    for r in rows:
        w.writerow([getattr(r, c) for c in COLUMNS])
    atomic_write(path, lambda f: f.write(buf.getvalue().encode()))


def write_json(path: str | Path, rows: Sequence[Row], fits: dict[str, Fit], meta: dict) -> None:
    from warp_spt.images.files import atomic_write

    doc = dict(meta, columns=list(COLUMNS), rows=[asdict(r) for r in rows],
               fits={k: asdict(v) for k, v in fits.items()})
    text = json.dumps(doc, indent=1, default=float, allow_nan=True)
    atomic_write(path, lambda f: f.write(text.encode()))


def write_plot(path: str | Path, rows: Sequence[Row], fits: dict[str, Fit], title: str = "") -> None:
    """Error against spp and against seconds, one line per configuration (needs matplotlib)."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        from warp_spt.runtime.extras import install_hint
        raise RuntimeError(f"the PNG plot needs matplotlib: {install_hint('plot')} "
                           "(or use --no-plot; the CSV and JSON are written anyway)") from None
    from warp_spt.images.files import atomic_write

    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    # small images render in milliseconds: label the time axis in them rather than in 2x10^-3 s
    unit, scale = ("milliseconds", 1e3) if max(r.seconds for r in rows) < 1.0 else ("seconds", 1.0)
    for config, fit in fits.items():
        rs = [r for r in rows if r.config == config and r.rmse > 0]
        label = f"{config} (slope {fit.slope:.2f})"
        axes[0].loglog([r.mean_spp for r in rs], [r.rmse for r in rs], "o-", label=label)
        axes[1].loglog([scale * r.seconds for r in rs], [r.rmse for r in rs], "o-", label=config)
    xs = np.array([min(r.mean_spp for r in rows), max(r.mean_spp for r in rows)])
    first = [r for r in rows if r.config == next(iter(fits))][0]
    axes[0].loglog(xs, first.rmse * (xs / first.mean_spp) ** -0.5, "k:", label="slope -0.5")
    axes[0].set(xlabel="samples per pixel", ylabel="RMSE vs reference", title="error vs samples")
    axes[1].set(xlabel=unit, ylabel="RMSE vs reference", title="error vs time")
    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=8)
        _plain_log_ticks(ax)
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    atomic_write(path, lambda f: f.write(buf.getvalue()))


def _plain_log_ticks(ax) -> None:
    """Plain numbers on both log axes, at 1, 2 and 5 x 10^k over a short range and at powers of ten over
    a long one: matplotlib's default labelled every minor tick of a short range in scientific notation,
    and at small image sizes the labels of the time axis ran into each other."""
    from matplotlib.ticker import FuncFormatter, LogLocator

    for axis, (lo, hi) in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
        subs = (1.0, 2.0, 5.0) if math.log10(hi / lo) <= 2.5 else (1.0,)
        axis.set_major_locator(LogLocator(base=10, subs=subs))
        axis.set_major_formatter(FuncFormatter(lambda v, _: f"{v:g}"))
        axis.set_minor_formatter(FuncFormatter(lambda v, _: ""))


# ---------------------------------------------------------------------------------------------
# Command line


