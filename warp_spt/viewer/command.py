"""The ``warp-spt`` command line that renders what the viewer shows, at a chosen size and spp.

The numbers follow the README: ``-cam px py pz dx dy dz fov focus aperture`` (position, view
*direction*, horizontal fov in degrees, focus distance, lens radius), Z up unless ``--up``. With
``-cam`` given the command line never frames the scene itself, so the command reproduces the view
exactly. Numbers are written with 9 significant digits: float32, which the renderer uses, needs
that many to round-trip.
"""

from __future__ import annotations

import shlex
from dataclasses import dataclass
from typing import Sequence

from warp_spt.scene.families import DEFAULT_SAMPLER

SKY_FLAGS = {"blue": ["-sky", "0"], "gradient": ["-sky", "1"], "pink": ["-sky", "2"]}


@dataclass(frozen=True)
class CommandSpec:
    """What the command renders besides the camera: scene files, size, samples and light transport.

    ``sky`` is a key of SKY_FLAGS, "studio" (the studio look's own sky: no flag) or None for a
    constant ``sky_color``; ``studio``: the view has the studio look (``--studio``).
    """

    objs: tuple[str, ...] = ()
    mtls: tuple[str, ...] = ()
    up: str = "z"
    width: int = 512
    height: int = 512
    spp: int = 64
    max_depth: int = 6
    sky: str | None = "blue"
    sky_color: tuple[float, float, float] = (0.0, 0.0, 0.0)
    integrator: str = "nee"
    sampler: str = DEFAULT_SAMPLER
    tonemap: str = "seed"
    out: str = "view.png"
    exposure: float = 0.0       # stops, for a tone-mapped output
    studio: bool = False
    studio_off: bool = False    # --no-studio was asked for
    smooth_angle: float | None = None   # --smooth-angle, when not the default
    env: tuple[str, float, float] | None = None   # sky "environment": --env FILE, --env-rotate, --env-strength
    env_background: tuple[float, float, float] | None = None   # --env-background R G B
    lighting: tuple[str, ...] = ()  # the page's lights and fog: --sun, --light, --fog flags (viewer.lighting)


def number(v: float) -> str:
    """A float as the shortest text with 9 significant digits (``-0`` written as ``0``)."""
    text = f"{float(v):.9g}"
    return "0" if text == "-0" else text


def cam_numbers(camera) -> list[str]:
    """``-cam``'s nine operands of a :class:`warp_spt.Camera`."""
    values = [*camera.position, *camera.direction, camera.fov, camera.focus, camera.aperture]
    return [number(v) for v in values]


def command_args(camera, spec: CommandSpec) -> list[str]:
    """The command line as a list of arguments, starting with ``warp-spt``."""
    args = ["warp-spt"]
    for obj in spec.objs:
        args += ["-obj", obj]
    for mtl in spec.mtls:
        args += ["-mtl", mtl]
    args += ["-cam", *cam_numbers(camera)]
    if spec.up != "z":
        args += [f"--up={spec.up}"] if spec.up.startswith("-") else ["--up", spec.up]
    args += ["-res", str(spec.width), str(spec.height), "-sr", str(spec.spp), "-depth", str(spec.max_depth)]
    args += ["--studio"] if spec.studio else ["--no-studio"] if spec.studio_off else []
    args += ["--smooth-angle", number(spec.smooth_angle)] if spec.smooth_angle is not None else []
    if spec.sky == "environment" and spec.env is not None:
        path, rotate, strength = spec.env
        args += ["--env", path] + (["--env-rotate", number(rotate)] if rotate else [])
        args += ["--env-strength", number(strength)] if strength != 1.0 else []
        args += ["--env-background", *map(number, spec.env_background)] if spec.env_background is not None else []
    elif spec.sky != "studio":
        args += SKY_FLAGS[spec.sky] if spec.sky in SKY_FLAGS else ["--sky-color", *map(number, spec.sky_color)]
    args += list(spec.lighting)
    args += ["--integrator", spec.integrator, "--sampler", spec.sampler]
    if spec.out.lower().endswith((".png", ".jpg", ".jpeg")):
        args += ["--tonemap", spec.tonemap]        # named: the command line's default depends on the scene
        args += ["--exposure", number(spec.exposure)] if spec.exposure else []
    return args + ["-out", spec.out]


def command_line(camera, spec: CommandSpec) -> str:
    """:func:`command_args` quoted for a POSIX shell."""
    return join(command_args(camera, spec))


def join(args: Sequence[str]) -> str:
    return " ".join(shlex.quote(a) for a in args)
