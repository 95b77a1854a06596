"""Light files (``--lights FILE``) and ``--light`` specifications: one light a line.

::

    # a comment; blank lines are ignored
    sun   direction 0.4 -0.3 1   color 3 3 2.8   radius 0.27
    point position 0 2 0         intensity 50
    spot  position 0 3 0  direction 0 -1 0  intensity 200 180 160  inner 15  outer 30  name key

The first word is the kind (``sun``, ``point``, ``spot``); then ``keyword value...`` pairs in any
order: three numbers for ``position`` and ``direction``, one (grey) or three for ``color`` /
``intensity``, one number of degrees for ``radius``, ``inner`` and ``outer``, a word for ``name``.
Units as ``warp_spt.scene.lights``: a sun's ``color`` is its irradiance and ``direction`` points
towards it; a point or spot light's ``intensity`` is W/sr; a spot's ``direction`` is where it
shines. Unset keywords take the records' defaults (a white sun of radius 0 straight up, intensity
1, a spot's cone 0 to 45 degrees). Every error names the file and line.

Kinds and keywords are read from the kinds' declarations (``scene.lights.PUNCTUAL_KINDS``), each
keyword by its field's type (``scene.lights.parse_light``, beside them, as the procedural textures'
``key=value`` maps are read beside theirs): a kind registered there is read here with no edit.
"""

from __future__ import annotations

from warp_spt.io.tokens import normalise_text, read_file
from warp_spt.scene.errors import SceneError
from warp_spt.scene.lights import parse_light


def load_lights(path: str) -> list:
    """The lights of a light file (SceneError naming the file and line)."""
    text = normalise_text(read_file(path, "light"), path, "light").decode("utf-8", errors="replace")
    lights = []
    for lineno, line in enumerate(text.split("\n"), 1):
        words = line.split("#", 1)[0].split()
        if not words:
            continue
        try:
            lights.append(parse_light(words))
        except ValueError as err:
            raise SceneError(path, lineno, str(err)) from None
    return lights
