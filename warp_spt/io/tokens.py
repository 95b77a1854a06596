"""Lexical rules shared by the OBJ and MTL readers: lines, tokens, numbers and names.

Both formats are read as bytes. A line ends at ``\\n``, ``\\r\\n`` or a lone ``\\r`` (classic Mac
OS files); tokens are separated by runs of ASCII whitespace (space, tab, CR, VT, FF).
A token that starts with ``#`` starts a comment that runs to the end of the line, so
``usemtl Mat#1`` keeps its name while ``v 1 2 3 # note`` loses the note. Names are decoded as
UTF-8, or as Latin-1 when they are not valid UTF-8 (older exporters), the same way in both
formats so that ``usemtl`` and ``newmtl`` names always match.
"""

from __future__ import annotations

import io
import math
import os
import re
import stat
from collections.abc import Iterator, Sequence

import numpy as np

from warp_spt.scene.numbers import FLOAT_PATTERN, INT_PATTERN, MAX_TOKEN_DIGITS
from warp_spt.scene.errors import SceneError

# Strict decimal syntax; Python's float() would also take "nan", "inf", "1_0" and "0x1p3".
_FLOAT_RE = re.compile(FLOAT_PATTERN.encode())
_INT_RE = re.compile(INT_PATTERN.encode())


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
    digits = len(tok.lstrip(b"+-"))
    if digits > MAX_TOKEN_DIGITS:   # int() would refuse past 4,300 digits with an error of its own
        raise SceneError(path, lineno, f"expected an integer {what}, got a number of {digits:,} digits")
    return int(tok)


# Bounds on what a scene file may hold before it is refused with a clear error (docs/limits.md).
MAX_FILE_BYTES = 2 << 30          # 2 GiB: an OBJ of about 20 million triangles
MAX_LINE_BYTES = 1 << 20          # 1 MiB: a polygon of ~100,000 corners; no real line needs more
HEAD_BYTES = 1 << 16              # read and checked first: binary data is refused before the rest is read

