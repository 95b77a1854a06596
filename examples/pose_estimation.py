"""Pose estimation with warp_spt: recover a box's position and rotation from a photo of it.

    python examples/pose_estimation.py            (PYTHONPATH=. python ... from a checkout not installed)
    python examples/pose_estimation.py --quick    (24 x 24 pixels, 60 iterations: what tests/ runs)

The box (three colours, under a gradient sky) starts 25 degrees and a fifth of its size away from its
true pose; Adam on the L2 loss over ``box.obj.translation`` and ``box.obj.rotation`` (a rotation
vector) brings it back. The gradient carries the box's silhouette and edges (the boundary term of
warp_spt.diff.boundary) besides its shading. See warp_spt.diff.pose_demo and docs/gradients.md.
"""

from __future__ import annotations

import argparse

from warp_spt.diff.pose_demo import figure, recover


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a small run (under two minutes on 2 cores)")
    ap.add_argument("--figure", help="write the start, the result, the target and the error curve to this PNG")
    args = ap.parse_args()

    def log(it, loss, err):
        print(f"iteration {it:3d}: loss {loss:.4e}, pose_error {err:.3f}")

    r = recover(args.quick, log=log)
    print(f"rotation off by {r.rotation_deg:.3f} degrees, translation by {r.translation_percent:.3f}% of the box "
          f"({r.seconds_per_iteration:.2f} s per iteration)")
    if args.figure:
        figure(r).save(args.figure)
    print(f"final: pose_error {r.error:.4f} (start {r.start_error:.4f})")


if __name__ == "__main__":
    main()
