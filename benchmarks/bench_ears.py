"""Efficiency-aware roulette and splitting (``ears``) against ``nee``: 1 / (MSE x CPU s) on bench_vs_mitsuba.py's scenes.

    python benchmarks/bench_ears.py                                  # 64^2 at 16 and 64 spp, references of 2048 spp
    python benchmarks/bench_ears.py --size 128 --ref-spp 1024        # 128^2
    python benchmarks/bench_ears.py --integrators nee,ears --scenes indirect

Rows: ``nee`` (no roulette, the default), ``nee:rrK`` (its throughput roulette from K hits,
``RenderSettings.roulette_depth``), ``ears`` (its defaults: the decisions aim at absolute error,
which is what this table measures) and ``ears:rel`` (the option ``relative``: relative error, as the
paper); other rows as bench_guiding.py's (``ears:grid=8``: an option of the integrator by name).
Renders, references (shared with bench_guiding.py's cache) and timing are bench_guiding.py's:
single-threaded, CPU seconds (``time.process_time``), kernels compiled before, MSE and seconds
averaged over ``--seeds`` seeds, the reference's own MSE subtracted. ``ears``'s seconds include its
training samples and the host's table; its spp are the caller's, training included.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_guiding import efficiency_rows, parse_config, print_table  # noqa: E402


def configure(text: str) -> tuple[str, int, dict]:
    """(integrator, roulette depth, integrator options) of a row's name (bench_guiding.parse_config);
    ``rel`` is short for the option ``relative=true``."""
    return parse_config(":".join("relative=true" if m == "rel" else m for m in text.split(":")))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", default="cornell,indirect,caustics")
    ap.add_argument("--integrators", default="nee,nee:rr3,ears,ears:rel")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--size", type=int, default=64)
    ap.add_argument("--spp", default="16,64")
    ap.add_argument("--ref-spp", type=int, default=2048)
    ap.add_argument("--cache", default=str(Path(tempfile.gettempdir()) / "warp_spt_bench"))
    args = ap.parse_args()
    spps = tuple(int(x) for x in args.spp.split(","))
    configs = {key: (lambda c=configure(key): c) for key in args.integrators.split(",")}
    print_table(efficiency_rows(args.scenes.split(","), configs, args.size, spps, args.ref_spp, Path(args.cache),
                                args.seeds), args.size)
    return 0


if __name__ == "__main__":
    sys.exit(main())
