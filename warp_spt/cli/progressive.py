"""The CLI's error, budget and adaptive-sampling flags (issue 9), kept apart from cli.py.

cli.py calls :func:`add_flags` on its parser, :func:`options` on the parsed namespace, and
:func:`render_and_save` instead of its plain render when :attr:`BudgetOptions.active`. The time
budget counts from the start of the process (:func:`process_start`), so it covers Python's start-up,
loading the scene and compiling the kernel, and the render stops early enough for the measured cost
of saving (:func:`finish_seconds`): the wall time the user sees (docs/error.md, "Budgets").
"""

from __future__ import annotations

import argparse
import math
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Callable

if TYPE_CHECKING:
    import numpy as np

# Only the standard library at import time (cli.py imports this module at its top; on main, cli.py
# installs its signal handling before numpy and Warp load), so numpy is imported where it is used.
MAP_SUFFIXES = (".npy", ".pfm", ".exr", ".png")


@dataclass(frozen=True)
class BudgetOptions:
    """The parsed flags; ``active`` when any of them asks for the progressive renderer."""

    time_budget: float | None = None
    target_error: float | None = None
    adaptive: bool = False
    min_spp: int | None = None
    save_partial: bool = False
    progressive: str | None = None
    error_map: str | None = None
    spp_map: str | None = None
    spp_given: bool = False
    denoise: bool = False
    adaptive_metric: str | None = None

    @property
    def active(self) -> bool:
        return any((self.time_budget, self.target_error, self.adaptive, self.save_partial, self.progressive,
                    self.error_map, self.spp_map, self.min_spp, self.denoise))


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number, got {text!r}")
    return value


def _fraction(text: str) -> float:
    """0.01 or 1%."""
    percent = text.endswith("%")
    value = _positive_float(text[:-1] if percent else text)
    return value / 100 if percent else value


def _metric(text: str) -> str:
    from warp_spt.rendering.progressive import ADAPTIVE_METRICS

    if text not in ADAPTIVE_METRICS:
        raise argparse.ArgumentTypeError(f"expected one of {', '.join(ADAPTIVE_METRICS)}, got {text!r}")
    return text


def add_flags(parser: argparse.ArgumentParser, int_at_least: Callable) -> None:
    """The issue-9 flags, as their own argument group."""
    g = parser.add_argument_group("error, budgets and adaptive sampling (docs/error.md)")
    g.add_argument("--time-budget", type=_positive_float, metavar="SECONDS",
                   help="end this many seconds after the command started (start-up, load, compile, saving "
                        "and exit included); -sr becomes a maximum")
    g.add_argument("--target-error", type=_fraction, metavar="E",
                   help="stop when the estimated relative error of the image is at most E (0.01 or 1%%)")
    g.add_argument("--adaptive", action="store_true",
                   help="after --min-spp, spend passes on the pixels whose estimated error is high "
                        "(opt-in; it lowers the error --adaptive-metric names; docs/error.md)")
    g.add_argument("--adaptive-metric", type=_metric, metavar="relative|rmse",
                   help="what --adaptive minimises: the relative error of the image (default; what "
                        "--target-error and the final line measure) or the RMSE (samples in proportion to "
                        "each pixel's absolute noise)")
    g.add_argument("--min-spp", type=int_at_least(1), metavar="N", help="samples every pixel gets (default 16)")
    g.add_argument("--save-partial", action="store_true",
                   help="on Ctrl-C, write the image accumulated so far instead of nothing")
    g.add_argument("--progressive", metavar="PATH", help="rewrite this image after every pass")
    g.add_argument("--error-map", metavar="PATH",
                   help="write the per-pixel standard error (.npy/.pfm linear, .png false colour of the "
                        "relative error)")
    g.add_argument("--spp-map", metavar="PATH", help="write the samples per pixel (.npy/.pfm, or .png false colour)")
    g.add_argument("--denoise", action="store_true",
                   help="denoise the output with Intel Open Image Denoise (needs pyoidn: warp-spt[denoise]); "
                        "the error line and maps describe the image before denoising")


def options(ns: argparse.Namespace, usage_error: Callable[[str], Exception],
            image_suffixes: tuple[str, ...]) -> BudgetOptions:
    """Validate the flags of :func:`add_flags` (suffixes only: files are checked before rendering)."""
    for flag, path, allowed in (("--progressive", ns.progressive, image_suffixes),
                                ("--error-map", ns.error_map, MAP_SUFFIXES), ("--spp-map", ns.spp_map, MAP_SUFFIXES)):
        if path is not None and Path(path).suffix.lower() not in allowed:
            raise usage_error(f"{flag} {path!r}: the file name must end in {', '.join(allowed)}")
        if path is not None and Path(path).suffix.lower() == ".exr":
            import importlib.util
            if importlib.util.find_spec("OpenEXR") is None:
                raise usage_error(f"{flag} {path!r}: writing .exr needs the optional openexr package "
                                  "(pip install 'warp-spt[exr]')")
    if ns.adaptive_metric is not None and not ns.adaptive:
        raise usage_error("--adaptive-metric needs --adaptive")
    return BudgetOptions(ns.time_budget, ns.target_error, ns.adaptive, ns.min_spp, ns.save_partial, ns.progressive,
                         ns.error_map, ns.spp_map, ns.sr is not None, ns.denoise, ns.adaptive_metric)


