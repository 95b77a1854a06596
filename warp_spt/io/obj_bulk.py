"""The vectorised OBJ scanner: the bulk ``v``/``vt``/``vn``/``f`` lines of a file in a few numpy passes.

The file is one bytes buffer viewed as a uint8 array. Token boundaries come from a whitespace
lookup table; each line's first token is its tag. The numbers of all vertex lines are copied out
once (a byte mask) and converted by one ``np.fromstring`` call; face corners likewise, with their
``/`` structure checked per token by counting slashes. Other statements (``usemtl``, ``b``,
``mtllib``, names, comments) are rare and go through the line reader of :mod:`warp_spt.io.obj`.

The scanner never reports errors itself: it returns ``None`` on anything irregular (a bad count, a
stray character, a comment after data, a number that does not parse) and the caller re-reads the
file with the line reader, which is authoritative. So a valid file reads the same either way, and
an invalid one always gets the line reader's exact message.
"""

from __future__ import annotations

import warnings

import numpy as np

from warp_spt.io.obj_scan import V_COUNTS, VN_COUNTS, VT_COUNTS, LineReader, RawObj
from warp_spt.io.tokens import strip_comment
from warp_spt.scene.errors import SceneError

_SPACE, _NL, _HASH, _SLASH = 32, 10, 35, 47


# Byte sets for bytes.translate(None, delete=...), which returns the bytes NOT in the set: a fast
# check that a text holds only the characters its numbers may use (the line reader rejects "nan",
# "inf", hex floats, stray control characters... with a precise message).
_BLANKS = b" \t\r\n\x0b\x0c"
_FLOAT32_MAX = float(np.finfo(np.float32).max)   # NaN fails the comparison too
_FLOAT_CHARS = b"0123456789+-.eE" + _BLANKS
_INDEX_CHARS = b"0123456789+-/" + _BLANKS
# everything but the control characters that are not blanks: a file holding one goes to the line reader
_NOT_ODD_CONTROL = bytes(c for c in range(256) if c >= 32 or c in _BLANKS)
_DIGIT = np.zeros(256, dtype=bool)
_DIGIT[np.frombuffer(b"0123456789", np.uint8)] = True


class _Lines:
    """Token and line layout of a buffer: where each non-blank line's tokens start and end."""

    def __init__(self, buf: np.ndarray):
        n = len(buf)
        ws = buf <= _SPACE  # exact: the caller has ruled out other control characters
        bounds = np.flatnonzero(ws[1:] != ws[:-1]) + 1   # token starts and ends, alternating
        if not ws[0]:
            bounds = np.concatenate([[0], bounds])
        if not ws[-1]:
            bounds = np.concatenate([bounds, [n]])
        del ws
        self.start = bounds[0::2]   # first byte of each token
        self.end = bounds[1::2]     # one past its last byte
        self.newline = np.flatnonzero(buf == _NL)
        # first token at or after each line start; a line has tokens when that token starts
        # before the next line does (fewer queries than finding the line of every token)
        line_start = np.concatenate([[0], self.newline + 1])
        first_tok = np.searchsorted(self.start, line_start)
        nonblank = first_tok < np.append(first_tok[1:], len(self.start))
        self.tag_tok = first_tok[nonblank]
        self.line = np.flatnonzero(nonblank)    # 0-based line of each non-blank line
        self.ntok = np.diff(self.tag_tok, append=len(self.start))
        self.is_first = np.zeros(len(self.start), dtype=bool)
        self.is_first[self.tag_tok] = True
        ts = self.start[self.tag_tok]
        tlen = self.end[self.tag_tok] - ts
        b0, b1 = buf[ts], buf[np.minimum(ts + 1, n - 1)]
        self.is_v = (tlen == 1) & (b0 == ord("v"))
        self.is_f = (tlen == 1) & (b0 == ord("f"))
        self.is_vt = (tlen == 2) & (b0 == ord("v")) & (b1 == ord("t"))
        self.is_vn = (tlen == 2) & (b0 == ord("v")) & (b1 == ord("n"))
        self.n = n

    def line_end(self, lines: np.ndarray) -> np.ndarray:
        """One past the newline ending each 0-based line (the buffer's end for the last line)."""
        nl = self.newline
        if len(nl) == 0:
            return np.full(len(lines), self.n, dtype=np.int64)
        return np.where(lines < len(nl), nl[np.minimum(lines, len(nl) - 1)] + 1, self.n)

    def line_bytes(self, data: bytes, line: int) -> bytes:
        lo = int(self.newline[line - 1]) + 1 if line > 0 else 0
        hi = int(self.newline[line]) if line < len(self.newline) else self.n
        return data[lo:hi]


