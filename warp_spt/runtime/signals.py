"""SIGINT and SIGTERM handled so that cancellation never depends on where the signal lands.

Python turns SIGINT into a KeyboardInterrupt raised at whatever bytecode the main thread is running.
Inside library code that holds a lock (``concurrent.futures``, a tqdm bar, a half-written file) that
can leave the lock held or a temporary file behind. The tools here keep the signal out of such code:

* :func:`stop_on_signals` installs handlers that only set a :class:`threading.Event` (the render's
  stop flag); the caller stops its workers and then calls :meth:`Caught.deliver`, which hands the
  signal to the handler that was installed before (by default: raise KeyboardInterrupt).
* :func:`deferred_signals` holds the signals for a short critical section (an atomic file write)
  and delivers them when it ends.
* :func:`install_cli_handlers` is what the command line installs first thing, before it imports
  numpy or Warp: both signals raise :class:`Interrupted`, a KeyboardInterrupt that knows its signal.

Only the main thread may install handlers; elsewhere these tools change nothing. Stdlib only, so
the command line can import this module before anything heavy.
"""

from __future__ import annotations

import os
import signal
import sys
import threading
from contextlib import contextmanager

TYPE_CHECKING = False
if TYPE_CHECKING:
    from collections.abc import Iterator

SIGNALS = tuple(s for s in (getattr(signal, "SIGINT", None), getattr(signal, "SIGTERM", None)) if s is not None)


class Interrupted(KeyboardInterrupt):
    """A KeyboardInterrupt raised for a signal; ``signum`` says which (SIGINT or SIGTERM)."""

    def __init__(self, signum: int = signal.SIGINT):
        super().__init__(signal.Signals(signum).name)
        self.signum = int(signum)


def exit_status(err: BaseException) -> int:
    """The shell convention 128 + N: 130 for SIGINT (and a plain KeyboardInterrupt), 143 for SIGTERM."""
    return 128 + int(getattr(err, "signum", signal.SIGINT))


def interruption_line(err: BaseException, prog: str = "warp-spt") -> str:
    """The command line's one line for an interruption."""
    return f"{prog}: {'terminated' if exit_status(err) == 128 + signal.SIGTERM else 'interrupted'}"


def _on_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


def deliver(signum: int, handler) -> None:
    """Act on ``signum`` as ``handler`` (a previously installed handler) would have."""
    if callable(handler):
        handler(signum, None)
    elif handler == signal.SIG_DFL:
        if signum == signal.SIGINT:
            raise KeyboardInterrupt
        signal.signal(signum, signal.SIG_DFL)   # the default action (SIGTERM: end the process)
        os.kill(os.getpid(), signum)
    # SIG_IGN or None (a handler not installed from Python): nothing to do


class Caught:
    """The first signal caught by :func:`stop_on_signals`, and the handlers it replaced."""

    def __init__(self) -> None:
        self.signum: int | None = None
        self.previous: dict[int, object] = {}

    def deliver(self) -> None:
        """Hand the caught signal (if any) to the handler it replaced; normally this raises."""
        if self.signum is not None:
            deliver(self.signum, self.previous.get(self.signum, signal.SIG_DFL))


def _install(handler) -> dict[int, object]:
    """Install ``handler`` for every signal not ignored; return the replaced handlers."""
    previous = {}
    for s in SIGNALS:
        old = signal.getsignal(s)
        if old != signal.SIG_IGN:
            previous[s] = signal.signal(s, handler)
    return previous


def _restore(previous: dict[int, object]) -> None:
    for s, old in previous.items():
        signal.signal(s, old if old is not None else signal.SIG_DFL)


@contextmanager
def stop_on_signals(stop: threading.Event) -> Iterator[Caught]:
    """While the block runs (on the main thread), SIGINT/SIGTERM only set ``stop``.

    The block should stop its work when ``stop`` is set; afterwards the caller calls
    ``caught.deliver()`` to raise the interruption the usual way. Handlers are restored on exit.
    """
    caught = Caught()
    if not _on_main_thread():
        yield caught
        return

    def handler(signum, frame):
        if caught.signum is None:
            caught.signum = signum
        stop.set()

    caught.previous = _install(handler)
    try:
        yield caught
    finally:
        _restore(caught.previous)


