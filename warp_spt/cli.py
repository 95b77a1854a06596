"""The ``warp-spt`` command line: the seed's flags unchanged, plus what a modern tool needs.

Two steps, so the first can be tested without rendering: :func:`parse_args` turns argv into a
validated :class:`Options` (pure: no files, no Warp), and :func:`run` loads, renders and saves.
:func:`main` ties them together and turns every failure into one ``warp-spt: error: ...`` line.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence, TextIO

from . import __version__
from .camera import Camera
from .cli_progressive import BudgetOptions, add_flags, check_outputs, options, process_start, render_and_save
from .demo import PRESETS, demo_files
from .integrators import INTEGRATORS
from .progress import ProgressBar
from .samplers import SAMPLERS
from .sky import Sky

PROG = "warp-spt"
OUTPUT_SUFFIXES = (".png", ".npy", ".pfm")
EXIT_OK, EXIT_FAILURE, EXIT_USAGE, EXIT_INTERRUPTED = 0, 1, 2, 130

# The seed's defaults (SEMANTICS §1); the output name follows its Readme, not its code (Q14).
DEFAULT_RES, DEFAULT_SPP, DEFAULT_DEPTH, DEFAULT_SKY, DEFAULT_OUT = (500, 500), 16, 6, 0, "output.png"
# Caps that keep nothing absurd from reaching a kernel; values above them are surely typos.
MAX_SPP, MAX_DEPTH = 1 << 20, 4096
# Film, accumulation and output buffers per pixel, with headroom for tiles and PNG encoding.
BYTES_PER_PIXEL = 64
MEMORY_FRACTION = 0.5

EXAMPLES = """\
examples:
  warp-spt                                   render the built-in demo to output.png
  warp-spt --demo 512p16s                    the seed's quick demo script (512x512, 16 spp)
  warp-spt -mtl scene.mtl -obj room.obj -obj balls.obj -sky 1 -res 512 512 -sr 32 -out room.png
  warp-spt -obj model.obj -cam 4 -55 16 0 1 0 38 27 0.001 --sky-color 0 0 0 -out model.pfm

