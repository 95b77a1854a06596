"""Physics to pixels: a thrown ball's launch velocity recovered from a strobe photograph, by gradient
descent through a Warp simulation and the render on one tape.

    python examples/physics_to_pixels.py            (PYTHONPATH=. python ... from a checkout not installed)
    python examples/physics_to_pixels.py --quick    (48 x 32 pixels, 40 iterations: what tests/ runs)

The simulation (warp_spt.diff.physics_demo: a ball under gravity bouncing on a damped-spring floor,
semi-implicit Euler, written as ordinary Warp kernels) runs on a wp.Tape; warp_spt.render_arrays
renders its states at five instants as one image on the same tape; a Warp kernel takes the L2 loss
against the target photograph; tape.backward gives d loss / d v0 through all of it. Adam on v0 starts
0.97 m/s from the truth. See docs/gradients.md, "Inverse rendering".
"""

from __future__ import annotations

import argparse

from warp_spt.diff.physics_demo import figure, recover


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a small run (under two minutes on 2 cores)")
    ap.add_argument("--seed", type=int, default=0, help="the run's seed (target and iterations)")
    ap.add_argument("--no-boundary", action="store_true", help="leave the boundary terms out (the control)")
    ap.add_argument("--figure", help="write the start, the result, the target and the error curve to this PNG")
    args = ap.parse_args()

    def log(it, loss, err):
        print(f"iteration {it:3d}: loss {loss:.4e}, v0 error {err:.4f} m/s")

    r = recover(args.quick, seed=args.seed, log=log, boundary=not args.no_boundary)
    print(f"v0 = ({r.v0[0]:.3f}, {r.v0[1]:.3f}, {r.v0[2]:.3f}) m/s ({r.seconds_per_iteration:.2f} s per iteration)")
    if args.figure:
        figure(r).save(args.figure)
    print(f"final: v0_error {r.error:.4f} (start {r.start_error:.4f})")


if __name__ == "__main__":
    main()
