"""The ``warp-spt`` command line: the seed's flags unchanged, plus what a modern tool needs.

Two steps, so the first can be tested without rendering: :func:`parse_args` turns argv into a
validated :class:`Options` (pure: no files, no Warp), and :func:`run` loads, renders and saves.
:func:`main` ties them together and turns every failure into one ``warp-spt: error: ...`` line.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Sequence, TextIO

# Only light modules here (stdlib, no numpy, no Warp): main() installs the SIGINT/SIGTERM handling
# before anything heavy is imported, so a Ctrl-C during start-up gets the same one-line message.
from . import __version__
from .cli_common import (EXIT_FAILURE, EXIT_INTERRUPTED, EXIT_OK, EXIT_TERMINATED, EXIT_USAGE, PROG,  # noqa: F401
                         Parser, RunError, UsageError, fail, finite_float, init_warp, int_at_least, one_line)
from .cli_progressive import BudgetOptions, add_flags, check_outputs, options, process_start, render_and_save
from .demo import PRESETS, demo_files
from .progress import ProgressBar
from .signals import (cli_interruption, deferred_signals, exit_status, finish_cli_handlers, install_cli_handlers,
                      interruption_line)
from .sky import Sky

if TYPE_CHECKING:
    from .camera import Camera

OUTPUT_SUFFIXES = (".png", ".jpg", ".jpeg", ".npy", ".pfm", ".exr")
UP_AXES = ("x", "y", "z", "-x", "-y", "-z")       # camera.AXES, spelled here so the CLI starts without numpy

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
  warp-spt -obj bunny.obj --up y --studio -sr 64 -out bunny.exr    a Y-up model, framed, product shot

-cam takes the order of the seed's design document: px py pz dx dy dz fov focus aperture
(the seed's Java code read fov aperture focus). d is a view direction, not a target; fov is the
horizontal angle in degrees. --look-at, --fov and --aperture override single fields of -cam.
-sky: 0 the seed's 'BlackSky' (a dull blue), 1 gradient, 2 pink. .png and .jpg are tone-mapped;
.npy, .pfm and .exr hold linear radiance (.exr needs the optional openexr package).
Exit status: 0 ok, 1 failure, 2 bad arguments, 130 interrupted (Ctrl-C, SIGINT), 143 terminated
(SIGTERM).

Z is up, as in the seed. Most exported models are Y-up: add --up y (any of x y z -x -y -z) to
stand them upright; it sets the camera's up axis and the framing's.

With -obj and no -cam the scene is framed automatically (a three-quarter view from the front,
the whole model in view, pinhole) when the seed's default camera would stand inside the scene's
bounds, see almost none of it or be too close to see it whole, and whenever --up is not z;
--frame always frames. The seed's own scenes are seen whole by the default camera and keep it.
"""


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
    integrator: str | None = None     # None: the renderer's default
    sampler: str | None = None
    up: str = "z"
    cam_given: bool = False          # -cam or --look-at placed the camera: never frame automatically
    frame: bool = False              # --frame: always frame
    studio: bool = False
    default_material: str = "auto"
    texture_modules: tuple[str, ...] = ()   # --textures: user modules registering procedural textures
    budget: BudgetOptions = field(default_factory=BudgetOptions)   # cli_progressive's flags
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


