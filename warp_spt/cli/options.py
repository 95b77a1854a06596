"""The ``warp-spt`` flags: argv -> a validated :class:`Options` (pure: no files, no numpy, no Warp).

Every flag group lives here (the seed's flags, your-own-model flags, budgets via
:mod:`warp_spt.cli.progressive`, animation and cluster flags), and :func:`settings_of` is the one
place where options become :class:`warp_spt.rendering.settings.RenderSettings`.
"""

from __future__ import annotations

import argparse
import difflib
import os
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from warp_spt.cli.budget_flags import BudgetOptions, add_flags, options, shared_output
from warp_spt.cli.light_flags import add_light_flags, light_options
from warp_spt.cli.common import PROG, Parser, UsageError, finite_float, int_at_least, integrator_options_of
from warp_spt.demo import PRESETS
from warp_spt.io.templates import frame_path, is_template, parse_frames
from warp_spt.scene.limits import MAX_DEPTH, MAX_ENV_ROTATE, MAX_FPS, MAX_RADIANCE, MAX_SPP, MAX_THREADS, MIN_FPS  # the API's caps (settings.check_args)
from warp_spt.runtime.extras import install_hint
from warp_spt.scene.sky import Sky

if TYPE_CHECKING:
    from warp_spt.scene.camera import Camera


# The seed's defaults (SEMANTICS §1); the output name follows its Readme, not its code (Q14).
DEFAULT_RES, DEFAULT_SPP, DEFAULT_DEPTH, DEFAULT_SKY, DEFAULT_OUT = (500, 500), 16, 6, 0, "output.png"


OUTPUT_SUFFIXES = (".png", ".jpg", ".jpeg", ".npy", ".pfm", ".exr")


UP_AXES = ("x", "y", "z", "-x", "-y", "-z")       # camera.AXES, spelled here so the CLI starts without numpy


# Film, accumulation and output buffers per pixel, with headroom for tiles and PNG encoding.
BYTES_PER_PIXEL = 64


MEMORY_FRACTION = 0.5


EXAMPLES = """\
commands:
  warp-spt view [scene flags]       explore a scene in the browser (pip install ".[view]" in the clone)
  warp-spt convergence [flags]      error against samples and seconds: CSV, JSON, PNG

examples:
  warp-spt                                   render the built-in demo to output.png
  warp-spt --demo 512p16s                    the seed's quick demo script (512x512, 16 spp)
  warp-spt -mtl scene.mtl -obj room.obj -obj balls.obj -sky 1 -res 512 512 -sr 32 -out room.png
  warp-spt -obj model.obj -cam 4 -55 16 0 1 0 38 27 0.001 --sky-color 0 0 0 -out model.pfm
  warp-spt -obj bunny.obj -sr 64 -out bunny.png        your model: Y up, framed, studio look
  warp-spt -obj bunny.obj --view left --exposure -0.5   from its left side, half a stop darker

-cam takes the order of the seed's design document: px py pz dx dy dz fov focus aperture
(the seed's Java code read fov aperture focus). d is a view direction, not a target; fov is the
horizontal angle in degrees. --look-at, --fov and --aperture override single fields of -cam.
-sky: 0 the seed's 'BlackSky' (a dull blue), 1 gradient, 2 pink. .png and .jpg are tone-mapped;
.npy, .pfm and .exr hold linear radiance (.exr needs the optional openexr package).
Exit status: 0 ok, 1 failure, 2 bad arguments, 130 interrupted (Ctrl-C, SIGINT), 143 terminated
(SIGTERM).

Up axis: --up wins (x y z -x -y -z). Otherwise the seed's scenes (the demo, OBJ spheres 'b', MTL
files with the seed's tags such as Roughness or Kl) and any command with -cam keep the seed's Z up;
any other model is Y up, as OBJ exporters write them (glTF always; a PLY file by its header or its
shape, or Z for a scan on a flat base). The "framed" line says what was assumed, and how sure.

Your own model (a standard OBJ, no -cam) is framed: the whole model in view, pinhole, a
three-quarter view from the front, or face-on for a flat cut-out; --view front|back|left|right|
top|bottom|AZ,EL (or --orbit AZ EL, degrees) chooses the side, --look-at the point looked at;
--fov zooms: the camera stands where the default 38-degree lens frames the model, and a narrower
--fov shows a detail, a wider one more around it. The printed -cam reproduces the view. A scene in the seed's dialect keeps the
seed's default camera unless it would stand inside the scene, see almost none of it or be too
close to see it whole; --frame always frames.

A model with no light of its own (no emitting material; an exporter's MTL has none) and no sky
flag gets the studio look: its own materials (grey clay for a bare model), a ground, a key light
placed from the camera (above, to the left, in front), a soft grey sky; the seed's scenes keep
their look. A light of yours (--sun, --light, --lights, a glTF file's lights, --env) is the key
instead: the ground stays, with a dimmer grey fill (or the map), and no key light of the studio's.
--no-studio or a sky flag turns it off; --studio turns it on for any model. --exposure EV brightens (or, negative,
darkens) the tone-mapped .png/.jpg by 2^EV; linear .npy/.pfm/.exr keep the scene's radiance.
"""