def extra_outputs(b: BudgetOptions) -> list[tuple[str, str]]:
    """(flag, path) of every further file the render writes (for the early writability check)."""
    return [(f, p) for f, p in (("--progressive", b.progressive), ("--error-map", b.error_map),
                                ("--spp-map", b.spp_map)) if p]


def check_outputs(b: BudgetOptions, error: Callable[[str], Exception]) -> None:
    """Fail before rendering when a further output cannot be written."""
    for flag, path in extra_outputs(b):
        parent = Path(path).parent
        if not parent.is_dir():
            raise error(f"cannot write {flag} {path!r}: directory {str(parent)!r} does not exist")
        if Path(path).is_dir():
            raise error(f"cannot write {flag} {path!r}: it is a directory")


def render_and_save(opts, scene, *, say: Callable[[str], None], started: float) -> int:
    """Render ``opts`` progressively, save the image and maps, and report the relative error.

    Returns the exit status: 0, or 130 after a Ctrl-C with --save-partial (the partial image written).
    """
    import numpy as np

    from warp_spt.core.device_scene import DeviceScene
    from warp_spt.io.images import save_image
    from warp_spt.rendering.progressive import render_progressive

    b: BudgetOptions = opts.budget
    dev = scene if isinstance(scene, DeviceScene) else DeviceScene(scene)   # the CLI hands it uploaded
    aux = None
    if b.denoise:
        from warp_spt.rendering.aux_buffers import feature_buffers
        from warp_spt.rendering.denoise import require

        require()                         # before rendering, not after minutes of it
        # before the render too, so that their kernel's compile counts against --time-budget
        aux = feature_buffers(dev, opts.camera, opts.width, opts.height, seed=opts.seed,
                              texture_filter=opts.texture_filter)
    spp = opts.spp if (b.spp_given or not (b.time_budget or b.target_error)) else None
    # The render's deadline leaves room for what follows its last pass: saving the outputs and exiting.
    reserve, render_budget = 0.0, None
    if b.time_budget is not None:
        reserve = finish_seconds(opts.out, opts.width, opts.height, opts.tonemap, 1 + bool(b.error_map) + bool(b.spp_map),
                                 denoise=b.denoise)
        render_budget = max(b.time_budget - reserve, 1e-3)

    def on_pass(res) -> None:
        say(f"pass {res.stats.passes}: {_spp_text(res.spp)}, {res.stats.seconds:.1f} s, "
            f"estimated relative error {_pct(res.relative_error)}")
        if b.progressive:
            save_image(b.progressive, res.image, tonemap=opts.tonemap)

    res = render_progressive(dev, opts.camera, width=opts.width, height=opts.height, spp=spp,
                             max_depth=opts.depth, sky=opts.sky, seed=opts.seed, threads=opts.threads,
                             texture_filter=opts.texture_filter, time_budget=render_budget,
                             target_error=b.target_error, adaptive=b.adaptive, min_spp=b.min_spp,
                             **({"adaptive_metric": b.adaptive_metric} if b.adaptive_metric else {}),
                             on_pass=on_pass, keep_partial=b.save_partial, started=started,
                             **{k: v for k, v in (("integrator", opts.integrator), ("sampler", opts.sampler)) if v})
    image = res.image
    if b.denoise:
        from warp_spt.rendering.denoise import denoise

        image = denoise(res.image, *aux)
        say("denoised with Intel Open Image Denoise (albedo and normal of the first non-specular hit): the image "
            "is smoother but biased; the error figures below are those of the image before denoising")
    save_image(opts.out, image, tonemap=opts.tonemap)
    if b.error_map:
        save_map(b.error_map, res.std_error, relative_map(res.std_error, res.image))
    if b.spp_map:
        counts = res.spp.astype(np.float32)
        save_map(b.spp_map, np.repeat(counts[..., None], 3, axis=2), counts / max(1.0, float(counts.max())))
    s = res.stats
    if render_budget is not None and s.pass_seconds and s.pass_seconds[0] > render_budget:
        say(f"warning: --time-budget {b.time_budget:g} s is less than start-up ({s.setup_seconds:.1f} s: Python, Warp, "
            f"loading, compiling) plus one pass ({s.pass_seconds[0] - s.setup_seconds:.1f} s) plus saving "
            f"({reserve:.1f} s) here; the image has the first pass's {res.spp_total} spp")
    rate = s.pixel_samples / max(s.render_seconds, 1e-9)
    say(f"wrote {opts.out} ({_spp_text(res.spp)}, {s.seconds:.1f} s since start, {rate / 1e6:.2f} M samples/s, "
        f"stopped by {s.stopped_by})")
    say(f"estimated relative error of the image: {_pct(res.relative_error)} (RMS of standard error / "
        f"max(value, 0.1 x mean); docs/error.md)")
    if s.stopped_by == "interrupt":
        say("interrupted: the partial image was saved (--save-partial)")
        return 130
    return 0


