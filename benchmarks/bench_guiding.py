"""Path guiding's efficiency against ``nee``: 1 / (MSE x CPU seconds) on bench_vs_mitsuba.py's three scenes.

    python benchmarks/bench_guiding.py              # 64^2 at 16 and 64 spp, references of 2048 spp
    python benchmarks/bench_guiding.py --quick      # 32^2 at 8 and 32 spp, references of 512 spp
    python benchmarks/bench_guiding.py --size 128 --ref-spp 1024   # a larger image (fixed costs amortised)

Scenes: ``cornell`` (direct light dominates), ``indirect`` (a closed room lit from a pillar's top
facing the ceiling: everything seen is lit after two or more bounces) and ``caustics`` (glass and
mirror balls, a small light, a dim sky), exactly as ``bench_vs_mitsuba.py`` builds them. The
reference is ``nee`` + Sobol' at high spp, the mean of two halves with different seeds, cached in
``--cache``; its own MSE (a quarter of the halves' mean squared difference) is subtracted from each
estimate's. Every render is single-threaded and timed in CPU seconds (``time.process_time``:
the machine is shared, so wall time measures the load), kernels compiled before; each cell is
averaged over ``--seeds`` seeds (MSE and seconds). ``guided`` includes its training passes and
tree builds: its spp are the caller's, training included. Options ``--integrators`` add rows:
a name, then ``:``-separated modifiers, ``rrK`` (a roulette depth) or ``NAME=VALUE`` (an option of
the integrator, ``RenderSettings.integrator_options``), e.g. ``guided:rr4`` or ``guided:alpha=0.25``.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parent))

from bench_vs_mitsuba import SCENES, warp_camera, warp_scene, warp_settings  # noqa: E402


def render(scene, desc, size, spp, integrator, seed, roulette=0, threads=1, options=None):
    from warp_spt import RenderSettings, render_scene
    kw = warp_settings(desc, size, spp, integrator, "sobol", seed, threads)
    rs = RenderSettings(**kw, roulette_depth=roulette, integrator_options=options or {})
    t = time.process_time()
    img = render_scene(scene, warp_camera(desc), rs).image.astype(np.float64)
    return img, time.process_time() - t


def reference(name, scene, desc, size, spp, cache: Path):
    path = cache / f"guiding_ref_{name}_{size}_{spp}.npz"
    if path.exists():
        d = np.load(path)
        return d["a"], d["b"]
    a, _ = render(scene, desc, size, spp // 2, "nee", 7001, threads=2)     # references: wall time only
    b, _ = render(scene, desc, size, spp // 2, "nee", 7002, threads=2)
    np.savez(path, a=a, b=b)
    return a, b


def parse_config(text: str) -> tuple[str, int, dict]:
    """(integrator, roulette depth, integrator options) of a row's name: ``name[:rrK][:OPTION=VALUE]...``
    (each option parsed by the integrator's parameter, ``Integrator.parse_options``)."""
    from warp_spt.integrators import get_integrator
    name, *mods = text.split(":")
    rr = [int(m[2:]) for m in mods if m.startswith("rr") and "=" not in m]
    pairs = [tuple(m.split("=", 1)) for m in mods if "=" in m]
    if len(rr) + len(pairs) != len(mods):
        raise SystemExit(f"bad row {text!r}: modifiers are rrK or NAME=VALUE")
    return name, rr[-1] if rr else 0, get_integrator(name).parse_options(pairs)


def efficiency(render_seed, seeds: int, ref: np.ndarray, ref_mse: float) -> tuple[float, float, float]:
    """(MSE, CPU s, 1 / (MSE x CPU s)) averaged over ``seeds`` renders ``render_seed(100 + s) -> (image,
    CPU s)``, the reference's own MSE subtracted (floored at a thousandth of it)."""
    mses, secs = [], []
    for s in range(seeds):
        img, sec = render_seed(100 + s)
        mses.append(max(float(np.mean((img - ref) ** 2)) - ref_mse, 1e-3 * ref_mse))
        secs.append(sec)
    mse, sec = float(np.mean(mses)), float(np.mean(secs))
    return mse, sec, 1.0 / (mse * sec)


def report(name: str, spp: int, eff: dict) -> list[tuple]:
    """Print each configuration's efficiency over ``nee``'s; the rows of the final table."""
    base, rows = eff["nee"][2], []
    for key, (mse, sec, e) in eff.items():
        rows.append((name, spp, key, mse, sec, e / base))
        print(f"{name:9s} {spp:4d} spp  {key:12s} MSE {mse:.4g}  CPU {sec:7.2f} s  efficiency / nee {e / base:5.2f}",
              flush=True)
    return rows


def efficiency_rows(scenes: list[str], configs: dict, size: int, spps, ref_spp: int, cache: Path,
                    seeds: int) -> list[tuple]:
    """(scene, spp, key, MSE, CPU s, efficiency / nee) for each scene, spp and configuration;
    ``configs[key]()`` returns a configuration's (integrator, roulette depth, integrator options)."""
    rows = []
    cache.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        for name in scenes:
            desc = SCENES[name]
            (Path(tmp) / name).mkdir()
            scene = warp_scene(desc, Path(tmp) / name)
            ra, rb = reference(name, scene, desc, size, ref_spp, cache)
            ref, ref_mse = 0.5 * (ra + rb), float(np.mean((ra - rb) ** 2)) / 4
            for setup in configs.values():
                integ, rr, opts = setup()
                render(scene, desc, 8, 4, integ, 1, rr, options=opts)            # compile and warm
            for spp in spps:
                eff = {}
                for key, setup in configs.items():
                    integ, rr, opts = setup()
                    eff[key] = efficiency(lambda seed: render(scene, desc, size, spp, integ, seed, rr, options=opts),
                                          seeds, ref, ref_mse)
                rows += report(name, spp, eff)
    return rows


def print_table(rows: list[tuple], size: int) -> None:
    """:func:`efficiency_rows`' rows as a Markdown table."""
    print("\n| scene | size | spp | integrator | MSE | CPU s | efficiency / nee |\n|---|---|---|---|---|---|---|")
    for name, spp, key, mse, sec, ratio in rows:
        print(f"| {name} | {size} | {spp} | {key} | {mse:.4g} | {sec:.2f} | {ratio:.2f} |")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--scenes", default="cornell,indirect,caustics")
    ap.add_argument("--integrators", default="nee,guided")
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--size", type=int, default=0, help="image width and height (default 64, --quick 32)")
    ap.add_argument("--spp", default="", help="comma-separated spp (default 16,64; --quick 8,32)")
    ap.add_argument("--ref-spp", type=int, default=0, help="reference spp (default 2048; --quick 512)")
    ap.add_argument("--cache", default=str(Path(tempfile.gettempdir()) / "warp_spt_bench"))
    args = ap.parse_args()
    size, spps, ref_spp = (32, (8, 32), 512) if args.quick else (64, (16, 64), 2048)
    size = args.size or size
    spps = tuple(int(x) for x in args.spp.split(",")) if args.spp else spps
    ref_spp = args.ref_spp or ref_spp
    configs = {key: (lambda c=parse_config(key): c) for key in args.integrators.split(",")}
    print_table(efficiency_rows(args.scenes.split(","), configs, size, spps, ref_spp, Path(args.cache), args.seeds),
                size)
    return 0


if __name__ == "__main__":
    sys.exit(main())