@dataclass(frozen=True)
class EnvOptions:
    """--env FILE, --env-rotate DEG, --env-strength X, --env-background R G B; ``plus``: the sky that
    -sky/--sky-color ask for beside the map (a second infinite light), or None."""

    path: str
    rotate: float = 0.0
    strength: float = 1.0
    background: tuple[float, float, float] | None = None
    plus: Sky | None = None


def _env_options(ns) -> EnvOptions | None:
    """The environment flags, checked: the others need --env; -sky/--sky-color with --env add that sky."""
    extra = [f for f, v in (("--env-rotate", ns.env_rotate), ("--env-strength", ns.env_strength),
                            ("--env-background", ns.env_background)) if v is not None]
    if ns.env is None:
        if extra:
            raise UsageError(f"{extra[0]} needs --env FILE")
        return None
    if not ns.env.strip():
        raise UsageError("--env needs a file name, got an empty one")
    check_env_values(ns)
    plus = None if ns.sky is None and ns.sky_color is None else _sky(ns.sky, ns.sky_color, DEFAULT_SKY)
    return EnvOptions(ns.env, ns.env_rotate or 0.0, 1.0 if ns.env_strength is None else ns.env_strength,
                      None if ns.env_background is None else tuple(ns.env_background), plus)


def check_env_values(ns) -> None:
    """--env-strength, --env-rotate and --env-background within the Sky's own bounds (UsageError): the
    render's flags and the viewer's alike, so that neither takes a value the other refuses."""
    if ns.env_strength is not None and not 0 <= ns.env_strength <= MAX_RADIANCE:
        raise UsageError(f"--env-strength must lie in [0, {MAX_RADIANCE:g}], got {ns.env_strength:g}")
    if ns.env_rotate is not None and not abs(ns.env_rotate) <= MAX_ENV_ROTATE:
        raise UsageError(f"--env-rotate must lie in [-{MAX_ENV_ROTATE:g}, {MAX_ENV_ROTATE:g}] degrees, "
                         f"got {ns.env_rotate:g}")
    if ns.env_background is not None and not all(0 <= c <= MAX_RADIANCE for c in ns.env_background):
        raise UsageError(f"--env-background colour values must lie in [0, {MAX_RADIANCE:g}], "
                         f"got {' '.join(f'{c:g}' for c in ns.env_background)}")


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
    sky: Sky | None = field(default_factory=Sky.black)   # None with --env: the scene's environment
    out: str = DEFAULT_OUT
    threads: int | None = None
    device: str = "cpu"
    seed: int = 0
    tonemap: str | None = None       # None: the first image's (cli/view_checks.first_image_defaults)
    texture_filter: str = "nearest"
    quiet: bool = False
    verbose: bool = False
    demo: str | None = None
    integrator: str | None = None     # None: the renderer's default
    sampler: str | None = None
    integrator_options: tuple[tuple[str, str], ...] = ()   # --integrator-option NAME=VALUE, as typed
    fog: object = None               # --fog: a warp_spt.scene.media.Medium filling the scene
    fog_scaled: bool = False         # --fog gave no sigma_a, sigma_s: the scene's default fog (scene_fog)
    volume: tuple | None = None      # --volume: (the .nvdb path, the Medium fields of its words)
    up: str | None = None            # --up; None: the rule of warp_spt.scene.conventions.up_axis
    cam_given: bool = False          # -cam or --look-at placed the camera: never frame automatically
    cam_explicit: bool = False       # -cam itself (the seed's Z-up convention)
    look_at: tuple[float, float, float] | None = None
    view: tuple[float, float] | None = None   # --view / --orbit: (azimuth, elevation) in degrees
    frame: bool = False              # --frame: always frame
    frame_all: bool = False          # --frame-all: frame a wide base (a ground) too
    studio: bool | None = None       # --studio / --no-studio; None: studio_look's rule
    sky_given: bool = False          # -sky, --sky-color or a --demo preset chose the sky
    exposure: float = 0.0            # --exposure, in stops, for tone-mapped outputs
    default_material: str = "auto"
    trust_paths: bool = False        # --trust-paths: scene files may name files outside their folder
    file_camera: str | None = None   # --camera: a camera of the model files (glTF), by name or index
    smooth_angle: float | str = "auto"   # --smooth-angle; "auto": 30 degrees unless the seed's dialect
    texture_modules: tuple[str, ...] = ()   # --textures: user modules registering procedural textures
    budget: BudgetOptions = field(default_factory=BudgetOptions)   # the budget flags (cli/budget_flags.py)
    env: EnvOptions | None = None    # --env and its flags: the scene's environment map (cli/view_checks.py)
    lights: tuple = ()               # --sun, --light, --lights (cli/light_flags.py): added to the scene
    # Distribution and animation (warp_spt.cluster, warp_spt.animation)
    cluster: str | None = None
    workers: int | None = None
    frames: range | None = None
    camera_path: str | None = None
    gif: str | None = None
    fps: float = 24.0                # --fps: frame k of an animated glTF is posed at k / fps seconds

    @property
    def animated(self) -> bool:
        """Frames, a camera path, a GIF or an OBJ template were given: render an animation."""
        return bool(self.frames or self.camera_path or self.gif or any(is_template(p) for p in self.objs))

    @property
    def uses_demo_scene(self) -> bool:
        """No ``-obj`` given (nor ``--volume`` without ``--demo``): the built-in demo scene is rendered."""
        return not self.objs and (self.volume is None or self.demo is not None)


