"""Imported by the fork server that local Dask workers are forked from (and nowhere else).

A worker forked while its parent is exiting (a Ctrl-C to the process group as ``--workers`` start)
unpickles start-up state naming semaphores that the parent has already unlinked:
``SemLock._rebuild`` raises FileNotFoundError (or the pickle ends early: EOFError), and the fork
server printed that child's traceback after the command's one line. Such a child has nothing left
to do: it exits with status 1, quietly. The parent, if it is still there, still learns of it (the
nanny reports a worker that failed to start). Every other start-up error prints as before.

Stdlib only: the fork server imports this before it forks anything.
"""

from __future__ import annotations

import multiprocessing.spawn as _spawn

_bootstrap_main = _spawn._main


def _main(fd, parent_sentinel):
    # Process._bootstrap catches everything the process itself raises: what escapes spawn._main
    # comes from reading the start-up state.
    try:
        return _bootstrap_main(fd, parent_sentinel)
    except (FileNotFoundError, EOFError):
        return 1


_spawn._main = _main
