"""Lexical rules shared by the OBJ and MTL readers: lines, tokens, numbers and names.

Both formats are read as bytes. A line ends at ``\\n`` (a trailing ``\\r`` is whitespace, so CRLF
files read the same); tokens are separated by runs of ASCII whitespace (space, tab, CR, VT, FF).
A token that starts with ``#`` starts a comment that runs to the end of the line, so
``usemtl Mat#1`` keeps its name while ``v 1 2 3 # note`` loses the note. Names are decoded as
UTF-8, or as Latin-1 when they are not valid UTF-8 (older exporters), the same way in both
formats so that ``usemtl`` and ``newmtl`` names always match.
"""

from __future__ import annotations

import io
import math
import re
from collections.abc import Iterator, Sequence

import numpy as np

from .errors import SceneError

# Strict decimal syntax; Python's float() would also take "nan", "inf", "1_0" and "0x1p3".
_FLOAT_RE = re.compile(rb"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_INT_RE = re.compile(rb"[+-]?\d+")


def iter_lines(data: bytes) -> Iterator[tuple[int, list[bytes]]]:
    """Yield (1-based line number, tokens without comment) for every line with tokens.

    Lines are produced one at a time (no list of all lines is built next to ``data``).
    """
    for lineno, line in enumerate(io.BytesIO(data), start=1):
        toks = strip_comment(line.split())
        if toks:
            yield lineno, toks


def strip_comment(toks: list[bytes]) -> list[bytes]:
    """Drop the first token that starts with ``#`` and everything after it."""
    for i, t in enumerate(toks):
        if t.startswith(b"#"):
            return toks[:i]
    return toks


def show(token: bytes) -> str:
    """A token as it should appear in an error message."""
    return repr(token.decode("utf-8", errors="replace"))


def decode_name(toks: Sequence[bytes]) -> str:
    """Join name tokens with single spaces and decode them (UTF-8, else Latin-1)."""
    raw = b" ".join(toks)
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError:
        return raw.decode("latin-1")


def parse_float(tok: bytes, path: str, lineno: int, tag: str) -> float:
    """One finite decimal number that is also finite in float32, or a SceneError."""
    if not _FLOAT_RE.fullmatch(tok):
        raise SceneError(path, lineno, f"expected a number after '{tag}', got {show(tok)}")
    value = float(tok)
    with np.errstate(over="ignore"):
        finite32 = bool(np.isfinite(np.float32(value)))
    if not math.isfinite(value) or not finite32:
        raise SceneError(path, lineno, f"expected a finite number after '{tag}', got {show(tok)}")
    return value


def parse_floats(toks: Sequence[bytes], counts: Sequence[int], path: str, lineno: int, tag: str) -> list[float]:
    """Parse the numbers after ``tag``; their count must be one of ``counts``."""
    if len(toks) not in counts:
        want = _phrase(counts)
        noun = "number" if counts == (1,) else "numbers"
        raise SceneError(path, lineno, f"expected {want} {noun} after '{tag}', got {len(toks)}")
    return [parse_float(t, path, lineno, tag) for t in toks]


def _phrase(counts: Sequence[int]) -> str:
    """(3,) -> "3", (1, 3) -> "1 or 3", (3, 4, 6) -> "3, 4 or 6", (1, 2, 3) -> "1 to 3"."""
    if len(counts) > 2 and list(counts) == list(range(counts[0], counts[-1] + 1)):
        return f"{counts[0]} to {counts[-1]}"
    head = ", ".join(str(c) for c in counts[:-1])
    return f"{head} or {counts[-1]}" if head else str(counts[-1])


def parse_int(tok: bytes, path: str, lineno: int, what: str) -> int:
    """One decimal integer (an OBJ index), or a SceneError."""
    if not _INT_RE.fullmatch(tok):
        raise SceneError(path, lineno, f"expected an integer {what}, got {show(tok)}")
    return int(tok)


def read_file(path: str, kind: str) -> bytes:
    """The whole file as bytes (read once), or a SceneError naming it."""
    try:
        with open(path, "rb") as f:
            return f.read()
    except OSError as err:
        raise SceneError(path, 0, f"cannot read {kind} file: {err.strerror or err}") from None