_ADDRESS = re.compile(r"(?:tcp://)?(\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+):([0-9]{1,5})")


def cluster_address(text: str) -> str:
    """An argparse ``type``: a Dask scheduler's address, ``tcp://HOST:PORT`` (or ``HOST:PORT``).

    Other protocols need set-up this command does not do (tls:// certificates, ucx:// its package),
    and reached Dask as an internal error; an empty address was silently ignored."""
    m = _ADDRESS.fullmatch(text)
    if not m or not 0 < int(m.group(2)) < 65536:
        scheme = text.partition("://")[0] if "://" in text else ""
        why = (f"the {scheme}:// protocol is not supported (only tcp://)" if scheme and scheme != "tcp" else
               "expected tcp://HOST:PORT, e.g. tcp://scheduler:8786")
        raise argparse.ArgumentTypeError(f"{why}, got {text!r}")
    return text if text.startswith("tcp://") else f"tcp://{text}"


def device_name(text: str) -> str:
    """An argparse ``type``: cpu, cuda or cuda:N (whether it exists is asked of Warp later)."""
    from warp_spt.runtime.warp_init import DEVICE_SYNTAX      # stdlib only: parsing stays Warp-free

    if not DEVICE_SYNTAX.fullmatch(text):
        raise argparse.ArgumentTypeError(f"expected cpu, cuda or cuda:N, got {text!r}")
    return text


def integrator_option(text: str) -> tuple[str, str]:
    """An argparse ``type``: ``NAME=VALUE`` as (name, value text); the value is parsed and checked by
    the integrator's parameter once Warp has started (:func:`warp_spt.cli.common.integrator_options_of`)."""
    name, eq, value = text.partition("=")
    if not eq or not name.strip() or not value.strip():
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}")
    return name.strip(), value.strip()


def _unique_options(pairs: list[tuple[str, str]]) -> tuple[tuple[str, str], ...]:
    names = [n for n, _ in pairs]
    twice = sorted({n for n in names if names.count(n) > 1})
    if twice:
        raise UsageError(f"--integrator-option {twice[0]} given more than once")
    return tuple(pairs)


