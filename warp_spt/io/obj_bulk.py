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
    nv = (lay.ntok - 1)[sel]
    vals = _values(buf, lay, sel, False) if sel.any() else np.zeros(0, np.float64)
    # finite in float32 too (the engine's type): anything else is left to the line reader's message
    if vals is None or len(vals) != nv.sum() or not (np.abs(vals) <= _FLOAT32_MAX).all():
        return None
    offset = np.cumsum(nv) - nv
    line = lay.line[sel] + 1
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
