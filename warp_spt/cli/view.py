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
from warp_spt.cli.options import UP_AXES, _camera, _join_up_operand, _smooth_angle
from warp_spt.runtime.extras import install_hint
from warp_spt.runtime.signals import exit_status
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
        camera = None
        if ns.cam is not None:
            from warp_spt.scene.camera import AXES

            camera = _camera(ns.cam).with_(up=AXES[ns.up or "z"])     # -cam: the seed's Z unless --up
    except UsageError as err:
        return fail(f"{err} (see {PROG} --help)", EXIT_USAGE, sys.stderr)
    missing = [m for m in ("aiohttp",) if importlib.util.find_spec(m) is None]
    if missing:
        return fail(f"the viewer needs {', '.join(missing)}: {install_hint('view')}", 1, sys.stderr)
    from warp_spt.viewer.server import serve
    width, height = ns.res or DEFAULT_VIEW
    try:
        status = serve(camera=camera, objs=ns.obj, mtls=ns.mtl, up=ns.up, port=ns.port or None, studio=ns.studio,
                       smooth_angle="auto" if ns.smooth_angle is None else ns.smooth_angle,
                       open_browser=not ns.no_browser, width=width, height=height)
    except KeyboardInterrupt as err:          # a signal before the server's loop took over
        status = exit_status(err)
    except OSError as err:
        if err.errno != errno.EADDRINUSE:
            raise
        return fail(f"port {ns.port} is in use (another viewer?): choose another --port, or leave --port out "
                    "for a free one", 1, sys.stderr)
    if status in (EXIT_INTERRUPTED, EXIT_TERMINATED):
        print(f"{PROG}: {'terminated' if status == EXIT_TERMINATED else 'interrupted'}", file=sys.stderr)
    return status
