"""``warp-spt view``: explore a scene in the browser (issue 23; the viewer is :mod:`warp_spt.viewer`).

The scene flags mean what they mean to ``warp-spt`` (-obj, -mtl, -cam, -res, --up, and the same
number syntax); the viewer adds --port and --no-browser. The page copies back the ``warp-spt``
command that renders the current view.
"""

from __future__ import annotations

import argparse
import errno
import importlib.util
import sys
from typing import Sequence

from warp_spt.cli.common import (
    EXIT_INTERRUPTED,
    EXIT_TERMINATED,
    EXIT_USAGE,
    Parser,
    UsageError,
    fail,
    finite_float,
    int_at_least,
)
from warp_spt.cli.light_flags import add_light_flags, light_options
from warp_spt.cli.options import UP_AXES, _camera, _fog, _join_up_operand, _smooth_angle, check_env_values
from warp_spt.runtime.extras import install_hint
from warp_spt.runtime.signals import exit_status
from warp_spt.scene.errors import SceneError
from warp_spt.scene.media import SIGMA_KEYS, given_keys
from warp_spt.scene.limits import MAX_VIEW_PIXELS

PROG = "warp-spt view"
DEFAULT_VIEW = (384, 288)


def build_parser() -> Parser:
    p = Parser(prog=PROG, allow_abbrev=False,
               description="Explore a scene in the browser: orbit, pan, zoom, refine, copy the warp-spt command "
                           "that renders the view. Needs the view extra: " + install_hint("view") + ".")
    p.add_argument("-obj", action="append", default=[], metavar="PATH", help="OBJ file (repeatable; default: the demo)")
    p.add_argument("-mtl", action="append", default=[], metavar="PATH", help="MTL file (repeatable)")
    p.add_argument("-cam", nargs=9, type=finite_float,
                   metavar=("PX", "PY", "PZ", "DX", "DY", "DZ", "FOV", "FOCUS", "APERTURE"),
                   help="start from this camera (as warp-spt -cam); default: the seed's for the demo, else framed")
    p.add_argument("-res", nargs=2, type=int_at_least(8, 4096), metavar=("W", "H"),
                   help=f"view size in pixels (default {DEFAULT_VIEW[0]} {DEFAULT_VIEW[1]})")
    p.add_argument("--up", choices=UP_AXES, metavar="AXIS",
                   help="the world's up axis (default: z for the seed's scenes and with -cam, y for other models)")
    p.add_argument("--studio", action=argparse.BooleanOptionalAction, default=None,
                   help="the studio look on or off (default: as warp-spt, on for a scene with no light of its own)")
    p.add_argument("--smooth-angle", type=_smooth_angle, default=None, metavar="DEG",
                   help="smooth normals by angle for OBJ files without vn, as warp-spt (default 30; 0: flat)")
    p.add_argument("--env", metavar="FILE", help="start with this environment map lighting the scene (as warp-spt)")
    p.add_argument("--env-rotate", type=finite_float, metavar="DEG", help="turn the --env map about the up axis")
    p.add_argument("--env-strength", type=finite_float, metavar="X", help="scale the --env map's radiance")
    p.add_argument("--env-background", nargs=3, type=finite_float, metavar=("R", "G", "B"),
                   help="camera rays that miss see this colour; the --env map still lights the scene")
    p.add_argument("--fog", action="append", default=[], metavar="KEY=VALUE",
                   help="start with a fog (as warp-spt: sigma_a, sigma_s, g; the page edits it)")
    add_light_flags(p, finite_float)
    p.add_argument("--port", type=int_at_least(0, 65535), default=0, help="port on 127.0.0.1 (default: a free one)")
    p.add_argument("--no-browser", action="store_true", help="only print the URL")
    return p


