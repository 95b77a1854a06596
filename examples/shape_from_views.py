"""Shape from views with warp_spt: a sphere mesh refined into a blob from rendered views (8; 6 with --quick).

    python examples/shape_from_views.py            (PYTHONPATH=. python ... from a checkout not installed)
    python examples/shape_from_views.py --quick    (642 vertices, 6 views of 24 x 24 pixels: what tests/ runs)

The blob (a sphere with four low-frequency bumps, grey, under a procedural environment map) is seen
by eight cameras; an icosphere starts in its place and Large Steps (warp_spt.diff.large_steps:
uniform Adam on the latent (I + lam L) v) moves its vertices on the L2 loss summed over the views,
with the outline's boundary term in each view's gradient. The Chamfer distance to the target surface
is printed per iteration. See warp_spt.diff.shape_demo and docs/gradients.md.
"""

from __future__ import annotations

import argparse

import numpy as np

from warp_spt.diff.shape_demo import figure, recover


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="a small run (under two minutes on 2 cores)")
    ap.add_argument("--seed", type=int, default=0, help="the run's random seed (targets and gradients)")
    ap.add_argument("--figure", help="write the start, the result, the target and the Chamfer curve to this PNG")
    args = ap.parse_args()

    def log(it, loss, dist):
        print(f"iteration {it:3d}: loss {loss:.4e}, chamfer {dist:.5f}", flush=True)

    r = recover(args.quick, seed=args.seed, log=log)
    cg = np.asarray(r.cg_iterations)
    print(f"{r.seconds_per_iteration:.2f} s per iteration; conjugate-gradient iterations per solve: "
          f"gradient {cg[0::2].mean():.1f}, positions {cg[1::2].mean():.1f} (mean), {cg.max()} at most")
    if args.figure:
        figure(r).save(args.figure)
    print(f"final: chamfer {r.chamfer:.5f} (start {r.start_chamfer:.5f})")


if __name__ == "__main__":
    main()
