"""The ``warp-spt`` command line: the seed's flags unchanged, plus what a modern tool needs.

Two steps, so the first can be tested without rendering: :func:`parse_args` turns argv into a
validated :class:`Options` (pure: no files, no Warp), and :func:`run` loads, renders and saves.
:func:`main` ties them together and turns every failure into one ``warp-spt: error: ...`` line.
"""

from __future__ import annotations

import os
import sys
import time
import warnings
from typing import Sequence, TextIO

# Only light modules here (stdlib, no numpy, no Warp): main() installs the SIGINT/SIGTERM handling
# before anything heavy is imported, so a Ctrl-C during start-up gets the same one-line message.
from warp_spt import __version__
from warp_spt.io.paths import trusting
from warp_spt.cli.common import (
    EXIT_FAILURE,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_TERMINATED,
    EXIT_USAGE,
    PROG,
    RunError,
    UsageError,
    fail,
    one_line,
    out_of_memory,
    process_start,
    registry_help,
)
from warp_spt.cli.options import Options, build_parser, parse_args
from warp_spt.runtime.signals import (
    cli_interruption,
    exit_status,
    finish_cli_handlers,
    install_cli_handlers,
    interruption_line,
)

# ---------------------------------------------------------------------------------------------
# Your own models: up axis, look-at, single-field overrides, framing, studio, default material


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``warp-spt`` and ``python -m warp_spt``; returns the exit status.

    ``argv`` None means "the program": SIGINT and SIGTERM handling is installed first and stays
    (a signal after the status is decided is ignored). With an explicit ``argv`` (tests, scripts)
    the caller's handlers are restored on return. ``warp-spt convergence ...`` runs the convergence
    report (warp_spt.rendering.convergence).
    """
    # --time-budget covers start-up, load and compile; called from Python, it counts from this call
    started = process_start() if argv is None else time.perf_counter()
    previous = install_cli_handlers()
    try:
        status = _main(sys.argv[1:] if argv is None else list(argv), sys.stderr, started)
        late = cli_interruption()
        if late is not None and status not in (EXIT_INTERRUPTED, EXIT_TERMINATED):
            # a signal whose exception some library swallowed just before the end: still report it
            status = _report(late, sys.stderr)
        return status
    finally:
        finish_cli_handlers(previous, program=argv is None)


def run(opts: Options, *, stderr: TextIO | None = None, started: float | None = None) -> int:
    """Run the command ``opts`` describes: frames or a cluster render (:mod:`warp_spt.cli.animation`),
    or one image on this machine (:mod:`warp_spt.cli.render`). Errors propagate; :func:`main` reports them.

    ``started`` (a perf_counter value, default now) is when the command started: --time-budget counts from it.
    """
    started = time.perf_counter() if started is None else started
    err = stderr or sys.stderr
    with warnings.catch_warnings():
        # a library's warning is one line like every message, and none with --quiet (not Python's
        # two lines with a source line)
        warnings.showwarning = lambda message, *args, **kw: None if opts.quiet else print(
            f"{PROG}: warning: {one_line(str(message))}", file=err)
        with trusting(opts.trust_paths):
            if opts.animated or opts.cluster or opts.workers:
                from warp_spt.cli.animation import run_cli
                return run_cli(opts, err, started)
            from warp_spt.cli.render import run_image
            return run_image(opts, err, started)


def _main(argv: list[str], stderr: TextIO, started: float) -> int:
    if argv[:1] == ["convergence"]:
        from warp_spt.cli.convergence import main as convergence_main
        return convergence_main(argv[1:])
    if argv[:1] == ["view"]:
        from warp_spt.cli.view import main as view_main
        try:
            return view_main(argv[1:])
        except BaseException as err:        # Ctrl-C before the server runs, a bug: one line
            return _report(err, stderr)
    try:
        opts = parse_args(argv)
        if opts.action == "help":
            print(build_parser().format_help(), end="", flush=True)    # the flags at once, no Warp
            print(registry_help(), end="")
            return EXIT_OK
        if opts.action == "version":
            print(f"{PROG} {__version__}")
            return EXIT_OK
        return run(opts, stderr=stderr, started=started)
    except BaseException as err:        # every failure ends as one line and an exit status
        return _report(err, stderr)


def _report(err: BaseException, stderr: TextIO) -> int:
    from warp_spt.scene.errors import SceneError

    signal_err = err if isinstance(err, KeyboardInterrupt) else cli_interruption()
    if signal_err is not None:          # Ctrl-C (SIGINT) or SIGTERM, wherever it arrived
        print(interruption_line(signal_err, PROG), file=stderr)
        return exit_status(signal_err)
    if isinstance(err, UsageError):
        return fail(f"{err} (see {PROG} --help)", EXIT_USAGE, stderr)
    if isinstance(err, (RunError, SceneError)):
        return fail(str(err), EXIT_FAILURE, stderr)
    if out_of_memory(err):
        return fail("out of memory: try a smaller -res or fewer --threads", EXIT_FAILURE, stderr)
    if isinstance(err, OSError):
        where = f" {err.filename!r}" if err.filename else ""
        return fail(f"{err.strerror or err}{where}", EXIT_FAILURE, stderr)
    if not isinstance(err, Exception) or os.environ.get("WARP_SPT_TRACEBACK"):
        raise err                       # SystemExit and the like; or a bug with its traceback asked for
    return fail(f"internal error: {type(err).__name__}: {err} (set WARP_SPT_TRACEBACK=1 for details)",
                 EXIT_FAILURE, stderr)