def scan_bulk(data: bytes, path: str) -> RawObj | None:
    """Scan ``data`` in bulk; ``None`` when anything needs the line reader's judgement."""
    buf = np.frombuffer(data, dtype=np.uint8)
    if len(buf) == 0:
        return LineReader(path).raw()
    if data.translate(None, _NOT_ODD_CONTROL):
        return None
    lay = _Lines(buf)
    bulk = lay.is_v | lay.is_vt | lay.is_vn | lay.is_f
    if not _counts_ok(lay) or (b"#" in data and _comment_in(buf, lay, bulk)):
        return None
    reader = LineReader(path)
    try:
        for k in np.flatnonzero(~bulk):
            toks = lay.line_bytes(data, int(lay.line[k])).split()
            if not toks[0].startswith(b"#"):
                reader.statement(int(lay.line[k]) + 1, strip_comment(toks))
    except SceneError:
        return None
    vertex = _vertex_lines(buf, lay)
    faces = _face_lines(buf, data, lay)
    if vertex is None or faces is None:
        return None
    raw = reader.raw()
    raw.positions, raw.v_line, raw.texcoords, raw.vt_line, raw.normals, raw.vn_line = vertex
    raw.corner_v, raw.corner_vt, raw.corner_vn, raw.poly_size, raw.poly_line = faces
    return raw


def _counts_ok(lay: _Lines) -> bool:
    """Every bulk line has a number count its tag allows."""
    nv = lay.ntok - 1
    return not (
        (lay.is_v & ~np.isin(nv, V_COUNTS)).any()
        or (lay.is_vt & ~np.isin(nv, VT_COUNTS)).any()
        or (lay.is_vn & ~np.isin(nv, VN_COUNTS)).any()
        or (lay.is_f & (nv < 3)).any()
    )


def _comment_in(buf: np.ndarray, lay: _Lines, bulk: np.ndarray) -> bool:
    """Whether some bulk line holds a ``#`` (a trailing comment: left to the line reader)."""
    hashes = np.flatnonzero(buf == _HASH)
    return bool(np.isin(lay.line[bulk], np.searchsorted(lay.newline, hashes)).any())


def _values(buf: np.ndarray, lay: _Lines, sel: np.ndarray, integers: bool) -> np.ndarray | None:
    """All numbers after the tag of the selected lines, in file order (None on any doubt).

    Integers (face corners, ``/`` read as a space) come back as int64, other numbers as float64
    (positions stay float64 until the upload; the line reader parses the same way).
    """
    first_val = lay.start[lay.tag_tok[sel] + 1]
    ends = lay.line_end(lay.line[sel])
    # alternating runs [gap, values, gap, values, ..., gap]; the values run keeps its newline
    bounds = np.empty(2 * len(first_val) + 2, dtype=np.int64)
    bounds[0], bounds[-1] = 0, lay.n
    bounds[1:-1:2], bounds[2:-1:2] = first_val, ends
    keep = np.zeros(len(bounds) - 1, dtype=bool)
    keep[1::2] = True
    text = buf[np.repeat(keep, np.diff(bounds))]
    return _numbers(text, integers)


def _numbers(text: np.ndarray, integers: bool) -> np.ndarray | None:
    """The numbers in the bytes ``text`` (modified in place), or None on any doubt."""
    raw = text.tobytes()
    if raw.translate(None, _INDEX_CHARS if integers else _FLOAT_CHARS):
        return None
    if integers:
        text[text == _SLASH] = _SPACE
        # numpy's integer reader takes a lone sign as 0 and skips blanks after a sign
        if b"-" in raw or b"+" in raw:
            signs = np.flatnonzero((text == ord("+")) | (text == ord("-")))
            if not _DIGIT[np.append(text, np.uint8(_SPACE))[signs + 1]].all():
                return None
    del raw
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error", DeprecationWarning)  # numpy < 2.3 only warned on bad text
            return np.fromstring(text, dtype=np.int64 if integers else np.float64, sep=" ")
    except (ValueError, DeprecationWarning):
        return None


def _vertex_lines(buf: np.ndarray, lay: _Lines):
    """(positions, v_line, texcoords, vt_line, normals, vn_line), or None."""
    sel = lay.is_v | lay.is_vt | lay.is_vn
    vals = _values(buf, lay, sel, False) if sel.any() else np.zeros(0, np.float64)
    return None if vals is None else _vertex_columns(vals, lay, sel)