_KINDS = ((stat.S_ISDIR, "a directory"), (stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
          (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"))


def describe_special(mode: int) -> str | None:
    """What a non-regular file is ("a FIFO (named pipe)"...), or None for a regular file."""
    if stat.S_ISREG(mode):
        return None
    return next((name for test, name in _KINDS if test(mode)), "not a regular file")


def file_problem(path: str | os.PathLike[str]) -> str | None:
    """Why ``path`` cannot be read as a scene file ("no such file", "it is a FIFO"...), or None.

    Never raises and never opens the file (so a FIFO cannot block).
    """
    try:
        special = describe_special(os.stat(path).st_mode)
    except (OSError, ValueError) as err:
        return _reason(err)
    return f"it is {special}, not a regular file" if special else None


def is_regular_file(path: str | os.PathLike[str]) -> bool:
    """Like Path.is_file, but False (never an exception) for names too long, NUL bytes and the like."""
    return file_problem(path) is None


def read_file(path: str, kind: str, *, limit: int | None = None, binary: bool = False) -> bytes:
    """The whole file as bytes (read once), or a SceneError naming it: the one guarded opener of
    every input reader (OBJ, MTL, camera paths).

    Only regular files are read (symbolic links are followed): a FIFO, a device such as
    ``/dev/zero`` or a directory is refused before anything is read, so nothing can block or grow
    without end. An OBJ or MTL file in another scene format (PLY, glTF, FBX, STL...) is refused from
    its first bytes or its suffix (:func:`refuse_other_format`). A file larger than ``limit`` bytes
    (default MAX_FILE_BYTES) is refused from its size, before more than its first HEAD_BYTES are
    read; a file whose first bytes are binary (NUL bytes, a PNG, UTF-16) is refused after reading
    only those (:func:`normalise_text` names the line). Every reader is a text reader; the caller
    checks the whole text with normalise_text. ``binary=True`` (PLY, glTF) skips both checks of the
    first bytes.
    """
    limit = MAX_FILE_BYTES if limit is None else limit
    try:
        # O_NONBLOCK: opening a FIFO must not wait for a writer; regular files ignore the flag
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_BINARY", 0))
    except (OSError, ValueError) as err:     # ValueError: a NUL byte in the name
        raise SceneError(path, 0, f"cannot read {kind} file: {_reason(err)}") from None
    try:
        info = os.fstat(fd)
        special = describe_special(info.st_mode)       # before fdopen, which refuses a directory by fd number
        if special:
            raise SceneError(path, 0, f"cannot read {kind} file: it is {special}, not a regular file")
        with os.fdopen(fd, "rb") as f:
            fd = -1                                    # the file object owns it now
            head = f.read(HEAD_BYTES)
            if not binary:
                refuse_other_format(path, head, kind)  # a PLY, glTF, FBX... file: say so, not "binary data"
            if info.st_size > limit:
                raise SceneError(path, 0, f"{kind} file is larger than the {_size(limit)} limit")
            if not binary:
                normalise_text(head, path, kind)       # binary data is refused from its first bytes
            # what the file holds, and one byte more to see it grow: f.read(n) allocates n bytes up
            # front (a limit of 128 MiB was taken for a grid of 64 KB)
            data = head + f.read(max(min(limit, info.st_size) + 1 - len(head), 0))
            if len(data) > info.st_size:            # it grew since fstat: read on up to the limit
                data += f.read(max(limit + 1 - len(data), 0))
    except OSError as err:
        raise SceneError(path, 0, f"cannot read {kind} file: {_reason(err)}") from None
    finally:
        if fd >= 0:
            os.close(fd)
    if len(data) > limit:                              # it grew while we read it
        raise SceneError(path, 0, f"{kind} file is larger than the {_size(limit)} limit")
    return data


# Scene formats that are not OBJ, by the bytes they start with and by their suffix. Given as -obj (or
# to load_scene) they were read as OBJ text and failed with "binary data (a NUL byte)" or "the scene has
# no geometry", which did not say what to do.
OTHER_FORMATS_BY_HEAD = ((b"ply\n", "PLY"), (b"ply\r", "PLY"), (b"glTF", "glTF"), (b"Kaydara FBX Binary", "FBX"),
                         (b"; FBX", "FBX"), (b"solid ", "STL"), (b"BLENDER", "Blender (.blend)"),
                         (b"PXR-USDC", "USD"), (b"#usda", "USD"), (b"OFF\n", "OFF"), (b"OFF\r", "OFF"),
                         (b"PK\x03\x04", "ZIP (3MF, USDZ...)"))
OTHER_FORMATS_BY_SUFFIX = {".ply": "PLY", ".gltf": "glTF", ".glb": "glTF", ".fbx": "FBX", ".stl": "STL",
                           ".3ds": "3DS", ".dae": "COLLADA (.dae)", ".blend": "Blender (.blend)", ".usd": "USD",
                           ".usda": "USD", ".usdc": "USD", ".usdz": "USD", ".abc": "Alembic", ".x3d": "X3D",
                           ".wrl": "VRML", ".off": "OFF", ".3mf": "3MF", ".max": "3ds Max", ".c4d": "Cinema 4D",
                           ".lwo": "LightWave", ".step": "STEP", ".stp": "STEP", ".iges": "IGES", ".igs": "IGES"}


def other_format(path: str, head: bytes) -> str | None:
    """The scene format other than OBJ that a file is in ("PLY", "glTF"...), from its first bytes (a JSON
    object is glTF when it has an "asset", an XML document COLLADA or X3D by its root), else from its
    suffix; None for anything else (OBJ, MTL, or text that the readers will judge)."""
    start = head.lstrip(b" \t\r\n\xef\xbb\xbf")
    by_head = next((name for magic, name in OTHER_FORMATS_BY_HEAD if head.startswith(magic)), None)
    if by_head is None and start.startswith(b"{"):
        by_head = "glTF" if b'"asset"' in start else "JSON"
    elif by_head is None and start.startswith(b"<"):
        by_head = "COLLADA (.dae)" if b"<COLLADA" in start else "X3D" if b"<X3D" in start else "XML"
    return by_head or OTHER_FORMATS_BY_SUFFIX.get(os.path.splitext(str(path))[1].lower())


def refuse_other_format(path: str, head: bytes, kind: str) -> None:
    """For an OBJ or MTL file (``kind``; a camera path is JSON), a SceneError when ``head`` (its first
    bytes) or ``path``'s suffix says it is in another scene format: one line naming the format and,
    for OBJ, what to do."""
    name = other_format(path, head) if kind in ("OBJ", "MTL") else None
    if name is None:
        return
    if kind != "OBJ":
        raise SceneError(path, 0, f"not {kind} text: a {name} file")
    suffix_name = OTHER_FORMATS_BY_SUFFIX.get(os.path.splitext(str(path))[1].lower())
    found = "" if suffix_name == name else f"the file holds {name} data, not OBJ text: "
    raise SceneError(path, 0, f"{found}{name} files are not supported yet; convert to OBJ "
                              "(e.g. with Blender or MeshLab)")


def _size(n: int) -> str:
    return f"{n >> 30} GiB" if n >= 1 << 30 else f"{n >> 20} MiB"


def _reason(err: BaseException) -> str:
    text = getattr(err, "strerror", None) or str(err)
    return text[:1].lower() + text[1:]


def normalise_text(data: bytes, path: str, kind: str) -> bytes:
    """Check that ``data`` is OBJ/MTL text and give every line a ``\\n`` end.

    ``\\r\\n`` and a lone ``\\r`` become ``\\n`` (line numbers are those an editor shows). UTF-16
    text, NUL bytes (binary data, e.g. an image given as OBJ) and lines longer than MAX_LINE_BYTES
    are SceneErrors naming the file and line.
    """
    if data[:2] in (b"\xff\xfe", b"\xfe\xff"):
        raise SceneError(path, 1, f"UTF-16 text is not supported: save the {kind} file as UTF-8 or ASCII")
    if data.startswith(UTF8_BOM):       # editors on Windows write one; it is not part of the first statement
        data = data[len(UTF8_BOM):]
    if b"\r" in data:
        data = data.replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    if data.startswith(b"\x89PNG"):
        raise SceneError(path, 1, f"not {kind} text: a PNG image")
    nul = data.find(b"\x00")
    if nul >= 0:
        looks_utf16 = b"\x00" in (data[:1], data[1:2])      # UTF-16 without a byte-order mark
        utf16 = " (UTF-16 text is not supported: save it as UTF-8)" if looks_utf16 else ""
        raise SceneError(path, data.count(b"\n", 0, nul) + 1, f"not {kind} text: binary data (a NUL byte){utf16}")
    _check_line_lengths(data, path)
    _check_invisible(data, path, kind)
    return data


UTF8_BOM = b"\xef\xbb\xbf"
# Characters that print as nothing (or as a plain space) but are not white space to the tokenizer: a
# statement starting with one is an unknown tag and would be dropped silently.
INVISIBLE = {b"\xef\xbb\xbf": "a byte-order mark (U+FEFF)", b"\xe2\x80\x8b": "a zero-width space (U+200B)",
             b"\xe2\x80\x8c": "a zero-width non-joiner (U+200C)", b"\xe2\x80\x8d": "a zero-width joiner (U+200D)",
             b"\xe2\x80\x8e": "a left-to-right mark (U+200E)", b"\xe2\x80\x8f": "a right-to-left mark (U+200F)",
             b"\xe2\x81\xa0": "a word joiner (U+2060)", b"\xc2\xa0": "a no-break space (U+00A0)"}


def _check_invisible(data: bytes, path: str, kind: str) -> None:
    """A SceneError at the first invisible character (see INVISIBLE), naming it and its line."""
    if data.isascii():          # each of them has a byte >= 0x80: one fast pass instead of 8 searches
        return
    found = [(at, name) for junk, name in INVISIBLE.items() if (at := data.find(junk)) >= 0]
    if found:
        at, name = min(found)
        raise SceneError(path, data.count(b"\n", 0, at) + 1,
                         f"{name} in the {kind} text: an invisible character that would change the "
                         "statement; delete it (or save the file as plain UTF-8)")


def _check_line_lengths(data: bytes, path: str) -> None:
    if len(data) <= MAX_LINE_BYTES:
        return
    ends = np.flatnonzero(np.frombuffer(data, np.uint8) == 10)
    bounds = np.concatenate([[-1], ends, [len(data)]])
    lengths = np.diff(bounds) - 1
    k = int(np.argmax(lengths))
    if lengths[k] > MAX_LINE_BYTES:
        raise SceneError(path, k + 1, f"line of {int(lengths[k]):,} bytes is longer than the "
                                      f"{MAX_LINE_BYTES >> 20} MiB limit")
