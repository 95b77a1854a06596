"""The one syntax of numbers, in scene files and on the command line: plain ASCII decimals.

Python's ``int()`` and ``float()`` also take ``1_0``, ``inf``, ``nan``, Arabic-Indic and full-width
digits, and ``int()`` raises its own error past 4,300 digits: none of that is a number here. The
patterns are kept as text so the OBJ/MTL tokenizer (bytes) and the command line (str) compile the
same ones. It lives in ``scene/`` (no imports), below the device families (``device/`` and above), so that a procedural texture's
``key=value`` numbers (``scene.proctex_registry.parse_proc_map``) take the same syntax.
"""

from __future__ import annotations

import math
import re

INT_PATTERN = r"[+-]?[0-9]+"
FLOAT_PATTERN = r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
MAX_INT_DIGITS = 18          # every integer the command line takes fits in int64 with this many digits
MAX_TOKEN_DIGITS = 100       # scene files: far above any index (which is then "out of range"), far below
                             # Python's own limit of 4,300 digits
_INT = re.compile(INT_PATTERN)
_FLOAT = re.compile(FLOAT_PATTERN)


def plain_int(text: str, what: str = "an integer") -> int:
    """``text`` as a plain decimal integer of at most MAX_INT_DIGITS digits, or ValueError naming ``what``."""
    if not _INT.fullmatch(text):
        raise ValueError(f"expected {what}, got {text!r}")
    if len(text.lstrip("+-")) > MAX_INT_DIGITS:
        raise ValueError(f"expected {what}, got a number of {len(text.lstrip('+-')):,} digits")
    return int(text)


def plain_float(text: str, what: str = "a number") -> float:
    """``text`` as a plain, finite decimal number, or ValueError naming ``what``."""
    if not _FLOAT.fullmatch(text):
        raise ValueError(f"expected {what}, got {text!r}")
    value = float(text)
    if not math.isfinite(value):
        raise ValueError(f"expected a finite number, got {text!r}")
    return value
