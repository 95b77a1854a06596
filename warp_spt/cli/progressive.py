"""The runner of budgeted and progressive renders: passes until a sample count, a time or an error.

:mod:`warp_spt.cli.render` calls :func:`render_and_save` instead of its plain render when
:attr:`warp_spt.cli.budget_flags.BudgetOptions.active`. The time
budget counts from the start of the process (:func:`process_start`), so it covers Python's start-up,
loading the scene and compiling the kernel, and the render stops early enough for the measured cost
of saving (:func:`finish_seconds`): the wall time the user sees (docs/error.md, "Budgets").
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Callable, TextIO

from warp_spt.cli.budget_flags import BudgetOptions
from warp_spt.cli.common import EXIT_TERMINATED, PROG, one_line
from warp_spt.runtime.signals import cli_interruption, exit_status

if TYPE_CHECKING:
    import numpy as np


def render_and_save(opts, scene, *, say: Callable[[str], None], started: float, err: TextIO | None = None) -> int:
    """Render ``opts`` progressively, save the image and maps, and report the relative error.

    Returns the exit status: 0, or 130 after a Ctrl-C (143 after SIGTERM) with --save-partial (the partial
    image written).
    ``err`` is where ``say`` writes (default stderr): on a terminal the passes rewrite one line there.
    """
    from warp_spt.cli.maps import save_error_map, save_spp_map
    from warp_spt.upload.device_scene import DeviceScene
    from warp_spt.images.files import save_image

    b: BudgetOptions = opts.budget
    dev = scene if isinstance(scene, DeviceScene) else DeviceScene(scene)   # the CLI hands it uploaded
    aux = None
    if b.denoise:                         # pyoidn is there (run_image checked, budget_flags.check_denoiser)
        from warp_spt.rendering.aux_buffers import feature_buffers

        # before the render, so that their kernel's compile counts against --time-budget
        aux = feature_buffers(dev, opts.camera, opts.width, opts.height, seed=opts.seed,
                              texture_filter=opts.texture_filter)
    spp = opts.spp if (b.spp_given or not (b.time_budget or b.target_error)) else None
    # The render's deadline leaves room for what follows its last pass: saving the outputs and exiting.
    reserve, render_budget = 0.0, None
    if b.time_budget is not None:
        reserve = finish_seconds(opts.out, opts.width, opts.height, opts.tonemap, 1 + bool(b.error_map) + bool(b.spp_map),
                                 denoise=b.denoise)
        render_budget = max(b.time_budget - reserve, 1e-3)
    line = PassLine(say, err or sys.stderr, live=not (opts.quiet or opts.verbose))
    side = SideOutputs(before=line.close)
    try:
        res = _render_passes(opts, dev, spp, render_budget, started, line, side)
    finally:
        line.close()                      # what follows (an error, "interrupted") starts a line of its own
    image = res.image
    if b.denoise:
        from warp_spt.rendering.denoise import denoise

        image = denoise(res.image, *aux)
        say("denoised with Intel Open Image Denoise (albedo and normal of the first non-specular hit; "
            "--no-denoise for the raw render): the image is smoother but biased; the error figures below are "
            "those of the image before denoising")
    save_image(opts.out, image, tonemap=opts.tonemap, exposure=opts.exposure)      # the main output first, then the side outputs
    if b.error_map:
        side.write("--error-map", b.error_map, lambda: save_error_map(b.error_map, res.std_error, res.image))
    if b.spp_map:
        side.write("--spp-map", b.spp_map, lambda: save_spp_map(b.spp_map, res.spp))
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
    if s.stopped_by == "interrupt":      # Ctrl-C: 130, SIGTERM: 143, as without --save-partial
        status = exit_status(cli_interruption() or KeyboardInterrupt())
        word = "terminated" if status == EXIT_TERMINATED else "interrupted"
        say(f"{word}: saved the partial image (--save-partial): {_unsampled(res.spp)}")
        return status
    return 0


def _unsampled(spp: np.ndarray) -> str:
    """How many pixels of a partial image have no samples (a Ctrl-C lands inside a pass, which renders
    runs of pixels in turn): they are black in the saved image."""
    empty = int((spp == 0).sum())
    if not empty:
        return "every pixel has samples"
    return f"{empty:,} of {spp.size:,} pixels have no samples yet (black)"


def _render_passes(opts, dev, spp: int | None, render_budget: float | None, started: float, line: PassLine,
                   side: SideOutputs):
    """render_progressive as ``opts`` asks, showing each pass on ``line`` and writing --progressive."""
    from dataclasses import fields

    from warp_spt.cli.options import settings_of
    from warp_spt.images.files import save_image
    from warp_spt.rendering.progressive import render_progressive

    b: BudgetOptions = opts.budget
    spp_max = None if b.adaptive else spp       # adaptive: -sr bounds each pixel, not the mean

    def on_pass(res) -> None:
        if b.progressive:
            side.write("--progressive", b.progressive,
                       lambda: save_image(b.progressive, res.image, tonemap=opts.tonemap, exposure=opts.exposure))
        line.show(pass_status(res, b.target_error, spp_max, render_budget))

    rs = settings_of(opts, spp=spp)
    # the batches own the sample indices and the tiling: every other setting as the command gave it
    settings = {f.name: getattr(rs, f.name) for f in fields(rs) if f.name not in ("sample_offset", "tile_pixels")}
    return render_progressive(dev, opts.camera, time_budget=render_budget, target_error=b.target_error,
                              adaptive=b.adaptive, min_spp=b.min_spp,
                              **({"adaptive_metric": b.adaptive_metric} if b.adaptive_metric else {}),
                              on_pass=on_pass, keep_partial=b.save_partial, started=started, **settings)


def pass_status(res, target: float | None, spp_max: int | None, budget: float | None) -> str:
    """The progress after a pass, short enough for a terminal's line: samples, seconds since start, the
    estimated relative error (and its target), and the time to go (:func:`time_to_go`), naming the
    limit that will end the render when there are several."""
    s = res.stats
    text = f"pass {s.passes}: {_spp_text(res.spp)}, {s.seconds:.1f} s, error {_pct(res.relative_error)}"
    if target is not None:
        text += f" (target {_pct(target)})"
    end = time_to_go(res, target, spp_max, budget)
    if end is None:
        return text
    several = sum(x is not None for x in (target, spp_max, budget)) > 1
    return text + f", about {_duration(end[0])} to go" + (f" ({end[1]})" if several else "")


def time_to_go(res, target: float | None, spp_max: int | None, budget: float | None) -> tuple[float, str] | None:
    """(seconds, limit) until the soonest of the render's limits: -sr ``spp_max`` samples, the ``target``
    error (the spp it needs by the 1/sqrt(spp) law, :func:`warp_spt.rendering.progressive.spp_for_error`),
    the end of ``budget`` (seconds since start). Samples cost what they have cost so far: the seconds since
    the first pass began over the mean spp. None before any estimate."""
    from warp_spt.rendering.progressive import spp_for_error

    s, spp = res.stats, float(res.spp.mean())
    if spp <= 0 or s.seconds <= s.setup_seconds:
        return None
    per_spp = (s.seconds - s.setup_seconds) / spp
    ends = []
    if spp_max is not None:
        ends.append((per_spp * max(0.0, spp_max - spp), f"-sr {spp_max}"))
    if target is not None and math.isfinite(res.relative_error):
        ends.append((per_spp * max(0.0, spp_for_error(spp, res.relative_error, target) - spp), "--target-error"))
    if budget is not None:
        ends.append((max(0.0, budget - s.seconds), "--time-budget"))
    return min(ends) if ends else None


def _duration(seconds: float) -> str:
    if seconds < 10:
        return f"{seconds:.1f} s"
    if seconds < 120:
        return f"{seconds:.0f} s"
    return f"{seconds / 60:.0f} min" if seconds < 7200 else f"{seconds / 3600:.1f} h"


class PassLine:
    """Where the passes are shown: on a terminal one line, rewritten after every pass (dozens of "pass N"
    lines said less than the last one); a line per pass into a log (stderr not a terminal) or with
    --verbose (``live`` False); nothing with --quiet (``say`` says nothing)."""

    def __init__(self, say: Callable[[str], None], err: TextIO, *, live: bool) -> None:
        self.say, self.err = say, err
        self.live = live and getattr(err, "isatty", lambda: False)()
        self.open = False         # a rewritten line is on the terminal, without its newline

    def show(self, text: str) -> None:
        if not self.live:
            self.say(text)
            return
        import shutil

        # cut to the terminal's width: a carriage return goes back to the start of the last row only
        width = shutil.get_terminal_size().columns - 1
        self.err.write(f"\r{(PROG + ': ' + one_line(text))[:width]}\x1b[K")
        self.err.flush()
        self.open = True

    def close(self) -> None:
        """End the rewritten line, so that what is printed next starts a line of its own."""
        if self.open:
            self.err.write("\n")
            self.err.flush()
            self.open = False


class SideOutputs:
    """Writes the outputs beside the image (--progressive, --error-map, --spp-map): a failure (a full
    disk, a missing directory) is one warning, shown even with --quiet, and the render goes on; a
    flag that failed is not tried again. The image itself (-out) is written before any side output
    of the final pass, and its failure is an error."""

    def __init__(self, err=None, before: Callable[[], None] = lambda: None) -> None:
        self.err = err or sys.stderr
        self.before = before          # called before a warning (PassLine.close)
        self.failed: set[str] = set()

    def write(self, flag: str, path: str, write: Callable[[], None]) -> None:
        if flag in self.failed:
            return
        try:
            write()
        except OSError as error:
            self.failed.add(flag)
            self.before()
            print(f"{PROG}: warning: {flag}: {error.strerror or error}; the render goes on without it", file=self.err)


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

    from warp_spt.images.files import to_display

    t = time.perf_counter()
    blank = np.random.default_rng(0).random((height, width, 3), dtype=np.float32)
    buf = io.BytesIO()
    fmt = {".png": "PNG", ".jpg": "JPEG", ".jpeg": "JPEG"}.get(Path(out).suffix.lower())
    if fmt is None:
        np.save(buf, blank)
    else:
        from PIL import Image

        Image.fromarray(to_display(blank, tonemap or "seed")).save(buf, format=fmt)
    seconds = images * (time.perf_counter() - t) + EXIT_SECONDS
    if denoise:
        from warp_spt.rendering.denoise import seconds as denoise_seconds

        seconds += denoise_seconds(width, height)
    return seconds


def _pct(e: float) -> str:
    return "n/a (needs 2 spp)" if not math.isfinite(e) else f"{100 * e:.2f}%"


def _spp_text(spp: np.ndarray) -> str:
    lo, hi = int(spp.min()), int(spp.max())
    return f"{lo} spp" if lo == hi else f"{lo}..{hi} spp (mean {float(spp.mean()):.1f})"
