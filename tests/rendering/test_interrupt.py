"""Ctrl-C and SIGTERM: cancellation that does not depend on where the signal lands (issue 11, part 1).

Unit tests of :mod:`warp_spt.runtime.threads` and :mod:`warp_spt.runtime.signals`, then real CLI processes
interrupted at random moments (a short run of the trials that ``benchmarks/soak_interrupt.py``
repeats hundreds of times).
"""

from __future__ import annotations

import os
import signal
import threading
import time

import pytest

from warp_spt.runtime.signals import Interrupted, deferred_signals, exit_status
from warp_spt.runtime.threads import run_jobs

from tests.support import interrupt_trials as T


def collect(jobs, threads, work):
    reported = []
    run_jobs(jobs, work, threads, reported.append)
    return reported


@pytest.mark.parametrize("threads", [1, 2, 5])
def test_every_job_runs_once_and_progress_reaches_the_calling_thread(threads):
    seen, callers = [], set()

    def work(job, stop, done):
        seen.append(job)
        done(job)

    def report(units):
        callers.add(threading.current_thread())
        total.append(units)

    total: list[int] = []
    run_jobs(list(range(1, 41)), work, threads, report)
    assert sorted(seen) == list(range(1, 41)) and sum(total) == sum(range(1, 41))
    assert callers == {threading.main_thread()}


def test_the_calling_thread_returns_when_the_last_worker_ends_not_at_its_next_poll(monkeypatch):
    """Jobs that report no progress (the progressive driver's launches) end the call as soon as the
    workers do: before, the calling thread waited out its poll, a tenth of a second on every pass."""
    from warp_spt.runtime import threads as threads_module

    monkeypatch.setattr(threads_module, "POLL_SECONDS", 30.0)
    t = time.perf_counter()
    run_jobs(list(range(4)), lambda job, stop, done: time.sleep(0.05), 2, lambda units: None)
    assert time.perf_counter() - t < threads_module.POLL_SECONDS / 10     # a ratio: not waited out


@pytest.mark.parametrize("threads", [1, 3])
def test_a_workers_exception_is_re_raised_after_the_others_stopped(threads):
    running = []

    def work(job, stop, done):
        if job == 1:
            raise ValueError("tile 1 failed")
        running.append(job)
        for _ in range(200):            # the other tiles run in steps until told to stop
            if stop.is_set():
                return
            time.sleep(0.01)

    with pytest.raises(ValueError, match="tile 1"):
        run_jobs(list(range(10)), work, threads, lambda units: None)
    assert not [t for t in threading.enumerate() if t.name.startswith("warp_spt-worker")]
    assert len(running) < 9


def test_an_exception_of_the_progress_callback_stops_the_workers():
    def work(job, stop, done):
        while not stop.is_set():
            done(1)
            time.sleep(0.005)

    def report(units):
        raise RuntimeError("callback broke")

    with pytest.raises(RuntimeError, match="callback broke"):
        run_jobs([0, 1, 2], work, 2, report)
    assert not [t for t in threading.enumerate() if t.name.startswith("warp_spt-worker")]


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_stops_the_jobs_then_raises_like_the_previous_handler(threads, signum):
    """SIGINT during the jobs: they stop between steps, then the old handler runs (here: raise)."""
    started, finished = [], []

    def work(job, stop, done):
        started.append(job)
        if job == 1:
            os.kill(os.getpid(), signum)
        for _ in range(20):             # steps, checking the stop flag between them
            if stop.is_set():
                return
            time.sleep(0.005)
        finished.append(job)

    def raising(s, frame):
        raise Interrupted(s)

    old = signal.signal(signum, raising)
    try:
        with pytest.raises(KeyboardInterrupt) as info:
            run_jobs(list(range(50)), work, threads, lambda units: None)
        assert signal.getsignal(signum) is raising      # the previous handler is back
    finally:
        signal.signal(signum, old)
    assert exit_status(info.value) == 128 + signum
    assert len(started) < 50 and not finished[threads:]     # stopped early
    assert not [t for t in threading.enumerate() if t.name.startswith("warp_spt-worker")]


def test_deferred_signals_deliver_after_the_block():
    order = []
    with pytest.raises(KeyboardInterrupt):
        with deferred_signals():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.01)
            order.append("block finished")
    assert order == ["block finished"]


def test_deferred_signals_with_second_now_deliver_a_second_signal_at_once():
    order = []
    with pytest.raises(KeyboardInterrupt):
        with deferred_signals(second_now=True):
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.01)
            order.append("held")
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.01)
            order.append("block finished")
    assert order == ["held"]


def test_a_fork_server_child_whose_start_up_state_is_gone_exits_quietly(tmp_path):
    """The fork server's child that finds its parent's semaphores unlinked (the parent exiting on a
    Ctrl-C as local workers start) ends with status 1 and prints nothing; other errors still print."""
    import subprocess
    import sys

    script = tmp_path / "child.py"
    script.write_text(
        "import os, pickle, sys\n"
        "import warp_spt.runtime.forkserver_preload\n"
        "from multiprocessing import spawn\n"
        "r, w = os.pipe()\n"
        "gone = (os.stat, ('/nonexistent-semaphore',)) if sys.argv[1] == 'gone' else (int, ('x',))\n"
        "class State:\n"
        "    def __reduce__(self):\n"
        "        return gone\n"
        "os.write(w, pickle.dumps({}) + pickle.dumps(State()))\n"
        "os.close(w)\n"
        "print(spawn._main(r, os.dup(r)))\n")
    gone = subprocess.run([sys.executable, str(script), "gone"], capture_output=True, text=True, timeout=60)
    assert (gone.stdout, gone.stderr) == ("1\n", ""), gone
    other = subprocess.run([sys.executable, str(script), "other"], capture_output=True, text=True, timeout=60)
    assert other.returncode != 0 and "ValueError" in other.stderr, other