def _vertex_columns(vals: np.ndarray, lay: _Lines, sel: np.ndarray):
    """The vertex lines' numbers ``vals`` (file order) split into their arrays, or None."""
    nv = (lay.ntok - 1)[sel]
    # finite in float32 too (the engine's type): anything else is left to the line reader's message
    if len(vals) != nv.sum() or not (np.abs(vals) <= _FLOAT32_MAX).all():
        return None
    line = lay.line[sel] + 1
    if lay.is_v[sel].all() and (nv == 3).all():     # the common file: positions only, 3 numbers each
        z = np.zeros(0, np.int64)
        return vals.reshape(-1, 3), line, np.zeros((0, 2), np.float32), z, np.zeros((0, 3), np.float32), z.copy()
    offset = np.cumsum(nv) - nv
    out = []
    for kind, width, dtype in ((lay.is_v[sel], 3, np.float64), (lay.is_vt[sel], 2, np.float32),
                               (lay.is_vn[sel], 3, np.float32)):
        o = offset[kind]
        cols = [vals[o + c] if c == 0 else np.where(nv[kind] > c, vals[np.minimum(o + c, len(vals) - 1)], 0.0)
                for c in range(width)]
        out += [np.stack(cols, axis=1).astype(dtype).reshape(-1, width), line[kind]]
    return tuple(out)


def _per_token(positions: np.ndarray, start: np.ndarray) -> np.ndarray:
    """How many of the sorted byte ``positions`` fall in each token (they all lie inside tokens)."""
    if len(positions) == 0:
        return np.zeros(len(start), np.int64)
    return np.bincount(np.searchsorted(start, positions, side="right") - 1, minlength=len(start))


def _face_lines(buf: np.ndarray, data: bytes, lay: _Lines):
    """(corner_v, corner_vt, corner_vn, poly_size, poly_line), or None."""
    sel = lay.is_f
    poly_size = (lay.ntok - 1)[sel]
    poly_line = lay.line[sel] + 1
    if not sel.any():
        z = np.zeros(0, dtype=np.int64)
        return z, z.copy(), z.copy(), poly_size, poly_line
    corner_tok = np.repeat(lay.is_f, lay.ntok) & ~lay.is_first
    cs, ce = lay.start[corner_tok], lay.end[corner_tok]
    nsl = nds = np.zeros(len(cs), np.int64)
    if b"/" in data:   # slashes and '//' starts are never blanks, so each lies in one token
        slash = np.flatnonzero(buf == _SLASH)
        nsl = _per_token(slash, lay.start)[corner_tok]
        if b"//" in data:
            nds = _per_token(slash[:-1][np.diff(slash) == 1], lay.start)[corner_tok]
    # valid corners: v, v/vt, v/vt/vn, v//vn, never starting or ending with '/'
    if (nsl > 2).any() or (buf[cs] == _SLASH).any() or (buf[ce - 1] == _SLASH).any():
        return None
    nvals = 1 + nsl - nds
    vals = _values(buf, lay, sel, True)
    # 0 is no index, and the reader saturates on overflow: let the line reader say so
    if vals is None or len(vals) != nvals.sum() or (vals == 0).any() or (np.abs(vals) >= 2**62).any():
        return None
    o = np.cumsum(nvals) - nvals
    cv = vals[o]
    cvt = np.where((nsl >= 1) & (nds == 0), vals[np.minimum(o + 1, len(vals) - 1)], 0)
    cvn = np.where(nsl == 2, vals[o + nvals - 1], 0)
    return cv, cvt, cvn, poly_size, poly_line


# ---------------------------------------------------------------- plain files: one pass per line, not per token
#
# Issue 45: on a 1M-triangle heightfield (`v x y z`, `f a b c`, 36 MB) scan_bulk's per-token layout
# (two int64 arrays of token starts and ends, 8M tokens, 130 MB, and the per-corner gathers) made
# the first read in a process 1.7 s, of which 1.1 s was first-touch page faults on those arrays (a
# second read in the same process: 0.67 s). Files without '/', '#' or '\' in them (what
# heightfield, scan and CAD exporters write: `f` with plain vertex indices) need only per-line facts:
# each line's tag and its count of tokens (one array of token starts, searched by line), no per-token
# ends, gathers or slash counts. Anything else goes to scan_bulk and then to the line reader, as before.

