"""Soak: interrupt real warp-spt processes at random moments hundreds of times and count failures.

    python benchmarks/soak_interrupt.py [TRIALS] [--res N] [--spp N] [--seed N] [--delay LO HI]

The issue's reproducer (a 4096x4096 render interrupted 2-9 s in):
    python benchmarks/soak_interrupt.py 30 --res 4096 --spp 1 --delay 2 9

Each trial starts the command line (``python -m warp_spt`` or the console script's entry), sends
SIGINT or SIGTERM after a delay drawn uniformly from 0 to 1.1x an uninterrupted run, and checks
the result (see ``tests/support/interrupt_trials.py``). Prints the counts of each outcome: hangs, leftover
temp files, corrupt outputs and bad exits should all be 0. ``before_our_code`` counts signals that
arrived while the Python interpreter itself was starting, before any warp_spt code ran.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from tests import interrupt_trials as T  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("trials", type=int, nargs="?", default=300)
    ap.add_argument("--res", type=int, default=256, help="image size (default 256: about a second of render)")
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--delay", type=float, nargs=2, metavar=("LO", "HI"),
                    help="signal delays in seconds (default: 0 to 1.1x an uninterrupted run)")
    args = ap.parse_args()
    start = time.monotonic()

    def report(k, trial):
        if trial.outcome in T.FAILURES:
            print(f"  trial {k}: {trial.outcome} after {trial.delay:.2f}s {trial.signum!s} {trial.entry} "
                  f"{trial.suffix} status {trial.status}: {trial.stderr.strip()[:300]!r}", flush=True)
        elif (k + 1) % 50 == 0:
            print(f"  {k + 1} trials, {time.monotonic() - start:.0f} s", flush=True)

    with tempfile.TemporaryDirectory() as tmp:
        lo, hi = args.delay or (0.0, None)
        counts, trials = T.run_trials(Path(tmp), args.trials, res=args.res, spp=args.spp, seed=args.seed,
                                      min_delay=lo, max_delay=hi, report=report)
    late = [t.seconds - t.delay for t in trials if t.outcome == "ok_interrupted"]
    seconds = time.monotonic() - start
    print(f"\n{args.trials} trials (res {args.res}, {args.spp} spp, seed {args.seed}) in {seconds:.0f} s")
    for outcome in ("ok_interrupted", "ok_finished", "before_our_code", *T.FAILURES):
        print(f"  {outcome:16s} {counts[outcome]}")
    if late:
        print(f"  signal-to-exit seconds: median {statistics.median(late):.3f}, max {max(late):.3f}")
    return 1 if any(counts[f] for f in T.FAILURES) else 0


if __name__ == "__main__":
    sys.exit(main())
