"""Build time of the top-level BVH (numpy, binned SAH) for 1e3, 1e4 and 1e5 boxes.

Run: python benchmarks/bench_tlas.py
"""

from __future__ import annotations

import sys
import timeit
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

from warp_spt.accel.tlas import build_tlas


def boxes(kind: str, k: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """'uniform' random boxes, 'clustered' ones, or 'identical' (degenerate) ones."""
    if kind == "identical":
        lo = np.zeros((k, 3))
        return lo, lo + 1.0
    if kind == "clustered":
        centres = rng.uniform(-100, 100, size=(8, 3))
        c = centres[rng.integers(0, 8, size=k)] + rng.normal(scale=1.0, size=(k, 3))
    else:
        c = rng.uniform(-100, 100, size=(k, 3))
    h = rng.exponential(0.3, size=(k, 3))
    return c - h, c + h


def main() -> None:
    rng = np.random.default_rng(0)
    print(f"{'boxes':>8} {'layout':>10} {'nodes':>8} {'depth':>6} {'build ms':>10}")
    for k in (1_000, 10_000, 100_000):
        for kind in ("uniform", "clustered", "identical"):
            lo, hi = boxes(kind, k, rng)
            tlas = build_tlas(lo, hi)
            seconds = min(timeit.repeat(lambda: build_tlas(lo, hi), number=1, repeat=3 if k < 100_000 else 1))
            print(f"{k:>8} {kind:>10} {tlas.num_nodes:>8} {tlas.depth:>6} {seconds * 1e3:>10.1f}")


if __name__ == "__main__":
    main()
