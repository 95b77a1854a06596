"""Frame templates: file names with ``{frame}`` in them, one file per animation frame, and frame ranges.

No numpy here: the command line validates templates while it parses its flags.
"""

from __future__ import annotations

FRAME_FIELD = "{frame"


def parse_frames(text: str) -> range:
    """``a:b[:step]`` -> range(a, b, step) (b excluded, as in Python); ``k`` alone is frame k only."""
    parts = text.split(":")
    try:
        nums = [int(p) for p in parts]
    except ValueError:
        raise ValueError(f"frames {text!r}: expected START:STOP[:STEP] or one frame number, "
                         "all integers") from None
    if len(nums) == 1:
        nums = [nums[0], nums[0] + 1]
    if len(nums) not in (2, 3):
        raise ValueError(f"frames {text!r}: expected START:STOP[:STEP]")
    start, stop, step = nums[0], nums[1], nums[2] if len(nums) == 3 else 1
    if start < 0 or step < 1 or stop <= start:
        raise ValueError(f"frames {text!r}: need 0 <= START < STOP and STEP >= 1")
    return range(start, stop, step)


def is_template(path: str) -> bool:
    """True for an OBJ path that names one file per frame, e.g. ``wave_{frame:04d}.obj``."""
    return FRAME_FIELD in str(path)


def frame_path(template: str, frame: int) -> str:
    """The file name of ``frame`` (``template.format(frame=frame)``); a plain path is returned as is."""
    if not is_template(template):
        return str(template)
    try:
        return str(template).format(frame=frame)
    except (KeyError, IndexError, ValueError) as err:
        raise ValueError(f"cannot format {template!r} with frame={frame}: {err}") from None
