"""``python -m warp_spt`` and the ``warp-spt`` command: signal handling first, then the CLI.

SIGINT/SIGTERM handling is installed before the command line module (and with it argparse, numpy
and Warp) is imported, so an interruption at any moment of start-up prints the same one line as
during a render and exits with 130 (SIGINT) or 143 (SIGTERM).
"""

import atexit
import os
import sys

from warp_spt.runtime.signals import (
    cli_interruption,
    exit_status,
    finish_cli_handlers,
    install_cli_handlers,
    interruption_line,
)


def main() -> int:
    """Entry point of the ``warp-spt`` console script."""
    install_cli_handlers()
    try:
        from warp_spt.cli.main import main as cli_main

        status = cli_main()
    except BaseException as err:            # interrupted while importing (the CLI reports the rest)
        signal_err = err if isinstance(err, KeyboardInterrupt) else cli_interruption()
        if signal_err is None:
            raise
        print(interruption_line(signal_err), file=sys.stderr)
        status = exit_status(signal_err)
    finally:
        finish_cli_handlers({}, program=True)   # the status is decided: ignore signals while exiting
    _exit_now(status)
    return status       # not reached


def _exit_now(status: int) -> None:
    """Exit without the interpreter's teardown of every module and object.

    With Warp loaded that teardown took 0.5-2 s on a busy machine (docs/error.md): wall time the user
    waits for after the image is written, which --time-budget counts. Everything is in place by now
    (files are written atomically and closed, worker threads have finished); atexit handlers still
    run and the standard streams are flushed, then the process ends with ``status``.
    """
    if status in (130, 143):
        # interrupted: the one line is printed; libraries' exit hooks (Dask's, closing a cluster whose
        # start the Ctrl-C cut short) say nothing more
        sys.stderr = open(os.devnull, "w")
    atexit._run_exitfuncs()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):      # a closed pipe: nothing more can be said anyway
            pass
    os._exit(int(status or 0))     # sys.exit(None) would also mean 0


if __name__ == "__main__":
    sys.exit(main())
