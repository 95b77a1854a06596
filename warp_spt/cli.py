"""The ``warp-spt`` command line: the seed's flags unchanged, plus what a modern tool needs.

Two steps, so the first can be tested without rendering: :func:`parse_args` turns argv into a
validated :class:`Options` (pure: no files, no Warp), and :func:`run` loads, renders and saves.
:func:`main` ties them together and turns every failure into one ``warp-spt: error: ...`` line.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
import time
import unicodedata
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Sequence, TextIO

# Only light modules here (stdlib, no numpy, no Warp): main() installs the SIGINT/SIGTERM handling
# before anything heavy is imported, so a Ctrl-C during start-up gets the same one-line message.
from . import __version__
from .demo import PRESETS, demo_files
from .progress import ProgressBar
from .signals import (cli_interruption, deferred_signals, exit_status, finish_cli_handlers, install_cli_handlers,
                      interruption_line)
from .sky import Sky

if TYPE_CHECKING:
    from .camera import Camera

PROG = "warp-spt"
OUTPUT_SUFFIXES = (".png", ".npy", ".pfm")
EXIT_OK, EXIT_FAILURE, EXIT_USAGE = 0, 1, 2
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143     # 128 + the signal number (signals.exit_status)

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
2 bad arguments, 130 interrupted (Ctrl-C, SIGINT), 143 terminated (SIGTERM).
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
    camera: Camera = field(default_factory=lambda: _camera(None))
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
    verbose: bool = False
    demo: str | None = None
    # Distribution and animation (warp_spt.cluster, warp_spt.animation)
    cluster: str | None = None
    workers: int | None = None
    frames: range | None = None
    camera_path: str | None = None
    gif: str | None = None

    @property
    def animated(self) -> bool:
        """Frames, a camera path, a GIF or an OBJ template were given: render an animation."""
        from .animation import is_template
        return bool(self.frames or self.camera_path or self.gif or any(is_template(p) for p in self.objs))

    @property
    def uses_demo_scene(self) -> bool:
        """No ``-obj`` given: the built-in demo scene is rendered."""
        return not self.objs


class _Parser(argparse.ArgumentParser):
    """argparse that raises instead of printing the usage and exiting."""

    def error(self, message: str):  # type: ignore[override]
        raise UsageError(message)


# Plain ASCII numbers only, as in OBJ files: int() and float() would also take "1_0", "inf", and
# Arabic-Indic or full-width digits.
_INT_RE = re.compile(r"[+-]?[0-9]+")
_FLOAT_RE = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")


def _int_at_least(low: int, high: int | None = None):
    def convert(text: str) -> int:
        if not _INT_RE.fullmatch(text):
            raise argparse.ArgumentTypeError(f"expected an integer, got {text!r}")
        value = int(text)
        if value < low:
            raise argparse.ArgumentTypeError(f"must be at least {low}, got {value}")
        if high is not None and value > high:
            raise argparse.ArgumentTypeError(f"must be at most {high}, got {value}")
        return value
    convert.__name__ = "integer"
    return convert


def _finite_float(text: str) -> float:
    if not _FLOAT_RE.fullmatch(text):
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}")
    value = float(text)
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
    new.add_argument("--verbose", action="store_true",
                     help="also show Warp's own messages (banner, module loads, missing CUDA driver)")
    more = p.add_argument_group("clusters and animation")
    more.add_argument("--cluster", metavar="ADDRESS", help="render on a running Dask scheduler, e.g. tcp://host:8786")
    more.add_argument("--workers", type=_int_at_least(1, 1024), metavar="N",
                      help="render on a local cluster of N worker processes")
    more.add_argument("--frames", metavar="A:B[:STEP]", help="render frames A..B-1; -obj may name "
                      "'wave_{frame:04d}.obj' and -out 'frame_{frame:04d}.png'")
    more.add_argument("--camera-path", metavar="FILE", help="JSON camera keyframes, interpolated per frame")
    more.add_argument("--gif", metavar="PATH", help="also write the frames as an animated GIF preview")
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
    if ns.quiet and ns.verbose:
        raise UsageError("give either --quiet or --verbose, not both")
    if ns.sky is not None and ns.sky_color is not None:
        raise UsageError("give either -sky or --sky-color, not both")
    preset = PRESETS.get(ns.demo) if ns.demo else None
    width, height = ns.res or ((preset.width, preset.height) if preset else DEFAULT_RES)
    check_image_size(width, height, memory_bytes)
    if ns.out is not None and not ns.out.strip():
        raise UsageError("-out needs a file name, got an empty one")
    out = ns.out or (preset.output_name(ns.demo) if preset else DEFAULT_OUT)
    if Path(out).suffix.lower() not in OUTPUT_SUFFIXES:
        raise UsageError(f"-out {out!r}: the file name must end in .png, .npy or .pfm")
    opts = Options(
        objs=tuple(ns.obj), mtls=tuple(ns.mtl), camera=_camera(ns.cam),
        width=width, height=height,
        spp=ns.sr or (preset.spp if preset else DEFAULT_SPP),
        depth=ns.depth or (preset.depth if preset else DEFAULT_DEPTH),
        sky=_sky(ns.sky, ns.sky_color, preset.sky if preset else DEFAULT_SKY),
        out=out, threads=ns.threads, seed=ns.seed, tonemap=ns.tonemap,
        texture_filter=ns.texture_filter, quiet=ns.quiet, verbose=ns.verbose, demo=ns.demo,
    )
    from .animation import with_animation_options
    return with_animation_options(opts, ns, explicit_out=ns.out is not None)


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
    from .camera import Camera

    if values is None:
        return Camera()
    cam = Camera(position=tuple(values[0:3]), direction=tuple(values[3:6]),
                 fov=values[6], focus=values[7], aperture=values[8])
    from .validate import camera_problem

    # Our float32 bounds first: Camera.validate normalises the direction, which overflows at 1e308.
    problem = camera_problem(cam.position, cam.direction, cam.fov, cam.focus, cam.aperture)
    if problem:
        raise UsageError(f"argument -cam: {problem}")
    try:
        cam.validate()
    except ValueError as err:
        raise UsageError(f"argument -cam: {err}") from None
    return cam


def _sky(index: int | None, colour: list[float] | None, fallback: int) -> Sky:
    if colour is None:
        return Sky.from_index(fallback if index is None else index)
    from .validate import sky_colour_problem

    if sky_colour_problem(colour):
        raise UsageError(f"argument --sky-color: {sky_colour_problem(colour)}")
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
    """Fail early, before any loading or rendering, on unreadable inputs or an unwritable output place.

    Inputs must be regular files (a FIFO or a device is refused without being opened, so nothing
    blocks); the output must not be an existing non-regular file (a symlink is written through).
    """
    from .tokens import file_problem

    for flag, paths in (("-obj", objs), ("-mtl", mtls)):
        for path in paths:
            problem = file_problem(path)
            if problem is None and not os.access(path, os.R_OK):
                problem = "permission denied"
            if problem:
                raise RunError(f"cannot read {flag} file {path!r}: {problem}")
    target = Path(os.path.realpath(out)) if Path(out).is_symlink() else Path(out)
    parent = target.parent
    if not parent.is_dir():
        raise RunError(f"cannot write -out {out!r}: directory {str(parent)!r} does not exist")
    if not os.access(parent, os.W_OK):
        raise RunError(f"cannot write -out {out!r}: directory {str(parent)!r} is not writable")
    if target.exists() and file_problem(target):
        raise RunError(f"cannot write -out {out!r}: {file_problem(target)}")


def run(opts: Options, *, stderr: TextIO | None = None) -> int:
    """Load, render and save as ``opts`` says. Errors propagate; :func:`main` reports them."""
    err = stderr or sys.stderr
    if opts.animated or opts.cluster or opts.workers:
        from .animation import run_cli
        return run_cli(opts, err)
    objs, mtls = scene_files(opts)
    check_files(objs, mtls, opts.out)
    say = (lambda msg: None) if opts.quiet else (lambda msg: print(f"{PROG}: {one_line(msg)}", file=err))
    _init_warp(opts)
    import numpy as np

    from .film import save_image
    from .loader import load_scene
    from .renderer import render

    start = time.perf_counter()
    try:
        scene = load_scene(objs, mtls, warn=lambda message: None)   # collected in scene.warnings, shown below
    except MemoryError:
        raise RunError("out of memory while loading the scene: its files or textures are too large for "
                       "this machine's memory") from None
    for warning in scene.warnings:
        say(f"warning: {warning}")
    what = f"the built-in demo ({opts.demo or 'default'})" if opts.uses_demo_scene else f"{len(objs)} OBJ file(s)"
    say(f"loaded {what}: {scene.num_triangles:,} triangles, {len(scene.spheres)} spheres "
        f"in {time.perf_counter() - start:.1f} s; rendering {opts.width}x{opts.height}, "
        f"{opts.spp} spp, depth {opts.depth}")
    bar = None if opts.quiet else ProgressBar(opts.width * opts.height * opts.spp, file=err)
    start = time.perf_counter()
    try:
        image = render(scene, opts.camera, width=opts.width, height=opts.height, spp=opts.spp,
                       max_depth=opts.depth, sky=opts.sky, seed=opts.seed, threads=opts.threads,
                       texture_filter=opts.texture_filter, progress=bar or False)
    except MemoryError:
        texels = sum(int(np.prod(t.shape[:2])) for t in getattr(scene, "textures", []))
        raise RunError(f"out of memory while uploading and rendering the scene ({scene.num_triangles:,} triangles, "
                       f"{texels:,} texels) at {opts.width}x{opts.height}: try a smaller -res or fewer "
                       "--threads, or a smaller scene") from None
    finally:
        if bar is not None:
            with deferred_signals():    # never interrupt tqdm while it holds its lock
                bar.close()
    seconds = time.perf_counter() - start
    dropped = dropped_samples()
    if dropped:     # shown even with --quiet: the image is wrong somewhere (docs/limits.md)
        print(f"{PROG}: warning: {dropped} samples were not finite and were dropped; the image is biased "
              "there (please report this scene)", file=err)
    save_image(opts.out, image, tonemap=opts.tonemap)
    rate = opts.width * opts.height * opts.spp / max(seconds, 1e-9)
    say(f"wrote {opts.out} ({seconds:.1f} s, {rate / 1e6:.2f} M samples/s)")
    return EXIT_OK


def dropped_samples() -> int:
    """Non-finite samples the kernel's guard dropped in the last render (0 when unknown)."""
    stats = getattr(sys.modules.get("warp_spt.renderer"), "last_stats", None)
    return int(getattr(stats, "dropped_samples", 0) or 0)