def test_real_processes_interrupted_at_random_moments(tmp_path):
    """A short run of the soak: every trial ends promptly, cleanly, and leaves no partial file."""
    seed = int(os.environ.get("WARP_SPT_TRIAL_SEED", time.time_ns() % 10**6))
    counts, trials = T.run_trials(tmp_path / "w", 10, res=96, spp=8, seed=seed)
    bad = [t for t in trials if t.outcome in T.FAILURES]
    assert not bad, f"seed {seed}: {counts}; first failure: {bad[0]}"
    assert counts["ok_interrupted"] >= 3, f"seed {seed}: {counts}"   # the signals did land during runs


def test_an_interruption_that_library_code_wraps_is_still_reported_as_one(tmp_path, monkeypatch, capsys):
    """numpy turns a KeyboardInterrupt inside its C-extension import into ImportError (found by the soak)."""
    import sys
    import types

    from warp_spt.cli.main import main

    def wrapping_load(objs, mtls, **kw):
        try:
            os.kill(os.getpid(), signal.SIGTERM)
            time.sleep(1)
        except KeyboardInterrupt as err:
            raise ImportError("Importing the numpy C-extensions failed.") from err

    monkeypatch.setitem(sys.modules, "warp_spt.io.loader", types.SimpleNamespace(load_scene=wrapping_load))
    obj = tmp_path / "a.obj"
    obj.write_text("b 0 0 0 1\n")
    assert main(["-obj", str(obj), "--quiet", "-out", str(tmp_path / "o.png")]) == 143
    assert capsys.readouterr().err == "warp-spt: terminated\n"


def test_the_entry_points_import_nothing_heavy_before_the_handlers():
    """Ctrl-C during start-up: the handlers go in before numpy or Warp is imported."""
    import subprocess
    import sys

    code = ("import sys, signal; import warp_spt.__main__, warp_spt.cli.main; "
            "heavy = [m for m in ('numpy', 'warp', 'PIL', 'tqdm') if m in sys.modules]; "
            "warp_spt.runtime.signals.install_cli_handlers(); "
            "print(heavy, signal.getsignal(signal.SIGTERM).__name__)")
    env = dict(os.environ, PYTHONPATH=str(T.REPO))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=60)
    assert out.stdout.strip() == "[] _cli_handler", out.stderr


def test_an_interruption_swallowed_by_a_callback_is_raised_again(tmp_path, monkeypatch, capsys):
    """Found by the soak: a SIGTERM inside importlib's weakref callback was printed and lost."""
    import gc
    import sys
    import types
    import weakref

    from warp_spt.cli.main import main

    reached = []

    def load_with_a_swallowing_callback(objs, mtls, **kw):
        class Thing:
            pass

        thing = Thing()
        ref = weakref.ref(thing, lambda r: os.kill(os.getpid(), signal.SIGTERM) or time.sleep(0.5))  # noqa: F841
        del thing           # the callback runs here; the exception raised in it is swallowed
        gc.collect()
        time.sleep(1)       # the re-sent signal lands here
        reached.append("after the callback")

    fake_loader = types.SimpleNamespace(load_scene=load_with_a_swallowing_callback)
    monkeypatch.setitem(sys.modules, "warp_spt.io.loader", fake_loader)
    obj = tmp_path / "a.obj"
    obj.write_text("b 0 0 0 1\n")
    assert main(["-obj", str(obj), "--quiet", "-out", str(tmp_path / "o.png")]) == 143
    assert capsys.readouterr().err == "warp-spt: terminated\n"
    assert reached == []                                  # the load itself was interrupted
    from warp_spt.runtime.signals import _cli_unraisable
    assert sys.unraisablehook is not _cli_unraisable      # the caller's hook is back


def test_the_signal_tests_pass_in_a_run_started_with_sigint_ignored():
    """``nohup python -m pytest tests &`` (issue 31): a background job inherits an ignored SIGINT.
    The suite's conftest gives the run, and so every process it starts, a terminal's disposition;
    a run of signal tests started that way passes."""
    import subprocess
    import sys

    tests = ["tests/rendering/test_progressive.py::test_a_signal_stops_a_pass_between_its_launches",
             "tests/rendering/test_interrupt.py::test_a_signal_stops_the_jobs_then_raises_like_the_previous_handler",
             "tests/rendering/test_interrupt.py::test_real_processes_interrupted_at_random_moments"]
    env = dict(os.environ, PYTHONPATH=str(T.REPO))
    done = subprocess.run([sys.executable, "-m", "pytest", "-q", "-n", "0", "-p", "no:cacheprovider", *tests],
                          cwd=T.REPO, env=env, capture_output=True, text=True, timeout=600,
                          preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    assert done.returncode == 0, done.stdout[-3000:]          # 1: a test failed, 5: none ran
