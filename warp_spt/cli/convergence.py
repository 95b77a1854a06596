"""``warp-spt convergence``: the command line of the convergence report (:mod:`warp_spt.rendering.convergence`)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import Sequence

import numpy as np

from warp_spt.rendering.convergence import (
    REF_SUFFIXES,
    SLOPE_TOLERANCE,
    default_configs,
    parse_config,
    run_report,
    write_csv,
    write_json,
    write_plot,
)

PROG = "warp-spt convergence"


def _parser(defaults: Sequence[str] = (), left_out: Sequence[str] = ()) -> argparse.ArgumentParser:
    """The parser; ``defaults`` (the default configurations) and ``left_out`` (the integrators that
    train over passes of their own, which the report cannot pace) from the registries, for --help."""
    from warp_spt.cli.common import Parser, int_at_least

    p = Parser(prog=PROG, add_help=False, allow_abbrev=False,
                description="Convergence report: error against samples and time, per configuration. "
                            "Takes the usual scene flags (-obj, -mtl, -cam, -res, -depth, -sky, --demo, ...).")
    p.add_argument("-h", "--help", action="store_true")
    p.add_argument("--max-spp", type=int_at_least(1, 1 << 16), default=64, metavar="N",
                   help="render 1, 2, 4, ... N spp (default 64)")
    p.add_argument("--reference", metavar="PATH", help="reference image (.npy/.pfm, linear) instead of rendering one")
    p.add_argument("--reference-spp", type=int_at_least(2, 1 << 20), metavar="N",
                   help="samples per pixel of the rendered reference (default 16 x --max-spp)")
    p.add_argument("--configs", metavar="LIST",
                   help="comma-separated INTEGRATOR/SAMPLER[+adaptive|+denoised] (default: "
                        + (", ".join(defaults) if defaults else "every integrator that renders in plain passes "
                           "with every sampler, and the default pair +adaptive")
                        + (f"; not {', '.join(left_out)}, which train over passes of their own" if left_out else "")
                        + ")")
    p.add_argument("--denoise", action="store_true", help="add the default pair +denoised (needs pyoidn)")
    p.add_argument("--prefix", default="convergence", metavar="PATH",
                   help="writes PATH.csv, PATH.json and PATH.png (default ./convergence)")
    p.add_argument("--no-plot", action="store_true", help="skip the PNG plot")
    return p


def main(argv: Sequence[str]) -> int:
    """``warp-spt convergence ...``: returns the exit status; errors are one line, as in the main CLI."""
    from warp_spt.cli.common import (
        EXIT_FAILURE,
        EXIT_INTERRUPTED,
        EXIT_USAGE,
        RunError,
        UsageError,
        fail,
    )
    from warp_spt.cli.options import parse_args

    err = sys.stderr
    try:
        ns, rest = _parser().parse_known_args(list(argv))
        if ns.help:
            from warp_spt.integrators import INTEGRATORS
            left_out = sorted(n for n, r in INTEGRATORS.items() if r.render_passes is not None)
            print(_parser(default_configs(), left_out).format_help(), end="")
            return 0
        configs = [c.strip() for c in ns.configs.split(",") if c.strip()] if ns.configs else default_configs()
        configs = list(dict.fromkeys(configs + ["denoised"] * ns.denoise))
        for c in configs:
            try:
                parse_config(c)
            except ValueError as e:
                raise UsageError(f"--configs: {e}") from None
        if ns.reference and Path(ns.reference).suffix.lower() not in REF_SUFFIXES:
            raise UsageError(f"--reference {ns.reference!r}: must be .npy or .pfm (linear radiance)")
        opts = parse_args(rest)
        return _run(ns, opts, configs, err)
    except UsageError as e:
        return fail(f"{e} (see {PROG} --help)", EXIT_USAGE, err)
    except (RunError, ValueError, RuntimeError, OSError) as e:
        return fail(str(e), EXIT_FAILURE, err)
    except KeyboardInterrupt:
        print(f"\n{PROG}: interrupted", file=err)
        return EXIT_INTERRUPTED


def _run(ns, opts, configs: list[str], err) -> int:
    from warp_spt.cli.common import init_warp, scene_files
    from warp_spt.images.files import load_image
    from warp_spt.io.loader import load_scene

    say = (lambda msg: None) if opts.quiet else (lambda msg: print(f"{PROG}: {msg}", file=err))
    if any("denoised" in parse_config(c)[2] for c in configs):
        from warp_spt.rendering.denoise import require

        require()
    if not ns.no_plot:
        try:
            import matplotlib  # noqa: F401
        except ImportError:
            from warp_spt.runtime.extras import install_hint
            raise RuntimeError(f"the PNG plot needs matplotlib: {install_hint('plot')}, or pass --no-plot") from None
    init_warp(opts)
    objs, mtls = scene_files(opts)
    scene = load_scene(objs, mtls, warn=lambda message: None)
    reference = None if ns.reference is None else load_image(ns.reference).astype(np.float64)
    rows, fits, ref_info = run_report(
        scene, opts.camera, width=opts.width, height=opts.height, max_spp=ns.max_spp,
        reference_spp=ns.reference_spp or 16 * ns.max_spp, reference=reference, configs=configs, seed=opts.seed,
        say=say, max_depth=opts.depth, sky=opts.sky, threads=opts.threads, texture_filter=opts.texture_filter)
    meta = dict(scene=[str(p) for p in objs], width=opts.width, height=opts.height, depth=opts.depth,
                reference=ref_info, slope_tolerance=SLOPE_TOLERANCE)
    write_csv(f"{ns.prefix}.csv", rows)
    write_json(f"{ns.prefix}.json", rows, fits, meta)
    if not ns.no_plot:
        write_plot(f"{ns.prefix}.png", rows, fits, title=f"{opts.width}x{opts.height}, depth {opts.depth}")
    for config, fit in fits.items():
        say(f"{config}: log-log slope of RMSE against spp {fit.slope:.3f}")
        if fit.warning:
            print(f"{PROG}: warning: {config}: {fit.warning}", file=err)
    say(f"wrote {ns.prefix}.csv, {ns.prefix}.json" + ("" if ns.no_plot else f", {ns.prefix}.png"))
    return 0
