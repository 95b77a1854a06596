"""Run a list of jobs on N plain threads, cancellable at any moment by SIGINT/SIGTERM or an error.

Why not ``concurrent.futures``: a KeyboardInterrupt that lands inside the executor's lock-holding
code leaves a lock held, and the next ``shutdown``/``join`` waits forever (issue 11). Here nothing
is ever interrupted asynchronously:

* while jobs run, SIGINT/SIGTERM only set a stop event (:func:`warp_spt.runtime.signals.stop_on_signals`);
* workers pull jobs from a queue and call ``work(job, stop, done)``; ``work`` checks ``stop``
  between its steps (kernel launches) and reports finished units through ``done``;
* the calling thread waits with timeouts, reports progress, and on a signal, a worker's exception
  or an exception of the progress callback sets ``stop``, waits for every worker to return, then
  re-raises: a worker's exception as it is, a signal the way its previous handler would
  (KeyboardInterrupt by default), so Jupyter's "interrupt" works too;
* a worker says on the same queue that it has ended, so the calling thread returns as soon as the
  last one has (it used to wait out its poll, up to POLL_SECONDS per call: a tenth of a second
  added to every short progressive pass, which quantised the convergence report's times).

``threads == 1`` runs the jobs on the calling thread, in order, with the same stop checks.
Which thread runs which job never changes a result as long as each job writes its own outputs.
"""

from __future__ import annotations

import os
import queue
import threading
from typing import Callable, Sequence, TypeVar

from warp_spt.runtime.signals import stop_on_signals

Job = TypeVar("Job")
DoneFn = Callable[[int], None]
WorkFn = Callable[[Job, threading.Event, DoneFn], None]
ReportFn = Callable[[int], None]

POLL_SECONDS = 0.1     # how often the waiting thread looks at the workers and the stop event
ENDED = None           # what a worker puts on the progress queue when it returns


def cores() -> int:
    """The cores of this machine (os.cpu_count): the default number of render threads, which is why one
    process already uses every core (the CLI warns when --workers asks for as many processes)."""
    return os.cpu_count() or 1


def run_jobs(jobs: Sequence[Job], work: WorkFn, threads: int, report: ReportFn) -> None:
    """Run ``work(job, stop, done)`` for every job on ``threads`` threads; see the module docs.

    ``report(units)`` is called on the calling thread with the units the workers passed to ``done``
    since the last call. Returns when every job is done; raises as described above otherwise.
    """
    stop = threading.Event()
    done_q: queue.SimpleQueue[int | None] = queue.SimpleQueue()   # units done, or ENDED
    with stop_on_signals(stop) as caught:
        if threads <= 1:
            _run_inline(jobs, work, stop, done_q, report)
        else:
            _run_threads(jobs, work, threads, stop, done_q, report)
    caught.deliver()     # a signal arrived: the jobs stopped early; raise it now


def _run_inline(jobs, work, stop, done_q, report) -> None:
    for job in jobs:
        if stop.is_set():
            return
        work(job, stop, done_q.put)
        _drain(done_q, report)


def _run_threads(jobs, work, threads, stop, done_q, report) -> None:
    todo: queue.SimpleQueue = queue.SimpleQueue()
    for job in jobs:
        todo.put(job)
    errors: list[BaseException] = []

    def worker() -> None:
        try:
            while not stop.is_set():
                try:
                    job = todo.get_nowait()
                except queue.Empty:
                    return
                work(job, stop, done_q.put)
        except BaseException as err:   # handed to the calling thread, which re-raises it
            errors.append(err)
            stop.set()
        finally:
            done_q.put(ENDED)

    pool = [threading.Thread(target=worker, name=f"warp_spt-worker-{k}", daemon=True)
            for k in range(min(threads, len(jobs)))]
    for t in pool:
        t.start()
    try:
        ended = 0
        while ended < len(pool):
            ended += _drain(done_q, report, POLL_SECONDS)
    finally:
        stop.set()                      # reached early only by an exception of ``report``
        for t in pool:
            while t.is_alive():
                t.join(POLL_SECONDS)
    if errors:
        raise errors[0]


def _drain(done_q: queue.SimpleQueue, report: ReportFn, wait: float = 0.0) -> int:
    """Report every unit queued so far, first waiting up to ``wait`` seconds for an item; returns how
    many workers said they ended (ENDED items)."""
    units = ended = 0
    try:
        item = done_q.get(timeout=wait) if wait > 0 else done_q.get_nowait()
        while True:
            if item is ENDED:
                ended += 1
            else:
                units += item
            item = done_q.get_nowait()
    except queue.Empty:
        pass
    if units:
        report(units)
    return ended
