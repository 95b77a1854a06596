"""Where guided's CPU time per sample goes: its passes against ``nee``'s, interleaved in one process.

    PYTHONPATH=. python benchmarks/bench_guiding_passes.py                       # indirect, 64x64, 64 spp
    PYTHONPATH=. python benchmarks/bench_guiding_passes.py --size 128 --rounds 3
    PYTHONPATH=. python benchmarks/bench_guiding_passes.py --option alpha=0.25   # guided's options by name

Each round renders ``nee`` then ``guided`` (one thread, CPU seconds, ``time.process_time``: the
machine is shared), kernels compiled before; ``guided``'s per-pass CPU ms per spp come from its
``WARP_SPT_GUIDE_TRACE`` lines. Printed, as medians over the rounds and as ratios to ``nee`` per
spp: guided's total, its last pass (no recording), its training passes from the third (guide and
recording), and the host's time outside the passes (tree refinement, alpha, uploads). Ablations
(docs/performance.md, Path guiding) are one-line edits of ``integrators/guided/__init__.py`` measured so.
"""

from __future__ import annotations

import argparse
import io
import os
import re
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_vs_mitsuba import SCENES, warp_camera, warp_scene, warp_settings  # noqa: E402

PASS_LINE = re.compile(r"pass (\d+): (\d+) spp, ([\d.]+) CPU ms/spp")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="indirect", choices=sorted(SCENES))
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--option", action="append", default=[], metavar="NAME=VALUE", help="a guided option")
    args = ap.parse_args()
    from warp_spt import RenderSettings, render_scene
    from warp_spt.integrators import get_integrator

    options = get_integrator("guided").parse_options([tuple(o.split("=", 1)) for o in args.option])
    desc = SCENES[args.scene]
    with tempfile.TemporaryDirectory() as tmp:
        scene = warp_scene(desc, Path(tmp))
        os.environ["WARP_SPT_GUIDE_TRACE"] = "1"

        def run(integ: str, spp: int) -> tuple[float, list[tuple[int, float]]]:
            rs = RenderSettings(**warp_settings(desc, args.size, spp, integ, "sobol", 101, 1),
                                integrator_options=options if integ == "guided" else {})
            err, old = io.StringIO(), sys.stderr
            sys.stderr = err                # the trace lines: per pass CPU ms per spp
            t = time.process_time()
            try:
                render_scene(scene, warp_camera(desc), rs)
            finally:
                sys.stderr = old
            sec = time.process_time() - t
            return sec, [(int(m.group(2)), float(m.group(3))) for m in PASS_LINE.finditer(err.getvalue())]

        for integ in ("nee", "guided"):
            run(integ, 4)                   # compile and warm
        rows: dict[str, list[float]] = {k: [] for k in ("nee", "guided", "last", "training", "host")}
        for _ in range(args.rounds):
            rows["nee"].append(run("nee", args.spp)[0] / args.spp * 1e3)
            sec, passes = run("guided", args.spp)
            rows["guided"].append(sec / args.spp * 1e3)
            rows["last"].append(passes[-1][1])
            rows["training"].append(float(np.mean([m for _, m in passes[2:-1]])) if len(passes) > 3 else np.nan)
            rows["host"].append((sec - sum(c * m for c, m in passes) / 1e3) / args.spp * 1e3)
    med = {k: float(np.median(v)) for k, v in rows.items()}
    print(f"{args.scene} {args.size}x{args.size} {args.spp} spp, ms per spp (x nee): nee {med['nee']:.2f}; "
          + "; ".join(f"guided {k} {med[k]:.2f} ({med[k] / med['nee']:.3f}x)"
                      for k in ("guided", "last", "training", "host")).replace("guided guided", "guided total"))
    return 0


if __name__ == "__main__":
    sys.exit(main())