def scan_plain(data: bytes, path: str) -> RawObj | None:
    """Scan a file whose lines all start with their tag and whose faces hold plain vertex indices;
    ``None`` when the file is anything else (scan_bulk and the line reader then read it)."""
    if not data or b"/" in data or b"#" in data or b"\\" in data or data.translate(None, _NOT_ODD_CONTROL):
        return None
    buf = np.frombuffer(data, dtype=np.uint8)
    n = len(buf)
    ws = buf <= _SPACE
    if ws[0] and buf[0] != _NL:
        return None                               # a line that starts with a blank: scan_bulk's business
    tok_start = ~ws
    tok_start[1:] &= ws[:-1]                      # first byte of each token
    newline = np.flatnonzero(buf == _NL)
    line_start = np.concatenate([[0], newline + 1])
    if line_start[-1] == n:
        line_start = line_start[:-1]              # the text after the final newline is no line
    # tokens per line: where the line starts fall among the token starts (np.add.reduceat of the
    # mask per line took 0.81 s at 1M triangles, this 0.1 s)
    tok = np.flatnonzero(tok_start)
    del tok_start
    ntok = np.diff(np.searchsorted(tok, line_start), append=len(tok))
    del tok
    nonblank = ntok > 0
    # a line with tokens must start with one (tag at column 0; the rest as scan_bulk reads it)
    if (ws[line_start[nonblank]]).any():
        return None
    line = np.flatnonzero(nonblank)               # 0-based line number of every non-blank line
    start, ntok = line_start[nonblank], ntok[nonblank]
    del nonblank, line_start

    def at(offset: int) -> tuple[np.ndarray, np.ndarray]:   # the byte and whether it ends a token
        k = start + offset
        inside = k < n
        b = buf[np.minimum(k, n - 1)]
        return b, ~inside | ws[np.minimum(k, n - 1)]

    b0, _ = at(0)
    b1, end1 = at(1)
    _, end2 = at(2)
    is_v = (b0 == ord("v")) & end1
    is_f = (b0 == ord("f")) & end1
    is_vt = (b0 == ord("v")) & (b1 == ord("t")) & end2
    is_vn = (b0 == ord("v")) & (b1 == ord("n")) & end2
    del ws, b0, b1, end1, end2
    lay = _LineLayout(n, newline, line, ntok, is_v, is_vt, is_vn, is_f)
    if not _counts_ok(lay):
        return None
    bulk = is_v | is_vt | is_vn | is_f
    reader = LineReader(path)
    try:
        for k in np.flatnonzero(~bulk):
            toks = lay.line_bytes(data, int(line[k])).split()
            reader.statement(int(line[k]) + 1, toks)
    except SceneError:
        return None
    vsel = is_v | is_vt | is_vn
    vals = _line_values(buf, lay, start, vsel, is_vt | is_vn, False)
    if vals is None:
        return None
    vertex = _vertex_columns(vals, lay, vsel)
    if vertex is None:
        return None
    poly_size = (ntok - 1)[is_f]
    poly_line = line[is_f] + 1
    cv = _line_values(buf, lay, start, is_f, np.zeros(len(is_f), bool), True) if is_f.any() else np.zeros(0, np.int64)
    # 0 is no index, and the reader saturates on overflow: let the line reader say so
    if cv is None or len(cv) != poly_size.sum() or (cv == 0).any() or (np.abs(cv) >= 2**62).any():
        return None
    raw = reader.raw()
    raw.positions, raw.v_line, raw.texcoords, raw.vt_line, raw.normals, raw.vn_line = vertex
    zero = np.zeros(len(cv), np.int64)
    raw.corner_v, raw.corner_vt, raw.corner_vn, raw.poly_size, raw.poly_line = cv, zero, zero.copy(), poly_size, poly_line
    return raw


class _LineLayout(_Lines):
    """The per-line part of :class:`_Lines` (no per-token arrays), built by :func:`scan_plain`."""

    def __init__(self, n, newline, line, ntok, is_v, is_vt, is_vn, is_f):   # noqa: D107 - fields as _Lines
        self.n, self.newline, self.line, self.ntok = n, newline, line, ntok
        self.is_v, self.is_vt, self.is_vn, self.is_f = is_v, is_vt, is_vn, is_f


def _line_values(buf, lay, start, sel, two_byte_tag, integers: bool) -> np.ndarray | None:
    """The numbers of the selected lines in file order: their bytes copied out in one masked gather,
    the tag bytes blanked, then the same checks and ``np.fromstring`` as :func:`_values`."""
    lo = start[sel]
    hi = lay.line_end(lay.line[sel])
    keep = np.zeros(lay.n + 1, np.int8)          # +1 at each selected line's start, -1 past its end
    keep[lo] = 1                                  # (starts are distinct, and so are ends)
    keep[hi] -= 1
    mask = np.cumsum(keep[:-1], dtype=np.int8).view(bool)
    del keep
    text = buf[mask]
    del mask
    first = np.cumsum(hi - lo) - (hi - lo)       # each line's start inside text
    text[first] = _SPACE                          # the tag: 'v' or 'f'
    t2 = first[two_byte_tag[sel]]
    text[t2 + 1] = _SPACE                         # the 't' or 'n' of 'vt', 'vn'
    return _numbers(text, integers)
