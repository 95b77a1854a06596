"""Interrupt real ``warp-spt`` processes at random moments and classify what each one left behind.

Shared by ``tests/rendering/test_interrupt.py`` (a short CI run) and ``benchmarks/soak_interrupt.py`` (hundreds
of trials). A trial starts the command line as a new process (``python -m warp_spt`` or the console
script's own entry, ``warp_spt.__main__:main``), sends SIGINT or SIGTERM after a random delay, and
checks the outcome against what the README promises:

* the process ends within ``HANG_SECONDS`` (else: a hang; it is then killed);
* status 0 with a complete output, or 130 (SIGINT) / 143 (SIGTERM) with exactly the one line
  ``warp-spt: interrupted`` / ``warp-spt: terminated`` on stderr (else: a bad exit);
* no hidden ``.NAME.<uuid>.tmp`` beside the output (else: a leftover);
* an output file, if there is one, reads back complete and finite (else: corrupt).

A signal that arrives while the interpreter itself starts, before any warp_spt code runs, gets
Python's own handling (a traceback from ``<frozen ...>`` modules); such trials are counted apart as
``before_our_code`` and are not failures of warp_spt.
"""

from __future__ import annotations

import os
import random
import re
import signal
import subprocess
import sys
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[2]
HANG_SECONDS = 60.0
SCENE = "v -10 0 0\nv 18 0 0\nv 18 0 30\nv -10 0 30\nf 1 2 3 4\nb 4 -20 16 5\n"   # the q.obj
ENTRIES = {
    "module": ["-m", "warp_spt"],
    "script": ["-c", "import sys; from warp_spt.__main__ import main; sys.exit(main())"],   # what pip's wrapper runs
}
LINES = {signal.SIGINT: "warp-spt: interrupted", signal.SIGTERM: "warp-spt: terminated"}


@dataclass
class Trial:
    delay: float
    signum: int
    entry: str
    suffix: str
    status: int | None = None
    stderr: str = ""
    outcome: str = ""        # ok_finished, ok_interrupted, before_our_code, hang, bad_exit, leftover, corrupt
    seconds: float = 0.0


def command(entry: str, workdir: Path, out: str, res: int, spp: int) -> list[str]:
    return [sys.executable, *ENTRIES[entry], "-obj", str(workdir / "q.obj"), "-res", str(res), str(res),
            "-sr", str(spp), "-depth", "2", "--quiet", "-out", out]


def default_signals() -> None:
    """In a child before it runs: SIGINT and SIGTERM as a foreground job in a terminal has them."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def environment() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(REPO) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def run_trial(workdir: Path, trial: Trial, res: int, spp: int) -> Trial:
    """Run one trial in ``workdir`` (emptied of earlier outputs first) and classify it."""
    for old in workdir.iterdir():
        if old.name != "q.obj":
            old.unlink()
    (workdir / "q.obj").write_text(SCENE)
    out = workdir / f"out{trial.suffix}"
    start = time.monotonic()
    # start_new_session: a hang can be killed with its whole group; an ignored SIGINT (a soak run
    # started in the background) would be inherited all the same, so the child resets it, as a
    # terminal's foreground job has it.
    proc = subprocess.Popen(command(trial.entry, workdir, str(out), res, spp), cwd=workdir, env=environment(),
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True,
                            preexec_fn=default_signals)
    time.sleep(trial.delay)
    if proc.poll() is None:
        proc.send_signal(trial.signum)
    try:
        _, err = proc.communicate(timeout=HANG_SECONDS)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        _, err = proc.communicate()
        trial.outcome = "hang"
    trial.seconds = time.monotonic() - start
    trial.status, trial.stderr = proc.returncode, err.decode("utf-8", "replace")
    if not trial.outcome:
        trial.outcome = classify(trial, workdir, out, res)
    return trial


def classify(trial: Trial, workdir: Path, out: Path, res: int) -> str:
    if any(p.name.endswith(".tmp") for p in workdir.iterdir()):
        return "leftover"
    if out.exists() and not output_is_complete(out, res):
        return "corrupt"
    if trial.status == 0:
        return "ok_finished" if out.exists() and trial.stderr == "" else "bad_exit"
    if trial.status == 128 + trial.signum and trial.stderr == LINES[trial.signum] + "\n":
        return "ok_interrupted"
    if not out.exists() and (("Traceback" in trial.stderr and not _ran_our_code(trial.stderr))
                             or (trial.status == -trial.signum and trial.stderr == "")):
        # Python's own handling (a traceback from its start-up modules) or the signal's default
        # action (killed at once): the signal came before the interpreter ran any warp_spt code.
        return "before_our_code"
    return "bad_exit"


# The modules Python must import (and, in a fresh checkout, compile) before the entry point can
# install its handlers: a traceback whose warp_spt frames are only their module-level code came
# before any of our code could run.
_ENTRY_MODULES = ("warp_spt/__init__.py", "warp_spt/__main__.py", "warp_spt/signals.py")


def _ran_our_code(stderr: str) -> bool:
    frames = re.findall(r'File "([^"]*)", line \d+, in (\S+)', stderr)
    # setuptools' editable-install finder (site-packages/__editable___warp_spt_..._finder.py) runs while
    # the interpreter imports its site module, before any code of ours: not ours
    ours = [(f.replace("\\", "/"), fn) for f, fn in frames if "warp_spt" in f and "__editable__" not in f]
    return any(not (fn == "<module>" and f.endswith(_ENTRY_MODULES)) for f, fn in ours)


def output_is_complete(out: Path, res: int) -> bool:
    try:
        if out.suffix == ".npy":
            img = np.load(out)
        elif out.suffix == ".pfm":
            from warp_spt.images.files import read_pfm
            img = read_pfm(out)
        else:
            from PIL import Image
            with Image.open(out) as im:
                im.load()
                img = np.asarray(im.convert("RGB"), dtype=np.float32)
    except Exception:
        return False
    return img.shape == (res, res, 3) and bool(np.isfinite(img).all())


def timed_full_run(workdir: Path, res: int, spp: int) -> float:
    """Seconds of one uninterrupted run (also warms Warp's kernel cache)."""
    (workdir / "q.obj").write_text(SCENE)
    start = time.monotonic()
    subprocess.run(command("module", workdir, str(workdir / "warm.npy"), res, spp), cwd=workdir,
                   env=environment(), check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.monotonic() - start


def run_trials(workdir: Path, count: int, *, res: int, spp: int, seed: int, min_delay: float = 0.0,
               max_delay: float | None = None, report=None) -> tuple[Counter, list[Trial]]:
    """``count`` trials with delays uniform in [min_delay, max_delay] (default: 1.1 x an uninterrupted
    run's time, measured first)."""
    workdir.mkdir(parents=True, exist_ok=True)
    # the first full run may compile kernels (a cold cache): time a second, warm one too, and take
    # the shorter, so that the delays spread over real runs rather than mostly after their end
    full = max_delay / 1.1 if max_delay is not None else min(timed_full_run(workdir, res, spp) for _ in range(2))
    rng = random.Random(seed)
    counts: Counter = Counter()
    trials = []
    for k in range(count):
        trial = Trial(delay=rng.uniform(min_delay, 1.1 * full), signum=rng.choice([signal.SIGINT, signal.SIGTERM]),
                      entry=rng.choice(sorted(ENTRIES)), suffix=rng.choice([".png", ".npy", ".pfm"]))
        run_trial(workdir, trial, res, spp)
        counts[trial.outcome] += 1
        trials.append(trial)
        if report is not None:
            report(k, trial)
    return counts, trials


FAILURES = ("hang", "bad_exit", "leftover", "corrupt")
