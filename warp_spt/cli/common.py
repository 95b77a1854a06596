"""What the ``warp-spt`` commands share (the render CLI in :mod:`warp_spt.cli.main`, the convergence report in
:mod:`warp_spt.rendering.convergence`, the animation runner): the program name, exit statuses, the two error
types, an argparse parser that raises, strict number converters, the one-line error report, and Warp's
quiet start-up.

Only the standard library here: ``main()`` installs its signal handling before anything heavy is
imported, so that a Ctrl-C during start-up gets the same one-line message.
"""

from __future__ import annotations

import argparse
import os
import re
import time
import unicodedata
from dataclasses import replace
from pathlib import Path
from typing import Sequence, TextIO

from warp_spt.demo import demo_files
from warp_spt.scene.numbers import plain_float, plain_int

PROG = "warp-spt"
EXIT_OK, EXIT_FAILURE, EXIT_USAGE = 0, 1, 2
EXIT_INTERRUPTED, EXIT_TERMINATED = 130, 143     # 128 + the signal number (signals.exit_status)


class UsageError(Exception):
    """A bad command line: reported as one line, exit status 2."""


class RunError(Exception):
    """A failure after parsing (unreadable input, output directory missing): exit status 1."""


# argparse asks this pattern whether a word that starts with "-" is a number (no flag of ours looks
# like one): digits with an optional fraction and an optional exponent
NEGATIVE_NUMBER = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


class Parser(argparse.ArgumentParser):
    """argparse that raises :class:`UsageError` instead of printing the usage and exiting, and that
    reads a negative number in exponent form (``-1.2246467991473532e-16``, ``-1e1``) as a number:
    argparse's own pattern (``-1``, ``-.5``, ``-1.5``) took it for a flag, so the ``-cam`` the framing
    line prints for five of the six named views was refused."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = NEGATIVE_NUMBER

    def error(self, message: str):  # type: ignore[override]
        raise UsageError(message)


def int_at_least(low: int, high: int | None = None):
    """An argparse ``type``: a plain decimal integer in [low, high] (no upper bound when ``high`` is None)."""
    def convert(text: str) -> int:
        try:
            value = plain_int(text)
        except ValueError as err:
            raise argparse.ArgumentTypeError(str(err)) from None
        if value < low:
            raise argparse.ArgumentTypeError(f"must be at least {low}, got {value}")
        if high is not None and value > high:
            raise argparse.ArgumentTypeError(f"must be at most {high}, got {value}")
        return value
    convert.__name__ = "integer"
    return convert


def finite_float(text: str) -> float:
    """An argparse ``type``: a plain decimal number, finite (:func:`warp_spt.scene.numbers.plain_float`)."""
    try:
        return plain_float(text)
    except ValueError as err:
        raise argparse.ArgumentTypeError(str(err)) from None


def one_line(text: str) -> str:
    """``text`` with control characters and line separators escaped (\\n, \\x85, \\u2028...), so that
    a message stays one line whatever the file names and file contents it quotes hold."""
    return "".join(ch.encode("unicode_escape").decode("ascii") if unicodedata.category(ch) in ("Cc", "Zl", "Zp")
                   else ch for ch in text)


def fail(message: str, status: int, stderr: TextIO) -> int:
    """Print ``warp-spt: error: message`` as one line on ``stderr`` and return ``status``."""
    print(f"{PROG}: error: {one_line(message)}", file=stderr)
    return status


def init_warp(opts) -> None:
    """Warp's banner, module-load lines and missing-CUDA-driver line only with ``opts.verbose``; then
    the ``--device`` asked for must exist (a :class:`RunError`, one line, before the scene loads)."""
    try:
        from warp_spt.runtime.warp_init import check_device
        from warp_spt.runtime.warp_init import init_warp as init
        init(opts.verbose, quiet=opts.quiet)
    except ImportError:  # Warp missing: the renderer's import will report the real problem
        return
    try:
        check_device(getattr(opts, "device", "cpu"))
    except ValueError as err:
        raise RunError(str(err)) from None


COMPILE_MESSAGE = "compiling kernels for this scene... (first run only)"


class CompileNotice:
    """Says COMPILE_MESSAGE once if a step inside ``with notice:`` takes longer than ``after`` seconds.

    Loading a kernel from Warp's cache takes about 0.02 s, compiling it 5 s or more, so a slow kernel
    load means a cold cache; the line appears while the compiler runs, before the progress bar. The
    threshold is 2 s, not less: on a 2-core machine at load 9 a cached load took over 0.5 s.
    """

    def __init__(self, say, after: float = 2.0) -> None:
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


def warm_up(render_scene, scene, camera, settings) -> None:
    """Load (on a cold cache: compile) the exact kernel of ``render_scene(scene, camera, settings)`` by
    rendering one pixel with one sample through the same call."""
    render_scene(scene, camera, replace(settings, width=1, height=1, spp=1), progress=False)


def say_for(opts, err: TextIO):
    """The runners' one-line messages on ``err`` (nothing with --quiet)."""
    if opts.quiet:
        return lambda msg: None
    return lambda msg: print(f"{PROG}: {one_line(msg)}", file=err)


