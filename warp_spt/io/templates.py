"""Frame templates: file names with ``{frame}`` in them, one file per animation frame, and frame ranges.

A template is not a Python format string: only ``{frame}`` and ``{frame:0Nd}`` (zero-padded to N <= 12
digits) may stand in a name, so a name can neither allocate a huge field (``{frame:999999999d}``) nor
reach an attribute (``{frame.__class__}``). No numpy here: the command line checks templates while
it parses its flags.
"""

from __future__ import annotations

import re

from warp_spt.scene.numbers import plain_int

FRAME_FIELD = "{frame"
MAX_WIDTH = 12                   # digits of a zero-padded frame number
MAX_FRAME = 10**9                # frames are counted, rendered and named: a billion is beyond any use
_FIELD = re.compile(r"\{frame(?::0([0-9]{1,2})d)?\}")


def parse_frames(text: str) -> range:
    """``a:b[:step]`` -> range(a, b, step) (b excluded, as in Python); ``k`` alone is frame k only."""
    parts = text.split(":")
    try:
        nums = [plain_int(p, "an integer") for p in parts]
    except ValueError as err:
        raise ValueError(f"frames {text!r}: expected START:STOP[:STEP] or one frame number, all plain "
                         f"integers ({err})") from None
    if len(nums) == 1:
        nums = [nums[0], nums[0] + 1]
    if len(nums) not in (2, 3):
        raise ValueError(f"frames {text!r}: expected START:STOP[:STEP]")
    start, stop, step = nums[0], nums[1], nums[2] if len(nums) == 3 else 1
    if start < 0 or step < 1 or stop <= start:
        raise ValueError(f"frames {text!r}: need 0 <= START < STOP and STEP >= 1")
    if stop > MAX_FRAME + 1:
        raise ValueError(f"frames {text!r}: frame numbers must be at most {MAX_FRAME:,}")
    return range(start, stop, step)


def is_template(path: str) -> bool:
    """True for a path that names one file per frame, e.g. ``wave_{frame:04d}.obj``."""
    return FRAME_FIELD in str(path)


def check_template(template: str) -> None:
    """ValueError unless every brace of ``template`` belongs to a ``{frame}`` or ``{frame:0Nd}`` field."""
    rest = _FIELD.sub("", template)
    if "{" in rest or "}" in rest:
        raise ValueError(f"{template!r}: a file name may hold only {{frame}} or {{frame:0Nd}} "
                         f"(N <= {MAX_WIDTH}), e.g. frame_{{frame:04d}}.png")
    widths = [int(w) for w in _FIELD.findall(template) if w]
    if any(w > MAX_WIDTH for w in widths):
        raise ValueError(f"{template!r}: a frame number is padded to at most {MAX_WIDTH} digits")


def frame_path(template: str, frame: int) -> str:
    """The file name of ``frame``; a plain path is returned as is. ValueError for a bad template."""
    if not is_template(template):
        return str(template)
    check_template(str(template))
    return _FIELD.sub(lambda m: f"{frame:0{int(m.group(1))}d}" if m.group(1) else str(frame), str(template))