@contextmanager
def deferred_signals(*, second_now: bool = False) -> Iterator[None]:
    """Hold SIGINT/SIGTERM until the block ends, then deliver the first one (main thread only).

    For short critical sections such as writing and renaming an output file: the block either
    completes or unwinds through its own error handling, never in the middle of its cleanup.
    With ``second_now``, a second signal while the first is held is delivered at once: for a block
    that may take seconds (starting local workers), where a user who presses Ctrl-C again means it.
    """
    if not _on_main_thread():
        yield
        return
    pending: list[int] = []
    previous: dict[int, object] = {}

    def hold(signum, frame):
        pending.append(signum)
        if second_now and len(pending) > 1:
            deliver(signum, previous.get(signum, signal.SIG_DFL))

    previous.update(_install(hold))
    try:
        yield
    finally:
        _restore(previous)
        if pending:
            deliver(pending[0], previous.get(pending[0], signal.SIG_DFL))


# Signal handlers belong to the process, and a handler receives no context of ours: the CLI's one
# state of "interrupted, by which signal" lives here, set by the handler, reset by install_cli_handlers().
_cli_state: dict[str, object] = {"interrupted": False, "signum": None}


def _cli_handler(signum, frame):
    # The first signal unwinds the program; later ones (a second Ctrl-C while it unwinds) are
    # ignored, so the cleanup that the first one started is never itself interrupted.
    if _cli_state["interrupted"]:
        return
    _cli_state["interrupted"] = True
    _cli_state["signum"] = signum
    raise Interrupted(signum)


def cli_interruption() -> Interrupted | None:
    """The interruption the CLI handler raised, if any: library code may have wrapped it in another
    exception on its way up (numpy turns one that lands in its C-extension import into ImportError)."""
    signum = _cli_state["signum"]
    return Interrupted(int(signum)) if signum is not None else None


def _cli_unraisable(info) -> None:
    """Where Python swallows exceptions (weakref callbacks, ``__del__``, e.g. inside importlib's module
    locks: found by the soak), an Interrupted raised there would be printed and lost. Instead it is
    raised again: the signal is re-sent from another thread a moment later (from this one, the handler
    would run at once, still inside the swallowing code), and lands on the main thread's next bytecode."""
    if isinstance(info.exc_value, Interrupted):
        _cli_state["interrupted"] = False
        resend = threading.Timer(0.01, os.kill, (os.getpid(), info.exc_value.signum))
        resend.daemon = True
        resend.start()
    else:
        _cli_state["unraisablehook"](info)


def install_cli_handlers() -> dict[int, object]:
    """SIGINT and SIGTERM raise :class:`Interrupted` (once); returns the replaced handlers.

    For the command line, first thing in ``main`` (main thread only; elsewhere nothing changes).
    """
    if not _on_main_thread():
        return {}
    _cli_state["interrupted"] = False
    _cli_state["signum"] = None
    if sys.unraisablehook is not _cli_unraisable:
        _cli_state["unraisablehook"] = sys.unraisablehook
        sys.unraisablehook = _cli_unraisable
    return _install(_cli_handler)


def finish_cli_handlers(previous: dict[int, object], *, program: bool) -> None:
    """At the end of ``main``: a program ignores any later signal while it exits (its status is
    decided and its files are in place); a caller that passed its own argv gets its handlers back.

    SIG_IGN rather than a Python handler: the interpreter resets Python handlers to SIG_DFL while it
    finalises, and a signal in that window would kill the finished process with status -2/-15.
    """
    if not _on_main_thread():
        return
    if program:
        for s in SIGNALS:
            signal.signal(s, signal.SIG_IGN)
    else:
        _restore(previous)
        if sys.unraisablehook is _cli_unraisable:
            sys.unraisablehook = _cli_state["unraisablehook"]


@contextmanager
def ignored_by_children() -> "Iterator[None]":
    """Processes started inside this block, and all they fork, ignore SIGINT for good.

    A terminal's Ctrl-C goes to the whole process group: local Dask workers that were starting up
    printed dozens of lines of tracebacks before the command's one line. An ignored disposition is
    inherited across fork and exec (a blocked mask is not: multiprocessing resets it), and Python keeps
    it at start-up. Start a fork server here and every worker forked from it later ignores the
    signal too. The parent ignores it only for the moment the block lasts (a Ctrl-C in that moment
    is lost; start only something quick here).
    """
    if not _on_main_thread() or not hasattr(signal, "SIGINT"):
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous if previous is not None else signal.SIG_DFL)