def _sky_index(text: str) -> int:
    # The seed mapped any unknown integer to BlackSky; a modern CLI reports the typo instead.
    if text not in ("0", "1", "2"):
        raise argparse.ArgumentTypeError(f"expected 0 (BlackSky), 1 (gradient) or 2 (pink), got {text!r}")
    return int(text)


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Help wrapped at spaces only, so that a hyphenated name (``--sampler sobol-affine``, a
    document's anchor) is never split across lines."""

    def _split_lines(self, text, width):
        import textwrap
        return textwrap.wrap(" ".join(text.split()), width, break_on_hyphens=False)


def build_parser() -> argparse.ArgumentParser:
    """The argument parser; single-dash multi-letter flags are the seed's, ``--`` flags are new.

    It stays Warp-free (usage errors and ``--help`` are instant): the integrators' and samplers'
    names are checked against their registries after Warp starts, and ``--help`` lists them after
    the flags (:func:`warp_spt.cli.common.registry_help`)."""
    # A short usage line: argparse's own lists every flag, 23 lines that filled the first screen.
    p = Parser(prog=PROG, add_help=False, allow_abbrev=False, epilog=EXAMPLES,
               usage=f"{PROG} [-obj PATH]... [-mtl PATH]... [-cam ...] [-res W H] [-sr N] [-out PATH] [options]",
                formatter_class=_HelpFormatter,
                description="A physically based path tracer on NVIDIA Warp. It reads the command lines\n"
                            "and the OBJ/MTL dialect of the seed, SimplePathTracer, and standard OBJ/MTL.")
    seed = p.add_argument_group("the seed's flags")
    seed.add_argument("-obj", action="append", default=[], metavar="PATH",
                      help="model file: OBJ, PLY, glTF or GLB (repeatable)")
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
    new.add_argument("--threads", type=int_at_least(1, MAX_THREADS), metavar="N",
                     help="worker threads (default: all cores)")
    new.add_argument("--device", type=device_name, default="cpu", metavar="cpu|cuda[:N]",
                     help="where kernels run (default cpu); cuda: one launch per pass, Warp's BVH")
    new.add_argument("--seed", type=int_at_least(0, 2**32 - 1), default=0, metavar="N",
                     help="random seed (default 0): the same seed gives the same image")
    new.add_argument("--sky-color", nargs=3, type=finite_float, metavar=("R", "G", "B"),
                     help="a constant sky instead of -sky; 0 0 0 for none")
    new.add_argument("--env", metavar="FILE",
                     help="an environment map lights the scene: an equirectangular (2:1) .hdr, .exr or .pfm "
                          "(an 8-bit .png with a warning); with -sky or --sky-color that sky lights it too")
    new.add_argument("--env-rotate", type=finite_float, metavar="DEG", help="turn the --env map about the up axis")
    new.add_argument("--env-strength", type=finite_float, metavar="X", help="scale the --env map's radiance (default 1)")
    new.add_argument("--env-background", nargs=3, type=finite_float, metavar=("R", "G", "B"),
                     help="camera rays that miss see this colour; the --env map still lights the scene")
    new.add_argument("--tonemap", choices=("seed", "srgb", "filmic"),
                     help="PNG mapping: the seed's curve, sRGB, or filmic (a highlight shoulder); default "
                          "filmic, the seed's curve for the seed's own scenes")
    new.add_argument("--filter", choices=("nearest", "bilinear"), default="nearest", dest="texture_filter",
                     help="texture lookup (default nearest, as the seed)")
    new.add_argument("--quiet", action="store_true", help="no progress bar or messages")
    new.add_argument("--verbose", action="store_true",
                     help="also show Warp's own messages (banner, module loads, missing CUDA driver)")
    # Names are checked against the registries in run(): importing them imports Warp, which must
    # first be initialised as --verbose says (and parsing stays Warp-free).
    new.add_argument("--integrator", metavar="NAME", help="light transport, by name (listed at the end)")
    new.add_argument("--sampler", metavar="NAME", help="random numbers, by name (listed at the end)")
    new.add_argument("--integrator-option", action="append", default=[], type=integrator_option,
                     metavar="NAME=VALUE", dest="integrator_option",
                     help="a parameter of the integrator, by name (repeatable; listed at the end)")
    new.add_argument("--fog", action="append", default=[], metavar="KEY=VALUE",
                     help="fill the scene with a homogeneous medium (repeatable): sigma_a=R[,G,B], "
                          "sigma_s=... per scene unit, g=G (-1..1), emission=..., majorant=M; without sigma_s "
                          "and sigma_a, an optical depth of about 0.6 across the scene; docs/volumes.md")
    new.add_argument("--volume", nargs="+", metavar=("FILE.nvdb", "KEY=VALUE"),
                     help="a density grid in the box of its own bounds, as that box's interior medium: "
                          "sigma_s=... (default 1), sigma_a=..., g=..., emission=..., majorant=..., per unit "
                          "density and scene unit; alone, or beside -obj; docs/volumes.md")
    new.add_argument("--textures", action="append", default=[], metavar="FILE.py",
                     help="Python module registering procedural textures (map_Kd proc:NAME; repeatable)")
    add_flags(p, int_at_least)
    add_light_flags(p, finite_float)
    _add_model_flags(p.add_argument_group("your own models"))
    more = p.add_argument_group("clusters and animation")
    more.add_argument("--cluster", type=cluster_address, metavar="ADDRESS",
                      help="render on a running Dask scheduler, e.g. tcp://host:8786")
    more.add_argument("--workers", type=int_at_least(1, 1024), metavar="N",
                      help="render on a local cluster of N worker processes")
    more.add_argument("--frames", metavar="A:B[:STEP]", help="render frames A..B-1; -obj may name "
                      "'wave_{frame:04d}.obj' and -out 'frame_{frame:04d}.png'")
    more.add_argument("--camera-path", metavar="FILE", help="JSON camera keyframes, interpolated per frame")
    more.add_argument("--gif", metavar="PATH", help="also write the frames as an animated GIF preview")
    more.add_argument("--fps", type=finite_float, default=24.0, metavar="N",
                      help="frames per second of a glTF's animation: frame k is posed at k / N seconds (default 24)")
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
        sky=None if ns.env is not None else _sky(ns.sky, ns.sky_color, preset.sky if preset else DEFAULT_SKY),
        env=_env_options(ns),
        out=out, threads=ns.threads, device=ns.device, seed=ns.seed, tonemap=ns.tonemap,
        texture_filter=ns.texture_filter, quiet=ns.quiet, verbose=ns.verbose, demo=ns.demo,
        integrator=ns.integrator, sampler=ns.sampler, texture_modules=tuple(ns.textures),
        integrator_options=_unique_options(ns.integrator_option), fog=_fog(ns.fog),
        fog_scaled=_fog_scaled(ns.fog), volume=_volume(ns.volume),
        up=ns.up, cam_given=ns.cam is not None or ns.look_at is not None, cam_explicit=ns.cam is not None,
        look_at=tuple(ns.look_at) if ns.look_at is not None else None, view=_view_angles(ns), frame=ns.frame,
        frame_all=ns.frame_all,
        studio=ns.studio, sky_given=(ns.sky is not None or ns.sky_color is not None or preset is not None
                                     or ns.env is not None),
        exposure=ns.exposure, default_material=ns.default_material, file_camera=ns.file_camera,
        trust_paths=ns.trust_paths,
        smooth_angle="auto" if ns.smooth_angle is None else ns.smooth_angle,
        budget=options(ns, UsageError, OUTPUT_SUFFIXES),
        lights=light_options(ns, UsageError),
    )
    opts = _check_exposure(with_animation_options(opts, ns, explicit_out=ns.out is not None))
    if opts.volume is not None and not opts.objs and opts.demo is None and opts.animated:
        raise UsageError("--volume alone renders one image: give -obj (the frames' models) for an animation")
    return opts


