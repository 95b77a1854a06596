"""The error, budget and adaptive-sampling flags (--time-budget, --target-error, --adaptive, maps, --denoise).

:mod:`warp_spt.cli.options` adds them to the parser (:func:`add_flags`) and reads them back (:func:`options`);
:mod:`warp_spt.cli.progressive` renders when :attr:`BudgetOptions.active`. Only the standard library here.
"""

from __future__ import annotations

import argparse
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from warp_spt.scene.numbers import plain_float
from warp_spt.runtime.extras import install_hint

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
    denoise: bool | None = None      # None: the first image's choice (cli/view_checks.first_image_defaults)
    adaptive_metric: str | None = None

    def flags(self) -> list[str]:
        """The flags given, as typed (those that switch to the progressive renderer)."""
        return [flag for flag, value in (
            ("--time-budget", self.time_budget), ("--target-error", self.target_error), ("--adaptive", self.adaptive),
            ("--min-spp", self.min_spp), ("--save-partial", self.save_partial), ("--progressive", self.progressive),
            ("--error-map", self.error_map), ("--spp-map", self.spp_map), ("--denoise", self.denoise)) if value]

    @property
    def active(self) -> bool:
        return any((self.time_budget, self.target_error, self.adaptive, self.save_partial, self.progressive,
                    self.error_map, self.spp_map, self.min_spp, self.denoise))

    def samples(self, spp: int) -> str:
        """What the render's start-up line says of its samples per pixel (``spp``: -sr or its default):
        "16 spp" only when that is what every pixel gets. A budget renders until it is met (-sr given:
        at most that many), adaptive sampling gives each pixel up to -sr."""
        until = " or ".join(f"{flag} {value}" for flag, value in (
            ("--target-error", f"{100 * self.target_error:g}%" if self.target_error else None),
            ("--time-budget", f"{self.time_budget:g} s" if self.time_budget else None)) if value)
        if until:
            return f"until {until}" + (f" (at most {spp} spp)" if self.spp_given else "")
        return f"up to {spp} spp per pixel (--adaptive)" if self.adaptive else f"{spp} spp"


def _positive_float(text: str) -> float:
    try:
        value = plain_float(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None
    if not value > 0:
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
                        "relative error with a legend)")
    g.add_argument("--spp-map", metavar="PATH",
                   help="write the samples per pixel (.npy/.pfm, or .png false colour with a legend)")
    g.add_argument("--denoise", action=argparse.BooleanOptionalAction,
                   help="denoise the output with Intel Open Image Denoise (needs pyoidn: pip install "
                        "\".[denoise]\" in a clone, or \"warp-spt[denoise]\"); the default for a .png/.jpg "
                        "of a standard file when pyoidn is installed; "
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
                                  f"({install_hint('exr')})")
    if ns.adaptive_metric is not None and not ns.adaptive:
        raise usage_error("--adaptive-metric needs --adaptive")
    return BudgetOptions(ns.time_budget, ns.target_error, ns.adaptive, ns.min_spp, ns.save_partial, ns.progressive,
                         ns.error_map, ns.spp_map, ns.sr is not None, ns.denoise, ns.adaptive_metric)


def extra_outputs(b: BudgetOptions) -> list[tuple[str, str]]:
    """(flag, path) of every further file the render writes (for the early writability check)."""
    return [(f, p) for f, p in (("--progressive", b.progressive), ("--error-map", b.error_map),
                                ("--spp-map", b.spp_map)) if p]


def shared_output(out: str | None, b: BudgetOptions) -> str | None:
    """Why two of the outputs (-out and the further ones) name the same file, or None: each is written
    atomically on its own, so one would silently replace the other."""
    seen: dict[str, str] = {}
    for flag, path in [("-out", out), *extra_outputs(b)]:
        if not path:
            continue
        key = os.path.realpath(path)
        if key in seen:
            return f"{seen[key]} and {flag} name the same file {path!r}: give each output its own name"
        seen[key] = flag
    return None


def check_denoiser(b: BudgetOptions, error: Callable[[str], Exception]) -> None:
    """--denoise needs pyoidn: one line naming the install command, before loading and rendering (it was
    a RuntimeError reported as an internal error, after the scene was loaded)."""
    if b.denoise:
        from warp_spt.rendering.denoise import INSTALL_HINT, available

        if not available():
            raise error(INSTALL_HINT)


def check_outputs(b: BudgetOptions, error: Callable[[str], Exception]) -> None:
    """Fail before rendering when a further output cannot be written."""
    for flag, path in extra_outputs(b):
        parent = Path(path).parent
        if not parent.is_dir():
            raise error(f"cannot write {flag} {path!r}: directory {str(parent)!r} does not exist")
        if Path(path).is_dir():
            raise error(f"cannot write {flag} {path!r}: it is a directory")