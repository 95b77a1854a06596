"""The light flags: ``--sun``, ``--sun-color``, ``--sun-radius``, ``--light`` and ``--lights FILE``.

:mod:`warp_spt.cli.options` adds them to the parser (:func:`add_light_flags`) and reads them back
(:func:`light_options`): a tuple of ``warp_spt.scene.lights`` records that the runners add to the
scene's own lights. ``--light`` takes one line of a light file (``warp_spt.io.light_file``), so the
file and the flag have one syntax. Warp-free, and numpy-free until the flags are read: the command
line imports this module before its Ctrl-C handlers go in (tests/rendering/test_interrupt.py).
"""

from __future__ import annotations

import argparse
from typing import Callable



def add_light_flags(p: argparse.ArgumentParser, number: Callable) -> None:
    g = p.add_argument_group("lights (added to the scene's own; docs/lights.md)")
    g.add_argument("--sun", nargs=3, type=number, metavar=("DX", "DY", "DZ"),
                   help="a sun in this direction (towards it, in the scene's frame)")
    g.add_argument("--sun-color", nargs=3, type=number, metavar=("R", "G", "B"),
                   help="the sun's irradiance on a surface facing it (default 1 1 1)")
    g.add_argument("--sun-radius", type=number, metavar="DEG",
                   help="the sun's angular radius in degrees (default 0: sharp shadows; the real sun: 0.27)")
    g.add_argument("--light", nargs="+", action="append", default=[], metavar="WORD",
                   help="a light as a line of a light file, e.g. --light point position 0 2 0 intensity 50 "
                        "(repeatable)")
    g.add_argument("--lights", action="append", default=[], metavar="FILE",
                   help="a light file: one light a line (sun, point, spot; repeatable)")


def light_options(ns: argparse.Namespace, error: Callable[[str], Exception]) -> tuple:
    """The lights the flags give, in order (--sun, each --light, each file); ``error(message)`` is
    raised for a bad flag, ``SceneError`` for a bad light file."""
    from warp_spt.io.light_file import load_lights, parse_light     # numpy: after the handlers
    from warp_spt.scene.lights import SunLight

    lights = []
    if ns.sun is None and (ns.sun_color is not None or ns.sun_radius is not None):
        raise error("--sun-color and --sun-radius need --sun DX DY DZ (the direction towards the sun)")
    if ns.sun is not None:
        try:
            lights.append(SunLight(direction=tuple(ns.sun), color=tuple(ns.sun_color or (1.0, 1.0, 1.0)),
                                   radius_deg=0.0 if ns.sun_radius is None else ns.sun_radius))
        except ValueError as err:
            raise error(f"--sun: {str(err).replace(repr('sun') + ': ', '').replace('light ', '', 1)}") from None
    for k, words in enumerate(ns.light):
        try:
            lights.append(parse_light(list(words), default_name=f"light{k}"))     # a sun keeps "sun"
        except ValueError as err:
            raise error(f"--light {' '.join(words)}: {err}") from None
    for path in ns.lights:          # a bad file is a SceneError naming it and the line (exit status 1)
        lights.extend(load_lights(path))
    return tuple(lights)