MAX_EXPOSURE = 20.0     # stops: 2^20 either way is far past any display; the viewer's range too
TONE_MAPPED = (".png", ".jpg", ".jpeg")


def _check_exposure(opts: Options) -> Options:
    """--exposure within +-MAX_EXPOSURE, and only where some output is tone mapped."""
    if not abs(opts.exposure) <= MAX_EXPOSURE:
        raise UsageError(f"--exposure must lie in [-{MAX_EXPOSURE:g}, {MAX_EXPOSURE:g}] stops, got {opts.exposure:g}")
    if opts.exposure and not opts.gif and Path(opts.out).suffix.lower() not in TONE_MAPPED:
        raise UsageError(f"--exposure changes tone-mapped .png/.jpg images; -out {opts.out!r} holds the scene's "
                         "linear radiance (scale it when you display it)")
    return opts


def _reject_unknown_flags(argv: Sequence[str], parser: argparse.ArgumentParser) -> None:
    """Only exact flags: argparse would take ``-ob`` for ``-obj`` even with allow_abbrev=False."""
    known = {name for action in parser._actions for name in action.option_strings}
    for token in argv:
        if token == "--":
            return
        name = token.split("=", 1)[0] if token.startswith("--") else token
        if token.startswith("-") and len(token) > 1 and name not in known and not _is_number(token):
            close = difflib.get_close_matches(name, sorted(known), n=1, cutoff=0.6)
            raise UsageError(f"unknown flag {token!r}" + (f"; did you mean {close[0]}?" if close else ""))


