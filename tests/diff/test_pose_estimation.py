"""examples/pose_estimation.py --quick, as a user runs it: it recovers the box's pose from a
rendered target and ends with ``final: pose_error VALUE (start VALUE)``.

Tolerance from the runs' own spread: over seeds 0..2 the quick run ended at pose_error
(degrees plus percent of the box's size): 1.05, 0.83 and 1.58, from a start of 44.7; 5 is three times the worst
and a ninth of the start."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_the_pose_example_converges():
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, str(ROOT / "examples" / "pose_estimation.py"), "--quick"],
                         capture_output=True, text=True, env=env, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    m = re.search(r"^final: pose_error ([0-9.]+) \(start ([0-9.]+)\)$", out.stdout, re.M)
    assert m, out.stdout[-2000:]
    final, start = float(m.group(1)), float(m.group(2))
    assert start > 40 and final < 5.0, (final, start)
