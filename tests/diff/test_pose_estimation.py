"""examples/pose_estimation.py --quick, as a user runs it: it recovers the box's pose from a
rendered target and ends with ``final: pose_error VALUE (start VALUE)``.

Tolerance from the runs' own spread: over seeds 0..2 the quick run ended at pose_error
(degrees plus percent of the box's size): 1.05, 0.83 and 1.58, from a start of 44.7; 5 is three times the worst
and a ninth of the start."""

from __future__ import annotations

from tests.support.examples import run_example


def test_the_pose_example_converges():
    final, start = run_example("pose_estimation.py", "pose_error")
    assert start > 40 and final < 5.0, (final, start)