def _is_number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True


def _camera(values: list[float] | None) -> Camera:
    from warp_spt.scene.camera import Camera

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


def _add_model_flags(g) -> None:
    g.add_argument("--up", choices=UP_AXES, metavar="AXIS",
                   help="the world's up axis: x, y, z, -x, -y or -z (default: z for the seed's scenes and "
                        "with -cam, y for other models; see below)")
    g.add_argument("--view", type=view_angles, metavar="SIDE",
                   help="frame your model from front, back, left, right, top, bottom or AZ,EL (degrees)")
    g.add_argument("--orbit", nargs=2, type=finite_float, metavar=("AZ", "EL"),
                   help="frame your model from azimuth AZ (from the front towards the right) and "
                        "elevation EL, in degrees")
    g.add_argument("--look-at", nargs=3, type=finite_float, metavar=("TX", "TY", "TZ"),
                   help="aim the camera (-cam's or the default position) at this point and focus on it")
    g.add_argument("--camera", metavar="NAME|INDEX", dest="file_camera",
                   help="look through a camera of the model files (glTF), by name or by index in file order")
    g.add_argument("--fov", type=finite_float, metavar="DEG", help="horizontal field of view, overriding -cam's")
    g.add_argument("--aperture", type=finite_float, metavar="R", help="lens radius, overriding -cam's (0: pinhole)")
    g.add_argument("--frame", action="store_true",
                   help="frame the scene: three-quarter view from the front, all of it in view, pinhole")
    g.add_argument("--frame-all", action="store_true",
                   help="when framing, include a base much wider than what stands on it (a ground); "
                        "by default the objects on it are framed")
    g.add_argument("--studio", action=argparse.BooleanOptionalAction, default=None,
                   help="neutral sky, a ground plane under the model and a key light (adds geometry, "
                        "never edits your files); default: on for a model with no light of its own and no sky flag")
    g.add_argument("--exposure", type=finite_float, default=0.0, metavar="EV",
                   help="scale the tone-mapped image by 2^EV (default 0)")
    g.add_argument("--smooth-angle", type=_smooth_angle, default=None, metavar="DEG",
                   help="smooth normals by angle for OBJ files without vn: faces within DEG degrees of "
                        "each other shade smooth (0: off, flat); default 30, off for the seed's dialect")
    g.add_argument("--trust-paths", action="store_true",
                   help="let scene files name files outside their own folder (absolute paths, '..', links "
                        "out): for scenes you trust; by default a glTF, OBJ or MTL reads only below its folder "
                        "(an MTL's maps also below the working directory)")
    g.add_argument("--default-material", choices=("auto", "clay", "checker"), default="auto",
                   help="material of faces with no usemtl: clay (grey) or checker (the seed's); "
                        "auto (default): checker if any MTL is given or any OBJ names a material, else clay")


def _smooth_angle(text: str) -> float:
    from warp_spt.scene.normals import MAX_SMOOTH_ANGLE

    value = finite_float(text)
    if not 0.0 <= value <= MAX_SMOOTH_ANGLE:
        raise argparse.ArgumentTypeError(f"must lie in [0, {MAX_SMOOTH_ANGLE:g}] degrees (0: off), got {text}")
    return value


def _join_up_operand(argv: Sequence[str]) -> list[str]:
    """``--up -y`` as ``--up=-y`` and ``--view -30,10`` as ``--view=-30,10``: argparse would take
    an operand starting with a dash for a flag."""
    out: list[str] = []
    for token in argv:
        if out and ((out[-1] == "--up" and token in UP_AXES) or (out[-1] == "--view" and token.startswith("-"))):
            out[-1] = f"{out[-1]}={token}"
        else:
            out.append(token)
    return out