def main(argv: Sequence[str]) -> int:
    """Parse, then serve until Ctrl-C (status 130, one line) or SIGTERM (143)."""
    if any(a in ("-h", "--help") for a in argv):
        print(build_parser().format_help(), end="")
        return 0
    try:
        ns = build_parser().parse_args(_join_up_operand(argv))
        if ns.mtl and not ns.obj:
            raise UsageError("-mtl given without any -obj file to use it")
        if ns.res and ns.res[0] * ns.res[1] > MAX_VIEW_PIXELS:
            raise UsageError(f"argument -res: a view of {ns.res[0]}x{ns.res[1]} is more than the "
                             f"{MAX_VIEW_PIXELS:,} pixels a view may have (1920x1080 fits; docs/viewer.md)")
        lighting = lighting_settings(ns)
        camera = None
        if ns.cam is not None:
            from warp_spt.scene.camera import AXES

            camera = _camera(ns.cam).with_(up=AXES[ns.up or "z"])     # -cam: the seed's Z unless --up
    except UsageError as err:
        return fail(f"{err} (see {PROG} --help)", EXIT_USAGE, sys.stderr)
    except SceneError as err:       # a --lights file: its name and line
        return fail(str(err), 1, sys.stderr)
    missing = [m for m in ("aiohttp",) if importlib.util.find_spec(m) is None]
    if missing:
        return fail(f"the viewer needs {', '.join(missing)}: {install_hint('view')}", 1, sys.stderr)
    from warp_spt.viewer.server import serve
    width, height = ns.res or DEFAULT_VIEW
    try:
        status = serve(camera=camera, objs=ns.obj, mtls=ns.mtl, up=ns.up, port=ns.port or None, studio=ns.studio,
                       smooth_angle="auto" if ns.smooth_angle is None else ns.smooth_angle,
                       open_browser=not ns.no_browser, width=width, height=height, **lighting)
    except KeyboardInterrupt as err:          # a signal before the server's loop took over
        status = exit_status(err)
    except ValueError as err:       # a setting the session refused, an --env file it cannot read
        return fail(str(err), 1, sys.stderr)
    except OSError as err:
        if err.errno != errno.EADDRINUSE:
            raise
        return fail(f"port {ns.port} is in use (another viewer?): choose another --port, or leave --port out "
                    "for a free one", 1, sys.stderr)
    if status in (EXIT_INTERRUPTED, EXIT_TERMINATED):
        print(f"{PROG}: {'terminated' if status == EXIT_TERMINATED else 'interrupted'}", file=sys.stderr)
    return status


def lighting_settings(ns) -> dict:
    """The viewer's settings (``ViewSettings`` fields) for the light, fog and environment flags: the
    page's sun, its one lamp, its fog (UsageError for what the page cannot hold)."""
    out: dict = {}
    extra = [f for f, v in (("--env-rotate", ns.env_rotate), ("--env-strength", ns.env_strength),
                            ("--env-background", ns.env_background)) if v is not None]
    if ns.env is None and extra:
        raise UsageError(f"{extra[0]} needs --env FILE")
    check_env_values(ns)                # the render's bounds, which the page's own settings share
    if ns.env is not None:
        out.update(sky="environment", env_path=ns.env)
        out.update({k: v for k, v in (("env_rotate", ns.env_rotate), ("env_strength", ns.env_strength))
                    if v is not None})
        if ns.env_background is not None:
            out["env_background"] = tuple(ns.env_background)
    lights = light_options(ns, UsageError)
    suns = [x for x in lights if x.kind == 0]
    lamps = [x for x in lights if x.kind != 0]
    if len(suns) > 1 or len(lamps) > 1:
        raise UsageError("the viewer holds one sun and one point or spot light: give at most one of each "
                         "(render more with warp-spt)")
    for sun in suns:
        out.update(sun=True, sun_direction=sun.direction, sun_color=sun.color, sun_radius=sun.radius_deg)
    for lamp in lamps:
        out.update(lamp="spot" if lamp.kind == 2 else "point", lamp_position=lamp.position,
                   lamp_intensity=lamp.intensity)
        if lamp.kind == 2:
            if lamp.inner_deg:
                raise UsageError("the viewer's spot light has no inner cone (inner 0): leave 'inner' out")
            out.update(lamp_direction=lamp.direction, lamp_angle=lamp.outer_deg)
    fog = _fog(ns.fog)
    if fog is not None:
        if any(fog.emission) or fog.majorant != 1.0:
            raise UsageError("the viewer's fog takes sigma_a, sigma_s and g (render emission and majorant "
                             "with warp-spt)")
        out.update(fog=True, fog_g=fog.g)
        given = given_keys(ns.fog)      # the others are the scene's default fog, as warp-spt's
        out.update({f"fog_{k}": getattr(fog, k) for k in SIGMA_KEYS if k in given})
    return out