def load_texture_modules(opts, say) -> None:
    """Import the ``--textures`` files (they register procedural textures) before any scene is read."""
    if opts.texture_modules:
        from warp_spt.device.proctex import load_texture_module
        for module in opts.texture_modules:
            say(f"textures from {module}: {', '.join(load_texture_module(module)) or 'none registered'}")


def scene_files(opts) -> tuple[list[str], list[str]]:
    """The OBJ and MTL files to load: the user's, or the built-in demo's."""
    if opts.uses_demo_scene:
        try:
            return demo_files()
        except FileNotFoundError as err:
            raise RunError(str(err)) from None
    return list(opts.objs), list(opts.mtls)


def check_files(objs: Sequence[str], mtls: Sequence[str], out: str | None, out_flag: str = "-out",
                env: str | None = None, volume: str | None = None) -> None:
    """Fail early, before any loading or rendering, on unreadable inputs or an unwritable output place.

    Inputs (``env``: the --env map, ``volume``: the --volume grid, or None) must be regular files (a FIFO or a device is refused
    without being opened, so nothing blocks); the output (``out_flag``'s; None: none) must not be an
    existing non-regular file (a symlink is written through).
    """
    from warp_spt.io.tokens import file_problem

    for flag, paths in (("-obj", objs), ("-mtl", mtls), ("--env", () if env is None else (env,)),
                        ("--volume", () if volume is None else (volume,))):
        for path in paths:
            problem = file_problem(path)
            if problem is None and not os.access(path, os.R_OK):
                problem = "permission denied"
            if problem:
                raise RunError(f"cannot read {flag} file {path!r}: {problem}")
    if out is None:
        return
    target = Path(os.path.realpath(out)) if Path(out).is_symlink() else Path(out)
    parent = target.parent
    if not parent.is_dir():
        raise RunError(f"cannot write {out_flag} {out!r}: directory {str(parent)!r} does not exist")
    if not os.access(parent, os.W_OK):
        raise RunError(f"cannot write {out_flag} {out!r}: directory {str(parent)!r} is not writable")
    if target.exists() and file_problem(target):
        raise RunError(f"cannot write {out_flag} {out!r}: {file_problem(target)}")


def out_of_memory(err: BaseException) -> bool:
    """Whether ``err`` means memory ran out: Python's MemoryError, or Warp's failed allocation (a
    RuntimeError "Failed to allocate N bytes on device ...", which is no MemoryError)."""
    return isinstance(err, MemoryError) or (isinstance(err, RuntimeError)
                                            and str(err).startswith("Failed to allocate "))


def check_registry_names(opts) -> None:
    """--integrator and --sampler name entries of the registries, every --integrator-option is
    one of that integrator's parameters with a value it allows, and an integrator that trains over
    its own passes of the whole image (``Integrator.render_passes``: guided, ears) is given no flag
    that renders in batches or slices (budgets, error maps, --save-partial, --workers, --cluster);
    a usage error otherwise, before anything is loaded."""
    from warp_spt.integrators import DEFAULT_INTEGRATOR, INTEGRATORS
    from warp_spt.samplers import SAMPLERS

    for flag, name, registry in (("--integrator", opts.integrator, INTEGRATORS), ("--sampler", opts.sampler, SAMPLERS)):
        if name is not None and name not in registry:
            raise UsageError(f"argument {flag}: invalid choice: {name!r} (choose from {', '.join(sorted(registry))})")
    integrator_options_of(opts)
    name = opts.integrator or DEFAULT_INTEGRATOR
    if getattr(opts, "fog", None) is not None and opts.integrator is not None:   # before anything is loaded
        refuse_without_media(opts.integrator, "--fog")
    if INTEGRATORS[name].render_passes is not None:
        given = opts.budget.flags() + [flag for flag, value in (("--workers", opts.workers),
                                                                ("--cluster", opts.cluster)) if value]
        if given:
            raise UsageError(f"--integrator {name} trains over its own passes of the whole image: it cannot "
                             f"render with {', '.join(given)} (use -sr, or another --integrator)")


