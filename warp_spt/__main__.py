"""``python -m warp_spt`` and the ``warp-spt`` command: signal handling first, then the CLI.

SIGINT/SIGTERM handling is installed before the command line module (and with it argparse, numpy
and Warp) is imported, so an interruption at any moment of start-up prints the same one line as
during a render and exits with 130 (SIGINT) or 143 (SIGTERM).
"""

import sys

from .signals import cli_interruption, exit_status, finish_cli_handlers, install_cli_handlers, interruption_line


def main() -> int:
    """Entry point of the ``warp-spt`` console script."""
    install_cli_handlers()
    try:
        from .cli import main as cli_main

        return cli_main()
    except BaseException as err:            # interrupted while importing (the CLI reports the rest)
        signal_err = err if isinstance(err, KeyboardInterrupt) else cli_interruption()
        if signal_err is None:
            raise
        print(interruption_line(signal_err), file=sys.stderr)
        return exit_status(signal_err)
    finally:
        finish_cli_handlers({}, program=True)   # the status is decided: ignore signals while exiting


if __name__ == "__main__":
    sys.exit(main())
