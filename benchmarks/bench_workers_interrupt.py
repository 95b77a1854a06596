"""How long ``warp-spt --workers N`` takes to exit after a Ctrl-C, and what it prints (issue 31).

    python benchmarks/bench_workers_interrupt.py [--trials 5] [--workers 2] [--after 1.0]

Starts the command line on the built-in demo with local worker processes, waits until it has said
"loaded" and ``--after`` more seconds (the workers are rendering), sends SIGINT to its process
group (as a terminal's Ctrl-C does), and prints the seconds from the signal to the exit, the exit
status and any line besides the start-up lines and ``warp-spt: interrupted``.
"""

from __future__ import annotations

import argparse
import os
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def trial(workers: int, after: float, folder: Path) -> tuple[float, int, list[str]]:
    cmd = [sys.executable, "-m", "warp_spt", "--demo", "512p16s", "-res", "128", "128", "-sr", "4096",
           "--workers", str(workers), "-out", str(folder / "w.png")]
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True, env=env, start_new_session=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    lines = []
    for line in proc.stderr:                  # up to the "loaded" line
        lines.append(line.rstrip("\n"))
        if line.startswith("warp-spt: loaded"):
            break
    time.sleep(after)
    sent = time.perf_counter()
    os.killpg(proc.pid, signal.SIGINT)
    rest = proc.stderr.read()
    proc.wait(timeout=120)
    seconds = time.perf_counter() - sent
    lines += rest.splitlines()
    other = [x for x in lines if not x.startswith(("warp-spt: loaded", "warp-spt: warning: --workers"))
             and x != "warp-spt: interrupted"]
    return seconds, proc.returncode, other


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=5)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--after", type=float, default=1.0, help="seconds after 'loaded' before the signal")
    args = ap.parse_args()
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.trials):
            seconds, status, other = trial(args.workers, args.after, Path(tmp))
            times.append(seconds)
            print(f"trial {k}: exit {status} {seconds:.2f} s after SIGINT" + (f"; also printed: {other}" if other else ""))
    print(f"median {statistics.median(times):.2f} s, max {max(times):.2f} s over {len(times)} trials")


if __name__ == "__main__":
    main()