EXIT_SECONDS = 0.1     # from the last file written to the end of the process (__main__._exit_now)


def finish_seconds(out: str, width: int, height: int, tonemap: str, images: int, denoise: bool = False) -> float:
    """Seconds the command needs after its last pass: denoising (with ``denoise``), writing ``images``
    images like ``out`` and exiting.

    Measured here by encoding an image of noise of the output's size in memory the way the writer
    will (tone map and PNG/JPEG encode, or the float32 copy of .npy/.pfm/.exr; noise compresses
    worst, so this errs long), plus EXIT_SECONDS, plus :func:`warp_spt.rendering.denoise.seconds` (measured
    on a small probe when pyoidn is there, else a conservative figure).
    """
    import io

    import numpy as np

    from warp_spt.io.images import tonemap_seed, tonemap_srgb

    t = time.perf_counter()
    blank = np.random.default_rng(0).random((height, width, 3), dtype=np.float32)
    buf = io.BytesIO()
    fmt = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG"}.get(Path(out).suffix.lower())
    if fmt is None:
        np.save(buf, blank)
    else:
        from PIL import Image

        Image.fromarray((tonemap_srgb if tonemap == "srgb" else tonemap_seed)(blank)).save(buf, format=fmt)
    seconds = images * (time.perf_counter() - t) + EXIT_SECONDS
    if denoise:
        from warp_spt.rendering.denoise import seconds as denoise_seconds

        seconds += denoise_seconds(width, height)
    return seconds


def process_start() -> float:
    """When this process started, as a ``time.perf_counter()`` value (Linux: from /proc; elsewhere: now).

    Python's start-up and the import of Warp take a second or two before ``main()`` runs; the
    time budget targets the wall time the user sees, so it counts them too where it can.
    """
    now = time.perf_counter()
    try:
        ticks = os.sysconf("SC_CLK_TCK")
        with open("/proc/self/stat", "rb") as f:
            start_ticks = int(f.read().rsplit(b")", 1)[1].split()[19])
        with open("/proc/uptime", "rb") as f:
            uptime = float(f.read().split()[0])
        age = uptime - start_ticks / ticks
        return now - age if 0.0 <= age < 3600.0 else now
    except (OSError, ValueError, IndexError, AttributeError):
        return now


def _pct(e: float) -> str:
    return "n/a (needs 2 spp)" if not math.isfinite(e) else f"{100 * e:.2f}%"


def _spp_text(spp: np.ndarray) -> str:
    lo, hi = int(spp.min()), int(spp.max())
    return f"{lo} spp" if lo == hi else f"{lo}..{hi} spp (mean {float(spp.mean()):.1f})"


def relative_map(std_error: np.ndarray, image: np.ndarray) -> np.ndarray:
    """Per-pixel relative error (mean over channels), with the floor of progressive.relative_error."""
    import numpy as np

    from warp_spt.rendering.result import ERROR_FLOOR_FRACTION

    floor = max(ERROR_FLOOR_FRACTION * float(np.mean(image)), 1e-12)
    rel = np.nan_to_num(std_error / np.maximum(image, floor), nan=0.0)
    return np.sqrt(np.mean(rel**2, axis=2))


def false_colour(x: np.ndarray, vmax: float | None = None) -> np.ndarray:
    """A scalar map (H, W) as uint8 RGB: black -> blue -> red -> yellow -> white over [0, vmax]."""
    import numpy as np

    vmax = float(np.max(x)) if vmax is None else vmax
    t = np.clip(np.nan_to_num(x / vmax if vmax > 0 else x * 0.0), 0.0, 1.0)
    stops = np.array([[0, 0, 0], [0, 0, 255], [255, 0, 0], [255, 255, 0], [255, 255, 255]], dtype=np.float64)
    pos = t * (len(stops) - 1)
    i = np.minimum(pos.astype(int), len(stops) - 2)
    f = (pos - i)[..., None]
    return (stops[i] * (1 - f) + stops[i + 1] * f + 0.5).astype(np.uint8)


def save_map(path: str, linear: np.ndarray, scalar: np.ndarray) -> None:
    """``.npy``/``.pfm``/``.exr``: the linear (H, W, 3) map; ``.png``: false colour of ``scalar`` (0 .. its max)."""
    import numpy as np
    from PIL import Image

    from warp_spt.io.images import atomic_write, save_image

    if Path(path).suffix.lower() == ".png":
        img8 = false_colour(scalar)
        atomic_write(path, lambda f: Image.fromarray(img8).save(f, format="PNG"))
    else:
        save_image(path, np.asarray(linear, dtype=np.float32))     # NaN where there is no estimate yet