def view_angles(text: str) -> tuple[float, float]:
    """An argparse ``type`` for --view: a named side or ``AZ,EL`` in degrees."""
    from warp_spt.scene.camera import VIEWS

    if text.lower() in VIEWS:
        return VIEWS[text.lower()]
    parts = text.split(",")
    try:
        az, el = (finite_float(p) for p in parts) if len(parts) == 2 else (None, None)
    except argparse.ArgumentTypeError:
        az = el = None
    if az is None or not -90.0 <= el <= 90.0:
        raise argparse.ArgumentTypeError(f"expected {', '.join(VIEWS)} or AZ,EL in degrees "
                                         f"(EL in [-90, 90]), got {text!r}")
    return az, el


def _view_angles(ns: argparse.Namespace) -> tuple[float, float] | None:
    if ns.orbit is not None:
        return view_angles(",".join(str(v) for v in ns.orbit))
    return ns.view


def _check_model_flags(ns: argparse.Namespace) -> None:
    if ns.frame and (ns.cam is not None or ns.look_at is not None):
        raise UsageError("--frame places the camera itself; it cannot be combined with -cam or --look-at")
    if ns.view is not None and ns.orbit is not None:
        raise UsageError("give either --view or --orbit, not both")
    if (ns.view is not None or ns.orbit is not None) and ns.cam is not None:
        raise UsageError("--view and --orbit place the camera themselves; they cannot be combined with -cam")
    if ns.file_camera is not None and (ns.cam is not None or ns.look_at is not None or ns.frame
                                       or ns.view is not None or ns.orbit is not None):
        raise UsageError("--camera uses a camera of the model files; it cannot be combined with -cam, --look-at, "
                         "--frame, --view or --orbit")
    for flag, given in (("--frame", ns.frame), ("--studio", ns.studio), ("--view", ns.view is not None),
                        ("--orbit", ns.orbit is not None), ("--camera", ns.file_camera is not None)):
        if given and not ns.obj:
            raise UsageError(f"{flag} is for your own -obj files, not the built-in demo")


def _model_camera(ns: argparse.Namespace) -> Camera:
    """-cam (or the seed's default) with --up, --look-at, --fov and --aperture applied."""
    from warp_spt.scene.camera import AXES, Camera

    cam = _camera(ns.cam)
    up = ns.up or "z"       # the rule's axis is set once the scene is read (cli/view_checks.py)
    try:     # look_at and with_ validate the camera they return
        if ns.look_at is not None:
            cam = Camera.look_at(cam.position, ns.look_at, up=up, fov=cam.fov, aperture=cam.aperture)
        return cam.with_(up=AXES[up], fov=ns.fov, aperture=ns.aperture)
    except ValueError as err:
        raise UsageError(f"camera: {err}") from None


def _check_exr(out: str) -> None:
    import importlib.util

    if Path(out).suffix.lower() == ".exr" and importlib.util.find_spec("OpenEXR") is None:
        raise UsageError(f"-out {out!r}: writing .exr needs the optional openexr package "
                         f"({install_hint('exr')})")


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


def _fog(words: list[str]):
    """The --fog medium, or None (UsageError naming the bad word)."""
    if not words:
        return None
    from warp_spt.scene.media import parse_medium

    try:
        return parse_medium(words, "--fog")
    except ValueError as err:
        raise UsageError(str(err)) from None


def _volume(words: list[str] | None):
    """(path, Medium fields) of --volume FILE [KEY=VALUE ...], or None (UsageError naming the word)."""
    if not words:
        return None
    from warp_spt.scene.media import given_keys, parse_medium

    path, pairs = words[0], words[1:]
    if "=" in path or not path.lower().endswith(".nvdb"):
        raise UsageError(f"--volume: expected a .nvdb file first, then KEY=VALUE words, got {path!r}")
    try:
        medium = parse_medium(pairs, "--volume")
    except ValueError as err:
        raise UsageError(str(err)) from None
    return path, {k: getattr(medium, k) for k in sorted(given_keys(pairs))}


def _fog_scaled(words: list[str]) -> bool:
    """--fog was given without sigma_a or sigma_s: the scene's default fog (scene.media.scene_fog)."""
    from warp_spt.scene.media import SIGMA_KEYS, given_keys

    return bool(words) and not given_keys(words) & set(SIGMA_KEYS)


