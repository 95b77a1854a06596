"""What the ``warp-spt`` commands share (the render CLI in :mod:`warp_spt.cli`, the convergence report in
:mod:`warp_spt.convergence`, the animation runner): the program name, exit statuses, the two error
types, an argparse parser that raises, strict number converters, the one-line error report, and Warp's
quiet start-up.

Only the standard library here: ``main()`` installs its signal handling before anything heavy is
imported, so that a Ctrl-C during start-up gets the same one-line message.
"""

from __future__ import annotations

import argparse
import math
import re
import unicodedata
from typing import TextIO

PROG = "warp-spt"
EXIT_OK, EXIT_FAILURE, EXIT_USAGE = 0, 1, 2
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143     # 128 + the signal number (signals.exit_status)


class UsageError(Exception):
    """A bad command line: reported as one line, exit status 2."""


class RunError(Exception):
    """A failure after parsing (unreadable input, output directory missing): exit status 1."""


class Parser(argparse.ArgumentParser):
    """argparse that raises :class:`UsageError` instead of printing the usage and exiting."""

    def error(self, message: str):  # type: ignore[override]
        raise UsageError(message)


# Plain ASCII numbers only, as in OBJ files: int() and float() would also take "1_0", "inf", and
# Arabic-Indic or full-width digits.
_INT_RE = re.compile(r"[+-]?[0-9]+")
_FLOAT_RE = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


def int_at_least(low: int, high: int | None = None):
    """An argparse ``type``: a plain decimal integer in [low, high] (no upper bound when ``high`` is None)."""
    def convert(text: str) -> int:
        if not _INT_RE.fullmatch(text):
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}")
        value = int(text)
        if value < low:
            raise argparse.ArgumentTypeError(f"must be at least {low}, got {value}")
        if high is not None and value > high:
            raise argparse.ArgumentTypeError(f"must be at most {high}, got {value}")
        return value
    convert.__name__ = "integer"
    return convert


def finite_float(text: str) -> float:
    """An argparse ``type``: a plain decimal number, finite."""
    if not _FLOAT_RE.fullmatch(text):
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}")
    value = float(text)
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def one_line(text: str) -> str:
    """``text`` with control characters and line separators escaped (\\n, \\x85, \\u2028...), so that
    a message stays one line whatever the file names and file contents it quotes hold."""
    return "".join(ch.encode("unicode_escape").decode("ascii") if unicodedata.category(ch) in ("Cc", "Zl", "Zp")
                   else ch for ch in text)


def fail(message: str, status: int, stderr: TextIO) -> int:
    """Print ``warp-spt: error: message`` as one line on ``stderr`` and return ``status``."""
    print(f"{PROG}: error: {one_line(message)}", file=stderr)
    return status


def init_warp(opts) -> None:
    """Warp's banner, module-load lines and missing-CUDA-driver line only with ``opts.verbose``."""
    try:
        from .warp_runtime import init_warp as init
        init(opts.verbose, quiet=opts.quiet)
    except ImportError:  # Warp missing: the renderer's import will report the real problem
        pass