-cam takes the order of the seed's design document: px py pz dx dy dz fov focus aperture
(the seed's Java code read fov aperture focus). d is a view direction, not a target; fov is the
horizontal angle in degrees. -sky: 0 the seed's 'BlackSky' (a dull blue), 1 gradient, 2 pink.
.png is tone-mapped, .npy and .pfm hold linear radiance. Exit status: 0 ok, 1 failure,
2 bad arguments, 130 interrupted.
"""


class UsageError(Exception):
    """A bad command line: reported as one line, exit status 2."""


class RunError(Exception):
    """A failure after parsing (unreadable input, output directory missing): exit status 1."""


@dataclass(frozen=True)
class Options:
    """A validated command line. ``action`` is "render", "help" or "version"."""

    action: str = "render"
    objs: tuple[str, ...] = ()
    mtls: tuple[str, ...] = ()
    camera: Camera = field(default_factory=Camera)
    width: int = DEFAULT_RES[0]
    height: int = DEFAULT_RES[1]
    spp: int = DEFAULT_SPP
    depth: int = DEFAULT_DEPTH
    sky: Sky = field(default_factory=Sky.black)
    out: str = DEFAULT_OUT
    threads: int | None = None
    seed: int = 0
    tonemap: str = "seed"
    texture_filter: str = "nearest"
    quiet: bool = False
    demo: str | None = None
    integrator: str | None = None     # None: the renderer's default
    sampler: str | None = None
    budget: BudgetOptions = field(default_factory=BudgetOptions)   # cli_progressive's flags

    @property
    def uses_demo_scene(self) -> bool:
        """No ``-obj`` given: the built-in demo scene is rendered."""
        return not self.objs


class _Parser(argparse.ArgumentParser):
    """argparse that raises instead of printing the usage and exiting."""

    def error(self, message: str):  # type: ignore[override]
        raise UsageError(message)


def _int_at_least(low: int, high: int | None = None):
    def convert(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}") from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be at least {low}, got {value}")
        if high is not None and value > high:
            raise argparse.ArgumentTypeError(f"must be at most {high}, got {value}")
        return value
    convert.__name__ = "integer"
    return convert


def _finite_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
    return value


def _sky_index(text: str) -> int:
    # The seed mapped any unknown integer to BlackSky; a modern CLI reports the typo instead.
    if text not in ("0", "1", "2"):
        raise argparse.ArgumentTypeError(f"expected 0 (BlackSky), 1 (gradient) or 2 (pink), got {text!r}")
    return int(text)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser; single-dash multi-letter flags are the seed's, ``--`` flags are new."""
    p = _Parser(prog=PROG, add_help=False, allow_abbrev=False, epilog=EXAMPLES,
                formatter_class=argparse.RawDescriptionHelpFormatter,
                description="A physically based path tracer on NVIDIA Warp. It reads the command lines\n"
                            "and the OBJ/MTL dialect of the seed, SimplePathTracer, and standard OBJ/MTL.")
    seed = p.add_argument_group("the seed's flags")
    seed.add_argument("-obj", action="append", default=[], metavar="PATH", help="OBJ file (repeatable)")
    seed.add_argument("-mtl", action="append", default=[], metavar="PATH", help="MTL file (repeatable, any order)")
    seed.add_argument("-cam", nargs=9, type=_finite_float,
                      metavar=("PX", "PY", "PZ", "DX", "DY", "DZ", "FOV", "FOCUS", "APERTURE"),
                      help="camera: position, view direction, horizontal fov (degrees), focus distance, "
                           "lens radius (default 4 -55 16 0 1 0 38 27 0.001)")
    seed.add_argument("-res", nargs=2, type=_int_at_least(1), metavar=("W", "H"), help="image size (default 500 500)")
    seed.add_argument("-depth", type=_int_at_least(1, MAX_DEPTH), metavar="N",
                      help="maximum surface hits per path (default 6)")
    seed.add_argument("-sr", type=_int_at_least(1, MAX_SPP), metavar="N", help="samples per pixel (default 16)")
    seed.add_argument("-sky", type=_sky_index, metavar="0|1|2", help="0 BlackSky (default), 1 gradient, 2 pink")
    seed.add_argument("-out", metavar="PATH", help="output .png, .npy or .pfm (default output.png)")
    new = p.add_argument_group("further options")
    new.add_argument("-h", "--help", action="store_true", help="show this help and exit")
    new.add_argument("--version", action="store_true", help="print the version and exit")
    new.add_argument("--demo", choices=sorted(PRESETS), metavar="PRESET",
                     help="render the built-in demo like the seed's script: " + ", ".join(PRESETS))
    new.add_argument("--threads", type=_int_at_least(1), metavar="N", help="worker threads (default: all cores)")
    new.add_argument("--seed", type=_int_at_least(0, 2**32 - 1), default=0, metavar="N",
                     help="random seed (default 0): the same seed gives the same image")
    new.add_argument("--sky-color", nargs=3, type=_finite_float, metavar=("R", "G", "B"),
                     help="a constant sky instead of -sky; 0 0 0 for none")
    new.add_argument("--tonemap", choices=("seed", "srgb"), default="seed",
                     help="PNG mapping: the seed's curve (default) or sRGB")
    new.add_argument("--filter", choices=("nearest", "bilinear"), default="nearest", dest="texture_filter",
                     help="texture lookup (default nearest, as the seed)")
    new.add_argument("--quiet", action="store_true", help="no progress bar or messages")
    new.add_argument("--integrator", choices=sorted(INTEGRATORS),
                     help="light transport: nee (light sampling with MIS) or seed (pure path tracing)")
    new.add_argument("--sampler", choices=sorted(SAMPLERS),
                     help="random numbers: sobol (Owen-scrambled Sobol') or independent")
    add_flags(p, _int_at_least)
    return p


def parse_args(argv: Sequence[str], *, memory_bytes: int | None = None) -> Options:
    """Parse and validate a command line (without the program name). Raises :class:`UsageError`.

    ``memory_bytes`` is the RAM budget for the image size check (default: half the machine's).
    """
    parser = build_parser()
    _reject_unknown_flags(argv, parser)
    ns = parser.parse_args(list(argv))
    if ns.help or ns.version:
        return Options(action="help" if ns.help else "version")
    if ns.demo and ns.obj:
        raise UsageError("--demo renders the built-in scene; it cannot be combined with -obj")
    if ns.mtl and not ns.obj:
        raise UsageError("-mtl given without any -obj file to use it")
    if ns.sky is not None and ns.sky_color is not None:
        raise UsageError("give either -sky or --sky-color, not both")
    preset = PRESETS.get(ns.demo) if ns.demo else None
    width, height = ns.res or ((preset.width, preset.height) if preset else DEFAULT_RES)
    check_image_size(width, height, memory_bytes)
    out = ns.out or (preset.output_name(ns.demo) if preset else DEFAULT_OUT)
    if Path(out).suffix.lower() not in OUTPUT_SUFFIXES:
        raise UsageError(f"-out {out!r}: the file name must end in .png, .npy or .pfm")
    return Options(
        objs=tuple(ns.obj), mtls=tuple(ns.mtl), camera=_camera(ns.cam),
        width=width, height=height,
        spp=ns.sr or (preset.spp if preset else DEFAULT_SPP),
        depth=ns.depth or (preset.depth if preset else DEFAULT_DEPTH),
        sky=_sky(ns.sky, ns.sky_color, preset.sky if preset else DEFAULT_SKY),
        out=out, threads=ns.threads, seed=ns.seed, tonemap=ns.tonemap,
        texture_filter=ns.texture_filter, quiet=ns.quiet, demo=ns.demo,
        integrator=ns.integrator, sampler=ns.sampler,
        budget=options(ns, UsageError, OUTPUT_SUFFIXES),
    )


def _reject_unknown_flags(argv: Sequence[str], parser: argparse.ArgumentParser) -> None:
    """Only exact flags: argparse would take ``-ob`` for ``-obj`` even with allow_abbrev=False."""
    known = {name for action in parser._actions for name in action.option_strings}
    for token in argv:
        if token == "--":
            return
        name = token.split("=", 1)[0] if token.startswith("--") else token
        if token.startswith("-") and len(token) > 1 and name not in known and not _is_number(token):
            raise UsageError(f"unknown flag {token!r}")


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _camera(values: list[float] | None) -> Camera:
    if values is None:
        return Camera()
    cam = Camera(position=tuple(values[0:3]), direction=tuple(values[3:6]),
                 fov=values[6], focus=values[7], aperture=values[8])
    try:
        cam.validate()
    except ValueError as err:
        raise UsageError(f"argument -cam: {err}") from None
    return cam


def _sky(index: int | None, colour: list[float] | None, fallback: int) -> Sky:
    if colour is None:
        return Sky.from_index(fallback if index is None else index)
    try:
        return Sky.constant(*colour)
    except ValueError as err:
        raise UsageError(f"argument --sky-color: {err}") from None


def available_memory() -> int:
    """Physical RAM in bytes (8 GiB when the platform does not say)."""
    try:
        return int(os.sysconf("SC_PAGE_SIZE")) * int(os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):
        return 8 << 30


def check_image_size(width: int, height: int, memory_bytes: int | None = None) -> None:
    """Refuse images whose buffers would not fit in the memory budget (instead of thrashing or crashing)."""
    budget = memory_bytes if memory_bytes is not None else int(available_memory() * MEMORY_FRACTION)
    need = width * height * BYTES_PER_PIXEL
    if need > budget:
        raise UsageError(f"-res {width} {height} needs about {need / 2**30:.1f} GiB for the image buffers, "
                         f"more than the {budget / 2**30:.1f} GiB this machine can spare")


def scene_files(opts: Options) -> tuple[list[str], list[str]]:
    """The OBJ and MTL files to load: the user's, or the built-in demo's."""
    if opts.uses_demo_scene:
        try:
            return demo_files()
        except FileNotFoundError as err:
            raise RunError(str(err)) from None
    return list(opts.objs), list(opts.mtls)


def check_files(objs: Sequence[str], mtls: Sequence[str], out: str) -> None:
    """Fail early, before any loading or rendering, on unreadable inputs or an unwritable output place."""
    for flag, paths in (("-obj", objs), ("-mtl", mtls)):
        for path in paths:
            try:
                with open(path, "rb"):
                    pass
            except OSError as err:
                raise RunError(f"cannot read {flag} file {path!r}: {err.strerror or err}") from None
            if Path(path).is_dir():
                raise RunError(f"cannot read {flag} file {path!r}: it is a directory")
    parent = Path(out).parent
    if not parent.is_dir():
        raise RunError(f"cannot write -out {out!r}: directory {str(parent)!r} does not exist")
    if not os.access(parent, os.W_OK):
        raise RunError(f"cannot write -out {out!r}: directory {str(parent)!r} is not writable")
    if Path(out).is_dir():
        raise RunError(f"cannot write -out {out!r}: it is a directory")


def run(opts: Options, *, stderr: TextIO | None = None, started: float | None = None) -> int:
    """Load, render and save as ``opts`` says. Errors propagate; :func:`main` reports them.

    ``started`` (a perf_counter value, default now) is when the command started: --time-budget counts from it.
    """
    started = time.perf_counter() if started is None else started
    err = stderr or sys.stderr
    objs, mtls = scene_files(opts)
    check_files(objs, mtls, opts.out)
    check_outputs(opts.budget, RunError)
    say = (lambda msg: None) if opts.quiet else (lambda msg: print(f"{PROG}: {msg}", file=err))
    _quiet_warp(opts.quiet)
    from .film import save_image
    from .loader import load_scene
    from .renderer import render

    start = time.perf_counter()
    scene = load_scene(objs, mtls, warn=lambda message: None)   # collected in scene.warnings, shown below
    for warning in scene.warnings:
        say(f"warning: {warning}")
    what = f"the built-in demo ({opts.demo or 'default'})" if opts.uses_demo_scene else f"{len(objs)} OBJ file(s)"
    say(f"loaded {what}: {scene.num_triangles:,} triangles, {len(scene.spheres)} spheres "
        f"in {time.perf_counter() - start:.1f} s; rendering {opts.width}x{opts.height}, "
        f"{opts.spp} spp, depth {opts.depth}")
    if opts.budget.active:
        return render_and_save(opts, scene, say=say, started=started)
    bar = None if opts.quiet else ProgressBar(opts.width * opts.height * opts.spp, file=err)
    start = time.perf_counter()
    try:
        image = render(scene, opts.camera, width=opts.width, height=opts.height, spp=opts.spp,
                       max_depth=opts.depth, sky=opts.sky, seed=opts.seed, threads=opts.threads,
                       texture_filter=opts.texture_filter, progress=bar or False,
                       **{k: v for k, v in (("integrator", opts.integrator), ("sampler", opts.sampler)) if v})
    finally:
        if bar is not None:
            bar.close()
    seconds = time.perf_counter() - start
    save_image(opts.out, image, tonemap=opts.tonemap)
    rate = opts.width * opts.height * opts.spp / max(seconds, 1e-9)
    say(f"wrote {opts.out} ({seconds:.1f} s, {rate / 1e6:.2f} M samples/s)")
    return EXIT_OK


def _quiet_warp(quiet: bool) -> None:
    """Warp logs a banner and kernel-load lines at INFO on stdout; a CLI's stdout should stay clean.

    ``--quiet`` also hides warnings, such as the missing CUDA driver on a CPU-only machine.
    """
    try:
        import warp
        warp.config.log_level = warp.LOG_ERROR if quiet else warp.LOG_WARNING
    except Exception:  # Warp missing or changed: the renderer will report the real problem
        pass


def _fail(message: str, status: int, stderr: TextIO) -> int:
    print(f"{PROG}: error: {message}", file=stderr)
    return status


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``warp-spt`` and ``python -m warp_spt``; returns the exit status."""
    from .errors import SceneError

    # --time-budget covers start-up, load and compile; called from Python, it counts from this call
    started = process_start() if argv is None else time.perf_counter()
    stderr = sys.stderr
    argv = sys.argv[1:] if argv is None else list(argv)
    if argv[:1] == ["convergence"]:
        from .convergence import main as convergence_main
        return convergence_main(argv[1:])
    try:
        opts = parse_args(argv)
        if opts.action == "help":
            print(build_parser().format_help(), end="")
            return EXIT_OK
        if opts.action == "version":
            print(f"{PROG} {__version__}")
            return EXIT_OK
        return run(opts, stderr=stderr, started=started)
    except UsageError as err:
        return _fail(f"{err} (see {PROG} --help)", EXIT_USAGE, stderr)
    except (RunError, SceneError) as err:
        return _fail(str(err), EXIT_FAILURE, stderr)
    except KeyboardInterrupt:
        print(f"\n{PROG}: interrupted", file=stderr)
        return EXIT_INTERRUPTED
    except MemoryError:
        return _fail("out of memory: try a smaller -res or fewer --threads", EXIT_FAILURE, stderr)
    except OSError as err:
        where = f" {err.filename!r}" if err.filename else ""
        return _fail(f"{err.strerror or err}{where}", EXIT_FAILURE, stderr)
    except Exception as err:  # a bug: still one line, with a way to see the traceback
        if os.environ.get("WARP_SPT_TRACEBACK"):
            raise
        return _fail(f"internal error: {type(err).__name__}: {err} (set WARP_SPT_TRACEBACK=1 for details)",
                     EXIT_FAILURE, stderr)