def refuse_without_media(integrator: str, what: str) -> None:
    """A :class:`UsageError` if ``integrator`` (a registered name, chosen by --integrator) ignores
    participating media, which ``what`` (--fog, or the scene's media) brings. Imports Warp."""
    from warp_spt.integrators import INTEGRATORS

    if not INTEGRATORS[integrator].media:
        media = ", ".join(sorted(n for n, r in INTEGRATORS.items() if r.media))
        raise UsageError(f"{what} brings participating media: --integrator {integrator} ignores them; leave "
                         f"--integrator out or choose {media}")


def integrator_options_of(opts) -> dict:
    """The ``--integrator-option`` values parsed by the chosen integrator's parameters (its
    ``Integrator.params``); a :class:`UsageError` names a bad one and what it allows. Imports Warp."""
    if not opts.integrator_options:
        return {}
    from warp_spt.integrators import DEFAULT_INTEGRATOR, INTEGRATORS

    rec = INTEGRATORS.get(opts.integrator or DEFAULT_INTEGRATOR)
    if rec is None:        # an unknown --integrator: check_registry_names reports it
        return {}
    try:
        return rec.parse_options(opts.integrator_options)
    except ValueError as err:
        raise UsageError(f"argument --integrator-option: {err}") from None


def registry_help() -> str:
    """The integrators, samplers and integrator parameters, listed from their registries under a
    heading of their own: ``--help`` prints it after the user's flags (it imports Warp, quietly, so
    the flags are printed and flushed first; the integrators' internal parameters, ``ears``' and
    ``guided``'s about twenty, would drown the user's flags in the middle)."""
    import textwrap

    from warp_spt.runtime.warp_init import init_warp as start_warp

    start_warp(False, quiet=True)
    from warp_spt.integrators import DEFAULT_INTEGRATOR, INTEGRATORS
    from warp_spt.samplers import DEFAULT_SAMPLER, SAMPLERS, get_sampler

    def entry(name: str, summary: str, default: str) -> str:
        return "\n".join(textwrap.wrap(f"{name:<14} {summary}{' (default)' if name == default else ''}", 98,
                                        initial_indent="  ", subsequent_indent=" " * 17, break_on_hyphens=False))

    lines = ["", "integrators (--integrator NAME) and samplers (--sampler NAME), from their registries:"]
    lines += [entry(n, r.summary, DEFAULT_INTEGRATOR) for n, r in sorted(INTEGRATORS.items())]
    lines += [entry(n, get_sampler(n).summary, DEFAULT_SAMPLER) for n in sorted(SAMPLERS)]
    lines += ["", "integrator parameters (--integrator-option NAME=VALUE; internal, for experiments):"]
    for n, r in sorted(INTEGRATORS.items()):
        if r.params:
            text = f"{n}: " + "; ".join(f"{q.name} ({q.allowed()}, default {q.default!r})" for q in r.params)
            lines += textwrap.wrap(text, 98, initial_indent="  ", subsequent_indent="    ", break_on_hyphens=False)
    return "\n".join(lines) + "\n"


def process_start() -> float:
    """When this process started, as a ``time.perf_counter()`` value (Linux: from /proc; elsewhere: now).

    Python's start-up and the import of Warp take a second or two before ``main()`` runs; the
    time budget targets the wall time the user sees, so it counts them too where it can.
    """
    now = time.perf_counter()
    try:
        ticks = os.sysconf("SC_CLK_TCK")
        with open("/proc/self/stat", "rb") as f:
            start_ticks = int(f.read().rsplit(b")", 1)[1].split()[19])
        with open("/proc/uptime", "rb") as f:
            uptime = float(f.read().split()[0])
        age = uptime - start_ticks / ticks
        return now - age if 0.0 <= age < 3600.0 else now
    except (OSError, ValueError, IndexError, AttributeError):
        return now