def _sky_index(text: str) -> int:
    # The seed mapped any unknown integer to BlackSky; a modern CLI reports the typo instead.
    if text not in ("0", "1", "2"):
        raise argparse.ArgumentTypeError(f"expected 0 (BlackSky), 1 (gradient) or 2 (pink), got {text!r}")
    return int(text)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser; single-dash multi-letter flags are the seed's, ``--`` flags are new."""
    p = Parser(prog=PROG, add_help=False, allow_abbrev=False, epilog=EXAMPLES,
                formatter_class=argparse.RawDescriptionHelpFormatter,
                description="A physically based path tracer on NVIDIA Warp. It reads the command lines\n"
                            "and the OBJ/MTL dialect of the seed, SimplePathTracer, and standard OBJ/MTL.")
    seed = p.add_argument_group("the seed's flags")
    seed.add_argument("-obj", action="append", default=[], metavar="PATH", help="OBJ file (repeatable)")
    seed.add_argument("-mtl", action="append", default=[], metavar="PATH", help="MTL file (repeatable, any order)")
    seed.add_argument("-cam", nargs=9, type=finite_float,
                      metavar=("PX", "PY", "PZ", "DX", "DY", "DZ", "FOV", "FOCUS", "APERTURE"),
                      help="camera: position, view direction, horizontal fov (degrees), focus distance, "
                           "lens radius (default 4 -55 16 0 1 0 38 27 0.001)")
    seed.add_argument("-res", nargs=2, type=int_at_least(1), metavar=("W", "H"), help="image size (default 500 500)")
    seed.add_argument("-depth", type=int_at_least(1, MAX_DEPTH), metavar="N",
                      help="maximum surface hits per path (default 6)")
    seed.add_argument("-sr", type=int_at_least(1, MAX_SPP), metavar="N", help="samples per pixel (default 16)")
    seed.add_argument("-sky", type=_sky_index, metavar="0|1|2", help="0 BlackSky (default), 1 gradient, 2 pink")
    seed.add_argument("-out", metavar="PATH", help="output .png, .jpg, .npy, .pfm or .exr (default output.png)")
    new = p.add_argument_group("further options")
    new.add_argument("-h", "--help", action="store_true", help="show this help and exit")
    new.add_argument("--version", action="store_true", help="print the version and exit")
    new.add_argument("--demo", choices=sorted(PRESETS), metavar="PRESET",
                     help="render the built-in demo like the seed's script: " + ", ".join(PRESETS))
    new.add_argument("--threads", type=int_at_least(1), metavar="N", help="worker threads (default: all cores)")
    new.add_argument("--seed", type=int_at_least(0, 2**32 - 1), default=0, metavar="N",
                     help="random seed (default 0): the same seed gives the same image")
    new.add_argument("--sky-color", nargs=3, type=finite_float, metavar=("R", "G", "B"),
                     help="a constant sky instead of -sky; 0 0 0 for none")
    new.add_argument("--tonemap", choices=("seed", "srgb"), default="seed",
                     help="PNG mapping: the seed's curve (default) or sRGB")
    new.add_argument("--filter", choices=("nearest", "bilinear"), default="nearest", dest="texture_filter",
                     help="texture lookup (default nearest, as the seed)")
    new.add_argument("--quiet", action="store_true", help="no progress bar or messages")
    new.add_argument("--verbose", action="store_true",
                     help="also show Warp's own messages (banner, module loads, missing CUDA driver)")
    # Names are checked against the registries in run(): importing them imports Warp, which must
    # first be initialised as --verbose says (and parsing stays Warp-free).
    new.add_argument("--integrator", metavar="NAME",
                     help="light transport: nee (light sampling with MIS, default) or seed (pure path tracing)")
    new.add_argument("--sampler", metavar="NAME",
                     help="random numbers: sobol (Owen-scrambled Sobol', default) or independent (PCG streams)")
    new.add_argument("--textures", action="append", default=[], metavar="FILE.py",
                     help="Python module registering procedural textures (map_Kd proc:NAME; repeatable)")
    add_flags(p, int_at_least)
    _add_model_flags(p.add_argument_group("your own models"))
    more = p.add_argument_group("clusters and animation")
    more.add_argument("--cluster", metavar="ADDRESS", help="render on a running Dask scheduler, e.g. tcp://host:8786")
    more.add_argument("--workers", type=int_at_least(1, 1024), metavar="N",
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
    argv = _join_up_operand(argv)
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
    _check_model_flags(ns)
    preset = PRESETS.get(ns.demo) if ns.demo else None
    width, height = ns.res or ((preset.width, preset.height) if preset else DEFAULT_RES)
    check_image_size(width, height, memory_bytes)
    if ns.out is not None and not ns.out.strip():
        raise UsageError("-out needs a file name, got an empty one")
    out = ns.out or (preset.output_name(ns.demo) if preset else DEFAULT_OUT)
    if Path(out).suffix.lower() not in OUTPUT_SUFFIXES:
        raise UsageError(f"-out {out!r}: the file name must end in .png, .jpg, .npy, .pfm or .exr")
    _check_exr(out)
    opts = Options(
        objs=tuple(ns.obj), mtls=tuple(ns.mtl), camera=_model_camera(ns),
        width=width, height=height,
        spp=ns.sr or (preset.spp if preset else DEFAULT_SPP),
        depth=ns.depth or (preset.depth if preset else DEFAULT_DEPTH),
        sky=_sky(ns.sky, ns.sky_color, preset.sky if preset else DEFAULT_SKY),
        out=out, threads=ns.threads, seed=ns.seed, tonemap=ns.tonemap,
        texture_filter=ns.texture_filter, quiet=ns.quiet, verbose=ns.verbose, demo=ns.demo,
        integrator=ns.integrator, sampler=ns.sampler, texture_modules=tuple(ns.textures),
        up=ns.up, cam_given=ns.cam is not None or ns.look_at is not None, frame=ns.frame,
        studio=ns.studio, default_material=ns.default_material,
        budget=options(ns, UsageError, OUTPUT_SUFFIXES),
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
    try:
        cam.validate()           # the API's checks (float32 bounds included): one source of truth
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


# ---------------------------------------------------------------------------------------------
# Your own models: up axis, look-at, single-field overrides, framing, studio, default material


def _add_model_flags(g) -> None:
    g.add_argument("--up", choices=UP_AXES, default="z", metavar="AXIS",
                   help="the world's up axis: x, y, z (default, as the seed), -x, -y or -z; "
                        "most exported models need --up y")
    g.add_argument("--look-at", nargs=3, type=finite_float, metavar=("TX", "TY", "TZ"),
                   help="aim the camera (-cam's or the default position) at this point and focus on it")
    g.add_argument("--fov", type=finite_float, metavar="DEG", help="horizontal field of view, overriding -cam's")
    g.add_argument("--aperture", type=finite_float, metavar="R", help="lens radius, overriding -cam's (0: pinhole)")
    g.add_argument("--frame", action="store_true",
                   help="frame the scene: three-quarter view from the front, all of it in view, pinhole")
    g.add_argument("--studio", action="store_true",
                   help="neutral sky, a ground plane under the model and a key light (adds geometry, "
                        "never edits your files)")
    g.add_argument("--default-material", choices=("auto", "clay", "checker"), default="auto",
                   help="material of faces with no usemtl: clay (grey) or checker (the seed's); "
                        "auto (default): checker if any MTL is given or any OBJ names a material, else clay")


def _join_up_operand(argv: Sequence[str]) -> list[str]:
    """``--up -y`` as ``--up=-y``: argparse would take ``-y`` for a flag."""
    out: list[str] = []
    for token in argv:
        if out and out[-1] == "--up" and token in UP_AXES:
            out[-1] = f"--up={token}"
        else:
            out.append(token)
    return out


def _check_model_flags(ns: argparse.Namespace) -> None:
    if ns.frame and (ns.cam is not None or ns.look_at is not None):
        raise UsageError("--frame places the camera itself; it cannot be combined with -cam or --look-at")
    if (ns.frame or ns.studio) and not ns.obj:
        raise UsageError("--frame and --studio are for your own -obj files, not the built-in demo")


def _model_camera(ns: argparse.Namespace) -> Camera:
    """-cam (or the seed's default) with --up, --look-at, --fov and --aperture applied."""
    from .camera import AXES, Camera

    cam = _camera(ns.cam)
    try:     # look_at and with_ validate the camera they return
        if ns.look_at is not None:
            cam = Camera.look_at(cam.position, ns.look_at, up=ns.up, fov=cam.fov, aperture=cam.aperture)
        return cam.with_(up=AXES[ns.up], fov=ns.fov, aperture=ns.aperture)
    except ValueError as err:
        raise UsageError(f"camera: {err}") from None


def _check_exr(out: str) -> None:
    import importlib.util

    if Path(out).suffix.lower() == ".exr" and importlib.util.find_spec("OpenEXR") is None:
        raise UsageError(f"-out {out!r}: writing .exr needs the optional openexr package "
                         "(pip install 'warp-spt[exr]')")


def prepare_view(opts: Options, scene, say, notice: "CompileNotice | None" = None) -> tuple[object, Camera, Sky]:
    """The scene (uploaded to the device), camera and sky to render.

    The scene is recentred if far from the origin, framed when the rule says so (see
    :func:`warp_spt.framing.should_frame`), checked for views that show nothing, and given the studio
    preset if asked. The probe's kernel may compile on a first run: ``notice`` announces it.
    """
    from .device_scene import DeviceScene

    with notice or CompileNotice(say):
        scene, camera, sky = _view(opts, scene, say)
    return DeviceScene(scene), camera, sky


def _view(opts: Options, scene, say) -> tuple[object, Camera, Sky]:
    from . import framing
    from .camera import Camera

    scene, camera, offset = framing.recentre(scene, opts.camera)
    if offset.any():
        say(f"recentred the scene by {framing.format_point(-offset)} for precision (far from the origin)")
    if opts.uses_demo_scene and opts.quiet:
        return scene, camera, opts.sky
    pr = None
    if not opts.uses_demo_scene and not opts.cam_given:
        pr = framing.probe(scene, camera, framing.PROBE_SIZE, max(1, round(framing.PROBE_SIZE * opts.height / opts.width)))
        why = _why_frame(opts, scene, camera, pr.coverage)
        if why:
            camera = framing.frame_camera(scene, up=opts.up, aspect=opts.width / opts.height, template=camera).with_(
                aperture=0.0 if camera.aperture == Camera().aperture else camera.aperture)
            say(f"framed the scene ({why}): -cam {' '.join(f'{v:.6g}' for v in _cam_numbers(camera, offset))}")
            pr = None
    for warning in framing.view_warnings(scene, camera, opts.width, opts.height, pr, offset):
        say(f"warning: {warning}")
    sky = opts.sky
    if opts.studio:
        from .studio import add_studio, studio_sky
        scene = add_studio(scene, up=opts.up)
        sky = studio_sky() if opts.sky == Sky.black() else opts.sky
    return scene, camera, sky


def _why_frame(opts: Options, scene, camera: Camera, coverage: float) -> str:
    """Why the scene is framed automatically, or "" to keep the camera (see the help's rule)."""
    from .framing import should_frame

    if opts.frame:
        return "--frame"
    if opts.up != "z":
        return f"--up {opts.up}: the seed's default camera is a Z-up one"
    if should_frame(scene, camera, coverage):
        return "the default camera would not show it whole; -cam or --look-at to choose"
    return ""


COMPILE_MESSAGE = "compiling kernels for this scene... (first run only)"


class CompileNotice:
    """Says COMPILE_MESSAGE once if a step inside ``with notice:`` takes longer than ``after`` seconds.

    Loading a kernel from Warp's cache takes about 0.02 s, compiling it seconds, so a slow kernel load
    means a cold cache; the line appears while the compiler runs, before the progress bar.
    """

    def __init__(self, say, after: float = 0.5) -> None:
        self.say, self.after, self.said = say, after, False
        self._timer = None

    def _fire(self) -> None:
        if not self.said:
            self.said = True
            self.say(COMPILE_MESSAGE)

    def __enter__(self) -> "CompileNotice":
        import threading

        self._timer = threading.Timer(self.after, self._fire)
        self._timer.daemon = True
        self._timer.start()
        return self

    def __exit__(self, *exc) -> None:
        self._timer.cancel()


def warm_up(render, scene, camera, settings: dict) -> None:
    """Load (on a cold cache: compile) the exact kernel of ``render(scene, camera, **settings)`` by
    rendering one pixel with one sample through the same public call."""
    render(scene, camera, **{**settings, "width": 1, "height": 1, "spp": 1}, progress=False)


def _cam_numbers(cam: Camera, offset) -> list[float]:
    """A camera as -cam's nine numbers in world coordinates."""
    return [*(p + o for p, o in zip(cam.position, offset)), *cam.direction, cam.fov, cam.focus, cam.aperture]


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


def run(opts: Options, *, stderr: TextIO | None = None, started: float | None = None) -> int:
    """Load, render and save as ``opts`` says. Errors propagate; :func:`main` reports them.

    ``started`` (a perf_counter value, default now) is when the command started: --time-budget counts from it.
    """
    started = time.perf_counter() if started is None else started
    err = stderr or sys.stderr
    if opts.animated or opts.cluster or opts.workers:
        from .animation import run_cli
        return run_cli(opts, err, started)
    objs, mtls = scene_files(opts)
    check_files(objs, mtls, opts.out)
    check_outputs(opts.budget, RunError)
    say = (lambda msg: None) if opts.quiet else (lambda msg: print(f"{PROG}: {one_line(msg)}", file=err))
    init_warp(opts)
    _check_registry_names(opts)
    import numpy as np

    from .film import save_image
    from .loader import load_scene
    from .framing import describe_bounds
    from .renderer import RenderSettings, render, render_scene

    if opts.texture_modules:
        from .proctex import load_texture_module
        for module in opts.texture_modules:
            say(f"textures from {module}: {', '.join(load_texture_module(module)) or 'none registered'}")
    start = time.perf_counter()
    try:
        scene = load_scene(objs, mtls, warn=lambda message: None,   # collected in scene.warnings, shown below
                           default_material=opts.default_material)
    except MemoryError:
        raise RunError("out of memory while loading the scene: its files or textures are too large for "
                       "this machine's memory") from None
    for warning in scene.warnings:
        say(f"warning: {warning}")
    what = f"the built-in demo ({opts.demo or 'default'})" if opts.uses_demo_scene else f"{len(objs)} OBJ file(s)"
    say(f"loaded {what}: {scene.num_triangles:,} triangles, {len(scene.spheres)} spheres, "
        f"{describe_bounds(scene)} in {time.perf_counter() - start:.1f} s; rendering {opts.width}x{opts.height}, "
        f"{opts.spp} spp, depth {opts.depth}")
    notice = CompileNotice(say)
    scene, camera, sky = prepare_view(opts, scene, say, notice=notice)
    if opts.budget.active:      # passes, budgets and error estimates (cli_progressive)
        return render_and_save(replace(opts, camera=camera, sky=sky), scene, say=say, started=started)
    chosen = {k: v for k, v in (("integrator", opts.integrator), ("sampler", opts.sampler)) if v}
    settings = dict(width=opts.width, height=opts.height, spp=opts.spp, max_depth=opts.depth, sky=sky,
                    seed=opts.seed, threads=opts.threads, texture_filter=opts.texture_filter, **chosen)
    with notice:
        warm_up(render, scene, camera, settings)
    bar = None if opts.quiet else ProgressBar(opts.width * opts.height * opts.spp, file=err)
    start = time.perf_counter()
    try:
        result = render_scene(scene, camera, RenderSettings(**settings), progress=bar or False)
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
    image, dropped = result.image, result.stats.dropped_samples
    if dropped:     # shown even with --quiet: the image is wrong somewhere (docs/limits.md)
        print(f"{PROG}: warning: {dropped} samples were not finite and were dropped; the image is biased "
              "there (please report this scene)", file=err)
    save_image(opts.out, image, tonemap=opts.tonemap)
    rate = opts.width * opts.height * opts.spp / max(seconds, 1e-9)
    say(f"wrote {opts.out} ({seconds:.1f} s, {rate / 1e6:.2f} M samples/s)")
    return EXIT_OK


def _check_registry_names(opts: Options) -> None:
    """--integrator and --sampler name entries of the registries (a usage error otherwise)."""
    from .integrators import INTEGRATORS
    from .samplers import SAMPLERS

    for flag, name, registry in (("--integrator", opts.integrator, INTEGRATORS), ("--sampler", opts.sampler, SAMPLERS)):
        if name is not None and name not in registry:
            raise UsageError(f"argument {flag}: invalid choice: {name!r} (choose from {', '.join(sorted(registry))})")


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of ``warp-spt`` and ``python -m warp_spt``; returns the exit status.

    ``argv`` None means "the program": SIGINT and SIGTERM handling is installed first and stays
    (a signal after the status is decided is ignored). With an explicit ``argv`` (tests, scripts)
    the caller's handlers are restored on return. ``warp-spt convergence ...`` runs the convergence
    report (warp_spt.convergence).
    """
    # --time-budget covers start-up, load and compile; called from Python, it counts from this call
    started = process_start() if argv is None else time.perf_counter()
    previous = install_cli_handlers()
    try:
        status = _main(sys.argv[1:] if argv is None else list(argv), sys.stderr, started)
        late = cli_interruption()
        if late is not None and status not in (EXIT_INTERRUPTED, EXIT_TERMINATED):
            # a signal whose exception some library swallowed just before the end: still report it
            status = _report(late, sys.stderr)
        return status
    finally:
        finish_cli_handlers(previous, program=argv is None)


def _main(argv: list[str], stderr: TextIO, started: float) -> int:
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
    except BaseException as err:        # every failure ends as one line and an exit status
        return _report(err, stderr)


def _report(err: BaseException, stderr: TextIO) -> int:
    from .errors import SceneError

    signal_err = err if isinstance(err, KeyboardInterrupt) else cli_interruption()
    if signal_err is not None:          # Ctrl-C (SIGINT) or SIGTERM, wherever it arrived
        print(interruption_line(signal_err, PROG), file=stderr)
        return exit_status(signal_err)
    if isinstance(err, UsageError):
        return fail(f"{err} (see {PROG} --help)", EXIT_USAGE, stderr)
    if isinstance(err, (RunError, SceneError)):
        return fail(str(err), EXIT_FAILURE, stderr)
    if isinstance(err, MemoryError):
        return fail("out of memory: try a smaller -res or fewer --threads", EXIT_FAILURE, stderr)
    if isinstance(err, OSError):
        where = f" {err.filename!r}" if err.filename else ""
        return fail(f"{err.strerror or err}{where}", EXIT_FAILURE, stderr)
    if not isinstance(err, Exception) or os.environ.get("WARP_SPT_TRACEBACK"):
        raise err                       # SystemExit and the like; or a bug with its traceback asked for
    return fail(f"internal error: {type(err).__name__}: {err} (set WARP_SPT_TRACEBACK=1 for details)",
                 EXIT_FAILURE, stderr)
