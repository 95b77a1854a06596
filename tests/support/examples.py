"""An example of examples/ run as a user runs it, its last line read: ``final: NAME VALUE (start VALUE)``."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def run_example(script: str, metric: str, *args: str) -> tuple[float, float]:
    """(final, start) of ``metric`` from ``examples/<script> --quick <args>`` in a subprocess; fails the
    test with the example's output when it exits non-zero or prints no such line."""
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, str(ROOT / "examples" / script), "--quick", *args],
                         capture_output=True, text=True, env=env, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    m = re.search(rf"^final: {re.escape(metric)} ([0-9.eE+-]+) \(start ([0-9.eE+-]+)\)$", out.stdout, re.M)
    assert m, out.stdout[-2000:]
    return float(m.group(1)), float(m.group(2))