def _init_warp(opts: Options) -> None:
    """Warp's banner, module-load lines and missing-CUDA-driver line only with ``--verbose``."""
    try:
        from .warp_runtime import init_warp
        init_warp(opts.verbose, quiet=opts.quiet)
    except ImportError:  # Warp missing: the renderer's import will report the real problem
        pass


def one_line(text: str) -> str:
    """``text`` with control characters and line separators escaped (\\n, \\x85, \\u2028...), so that
    a message stays one line whatever the file names and file contents it quotes hold."""
    return "".join(ch.encode("unicode_escape").decode("ascii") if unicodedata.category(ch) in ("Cc", "Zl", "Zp")
                   else ch for ch in text)


def _fail(message: str, status: int, stderr: TextIO) -> int:
    print(f"{PROG}: error: {one_line(message)}", file=stderr)
    return status


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``warp-spt`` and ``python -m warp_spt``; returns the exit status.

    ``argv`` None means "the program": SIGINT and SIGTERM handling is installed first and stays
    (a signal after the status is decided is ignored). With an explicit ``argv`` (tests, scripts)
    the caller's handlers are restored on return.
    """
    previous = install_cli_handlers()
    try:
        status = _main(sys.argv[1:] if argv is None else list(argv), sys.stderr)
        late = cli_interruption()
        if late is not None and status not in (EXIT_INTERRUPTED, EXIT_TERMINATED):
            # a signal whose exception some library swallowed just before the end: still report it
            status = _report(late, sys.stderr)
        return status
    finally:
        finish_cli_handlers(previous, program=argv is None)


def _main(argv: list[str], stderr: TextIO) -> int:
    try:
        opts = parse_args(argv)
        if opts.action == "help":
            print(build_parser().format_help(), end="")
            return EXIT_OK
        if opts.action == "version":
            print(f"{PROG} {__version__}")
            return EXIT_OK
        return run(opts, stderr=stderr)
    except BaseException as err:        # every failure ends as one line and an exit status
        return _report(err, stderr)


def _report(err: BaseException, stderr: TextIO) -> int:
    from .errors import SceneError

    signal_err = err if isinstance(err, KeyboardInterrupt) else cli_interruption()
    if signal_err is not None:          # Ctrl-C (SIGINT) or SIGTERM, wherever it arrived
        print(interruption_line(signal_err, PROG), file=stderr)
        return exit_status(signal_err)
    if isinstance(err, UsageError):
        return _fail(f"{err} (see {PROG} --help)", EXIT_USAGE, stderr)
    if isinstance(err, (RunError, SceneError)):
        return _fail(str(err), EXIT_FAILURE, stderr)
    if isinstance(err, MemoryError):
        return _fail("out of memory: try a smaller -res or fewer --threads", EXIT_FAILURE, stderr)
    if isinstance(err, OSError):
        where = f" {err.filename!r}" if err.filename else ""
        return _fail(f"{err.strerror or err}{where}", EXIT_FAILURE, stderr)
    if not isinstance(err, Exception) or os.environ.get("WARP_SPT_TRACEBACK"):
        raise err                       # SystemExit and the like; or a bug with its traceback asked for
    return _fail(f"internal error: {type(err).__name__}: {err} (set WARP_SPT_TRACEBACK=1 for details)",
                 EXIT_FAILURE, stderr)