def settings_of(opts, **overrides):
    """The RenderSettings the command line asks for (the one place options become settings);
    ``overrides`` replace fields (the view's sky, a budget's spp)."""
    from warp_spt.rendering.settings import RenderSettings

    chosen = {k: v for k, v in (("integrator", opts.integrator), ("sampler", opts.sampler)) if v}
    if opts.integrator_options:
        chosen["integrator_options"] = integrator_options_of(opts)
    fields = dict(width=opts.width, height=opts.height, spp=opts.spp, max_depth=opts.depth, sky=opts.sky,
                  seed=opts.seed, texture_filter=opts.texture_filter, threads=opts.threads, device=opts.device,
                  **chosen)
    return RenderSettings(**{**fields, **overrides})


DEFAULT_FRAME_OUT = "frame_{frame:04d}.png"


def with_animation_options(opts, ns, *, explicit_out: bool):
    """Add the cluster and animation flags of the parsed namespace ``ns`` to ``opts``, validated.

    Without an explicit ``-out`` an animation writes ``frame_{frame:04d}.png``, or only the GIF when
    ``--gif`` is given (then ``opts.out`` is empty).
    """
    from warp_spt.cli.common import UsageError
    from warp_spt.cli.options import OUTPUT_SUFFIXES

    if ns.cluster and ns.workers:
        raise UsageError("give either --cluster or --workers, not both")
    if ns.camera_path and ns.cam:
        raise UsageError("give either -cam or --camera-path, not both")
    if ns.gif is not None and Path(ns.gif).suffix.lower() != ".gif":
        raise UsageError(f"--gif {ns.gif!r}: the file name must end in .gif")
    try:
        frames = parse_frames(ns.frames) if ns.frames is not None else None
    except ValueError as err:
        raise UsageError(f"argument --frames: {err}") from None
    if not MIN_FPS <= ns.fps <= MAX_FPS:
        raise UsageError(f"--fps must lie in [{MIN_FPS:g}, {MAX_FPS:g}], got {ns.fps:g}")
    opts = replace(opts, cluster=ns.cluster, workers=ns.workers, frames=frames, camera_path=ns.camera_path,
                   gif=ns.gif, fps=ns.fps)
    check_budget_flags(opts)
    if not opts.animated:
        return opts
    templates = [p for p in opts.objs if is_template(p)]
    if templates and frames is None and not opts.camera_path:
        raise UsageError(f"-obj {templates[0]!r} names one file per frame: give --frames A:B")
    out = opts.out if explicit_out else ("" if opts.gif else DEFAULT_FRAME_OUT)
    several = frames is None or len(frames) > 1
    if out and several and not is_template(out):
        raise UsageError(f"-out {out!r}: an animation writes one file per frame; "
                         "put {frame} in the name, e.g. frame_{frame:04d}.png")
    for name in templates + ([out] if out else []):
        try:
            frame_path(name, 0)
        except ValueError as err:
            raise UsageError(str(err)) from None
    if out and Path(frame_path(out, 0)).suffix.lower() not in OUTPUT_SUFFIXES:
        raise UsageError(f"-out {out!r}: the file name must end in .png, .npy or .pfm")
    return replace(opts, out=out)


BUDGET_FLAGS = (("adaptive", "--adaptive"), ("min_spp", "--min-spp"), ("save_partial", "--save-partial"),
                ("progressive", "--progressive"), ("error_map", "--error-map"), ("spp_map", "--spp-map"),
                ("denoise", "--denoise"))


def check_budget_flags(opts) -> None:
    """On a cluster only --time-budget and --target-error of the budget flags apply, and to one image."""
    from warp_spt.cli.common import UsageError

    b = opts.budget
    problem = shared_output(opts.out, b)
    if problem:
        raise UsageError(problem)
    if not (opts.cluster or opts.workers or opts.animated) or not b.active:
        return
    where = "an animation" if opts.animated else "a cluster"
    if opts.animated:
        raise UsageError(f"budget and error flags are not supported for {where}: render frames with -sr")
    for name, flag in BUDGET_FLAGS:
        if getattr(b, name):
            raise UsageError(f"{flag} is not supported on {where} (--time-budget and --target-error are)")
