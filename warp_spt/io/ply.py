"""PLY (Stanford polygon file) reader: ascii, binary little and big endian, into an :class:`ObjData`.

What is read:

* ``vertex``: ``x y z`` (required), normals ``nx ny nz``, texture coordinates (``u v``, ``s t``,
  ``texture_u texture_v`` or ``texture_s texture_t``) and colours ``red green blue`` (or
  ``diffuse_red``...; integer types are scaled by their maximum, float types taken as written);
* ``face``: a list property ``vertex_indices`` (or ``vertex_index``) of any polygon with 3 or more
  corners, fan-triangulated as OBJ polygons are;
* ``tristrips``: a list property ``vertex_indices`` of strips, ``-1`` restarting a strip; triangle k
  of a strip is (i_k, i_k+1, i_k+2), with the first two swapped for odd k so that every triangle has
  the strip's winding. Triangles that repeat an index join strips and are dropped silently;
* any other element, and any other property, is skipped by its declared size;
* ``comment`` and ``obj_info`` lines: what they say about the up axis (:func:`up_hint`, into
  ``ObjData.up_hint``; PLY has no convention of its own, scene/conventions.py).

Vertex colours become a baked texture (:func:`vertex_colour_texture`): each triangle owns a 2x2 texel
block whose three used texels hold its corners' colours at their centres, so bilinear filtering
(``--filter bilinear``) interpolates the colours across the triangle exactly; the nearest filter
paints each third of the triangle with its nearest corner's colour. The material that holds it is
the file's own (the default material otherwise).

Every count, list length and index is checked against the bytes and the element sizes before
anything is allocated or read, so a forged header cannot make the reader read past the data or
allocate more than the file could hold. Errors are :class:`SceneError` naming the file, the header
or data line (ascii; 0 for binary data, whose message names the element row and byte offset) and
what was expected.
"""

from __future__ import annotations

import os
import re
import struct
from dataclasses import dataclass, field

import numpy as np

from warp_spt.io.tokens import read_file
from warp_spt.scene.atlas_layout import TEXEL_BUDGET
from warp_spt.scene.errors import SceneError
from warp_spt.scene.model import CHECKER_NAME, Material, ObjData, TextureRef, column_range
from warp_spt.scene.validate import MAX_COORDINATE, nonzero_area

__all__ = ["load_ply", "parse_ply_bytes", "vertex_colour_texture", "VERTEX_COLOUR_MATERIAL"]

# Type names of the PLY specification and their common aliases, as numpy scalar kinds (no byte order)
_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
          "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
          "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
_FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
MAX_HEADER_BYTES = 1 << 20      # a header is a few hundred bytes; this bounds the search for its end
MAX_HEADER_LINES = 10_000
MAX_LIST_LENGTH = 1 << 20       # corners of one polygon or indices of one strip row (beyond: a forged count)
VERTEX_COLOUR_MATERIAL = "vertex colours"   # the material's name after the file's: "scan.ply: vertex colours"
_UV_NAMES = (("u", "v"), ("s", "t"), ("texture_u", "texture_v"), ("texture_s", "texture_t"))
_COLOUR_NAMES = (("red", "green", "blue"), ("diffuse_red", "diffuse_green", "diffuse_blue"),
                 ("r", "g", "b"))


@dataclass
class _Property:
    name: str
    kind: str                     # numpy kind without byte order ("f4")
    count_kind: str | None = None  # for a list property, the kind of its length
    line: int = 0


@dataclass
class _Element:
    name: str
    count: int
    line: int
    properties: list[_Property] = field(default_factory=list)

    @property
    def fixed(self) -> bool:
        return all(p.count_kind is None for p in self.properties)


def load_ply(path: str | os.PathLike[str]) -> ObjData:
    """Read one PLY file into validated arrays (one object of the scene); see the module docs."""
    path = str(path)
    return parse_ply_bytes(read_file(path, "PLY", binary=True), path)


def parse_ply_bytes(data: bytes, path: str = "<input>") -> ObjData:
    """Parse a PLY file given as bytes; ``path`` names it in errors."""
    fmt, elements, body_start, header_lines = _header(data, path)
    if fmt is None:
        values = _read_ascii(data, body_start, header_lines, elements, path)
    else:
        values = _read_binary(data, body_start, fmt, elements, path)
    obj = _assemble(values, elements, path)
    obj.format, obj.up_hint = "PLY", up_hint(data[:body_start])
    return obj


# What a PLY header's comments may say about the up axis (PLY itself has no convention): an axis
# named with the word "up" ("comment up z", "comment up_axis: Z", "comment Z-up"), else the writer:
# Blender's exporters write Z up (their default axes: -Y forward, Z up); the Stanford scanning
# repository's zippered scans ("zipper output") are Y up. Other writers (MeshLab's "VCGLIB
# generated", scanners) say nothing about it.
_UP_WORDS = (re.compile(rb"\bup(?:[ _-]?axis)?\s*[:=]?\s*\+?([xyz])\b", re.I),
             re.compile(rb"\b\+?([xyz])[ _-]up\b", re.I))
_WRITERS = ((re.compile(rb"\bblender\b", re.I), "z", "written by Blender, which exports Z up"),
            (re.compile(rb"\bzipper\b", re.I), "y", "a Stanford zippered scan, which are Y up"))


def up_hint(header: bytes) -> tuple[str, str] | None:
    """(axis, what says so) from a PLY header's ``comment``/``obj_info`` lines, or None when they
    say nothing about the up axis (see _UP_WORDS, _WRITERS)."""
    lines = header.replace(b"\r", b"\n").split(b"\n")
    comments = [(raw.split(None, 1) + [b""])[1] for raw in lines if raw.split()[:1] in ([b"comment"], [b"obj_info"])]
    for text in comments:
        for pattern in _UP_WORDS:
            m = pattern.search(text)
            if m:
                return m.group(1).decode().lower(), f"its header says {text.decode('latin-1').strip()[:60]!r}"
    for pattern, axis, why in _WRITERS:
        if any(pattern.search(text) for text in comments):
            return axis, why
    return None


# ----------------------------------------------------------------------------------------------- header

def _header(data: bytes, path: str) -> tuple[str | None, list[_Element], int, int]:
    """(byte order or None for ascii, elements, offset of the body, number of header lines)."""
    if not (data.startswith(b"ply\n") or data.startswith(b"ply\r")):
        raise SceneError(path, 1, "not a PLY file: expected 'ply' on the first line")
    end = None
    for marker in (b"end_header\r\n", b"end_header\n", b"end_header\r"):
        k = data.find(marker, 0, MAX_HEADER_BYTES)
        if k >= 0 and (end is None or k < end[0] or (k == end[0] and len(marker) > end[1] - end[0])):
            end = (k, k + len(marker))
    if end is None:
        raise SceneError(path, 0, f"no 'end_header' line in the first {MAX_HEADER_BYTES >> 20} MiB")
    text = data[:end[0]].replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    lines = text.split(b"\n")
    if len(lines) > MAX_HEADER_LINES:
        raise SceneError(path, 0, f"the header has {len(lines)} lines, more than {MAX_HEADER_LINES}")
    fmt: str | None = "?"
    elements: list[_Element] = []
    for lineno, raw in enumerate(lines[1:], start=2):
        toks = raw.decode("latin-1").split()
        if not toks or toks[0] in ("comment", "obj_info"):
            continue
        if toks[0] == "format":
            if len(toks) != 3 or toks[1] not in _FORMATS or toks[2] != "1.0":
                raise SceneError(path, lineno, "expected 'format ascii|binary_little_endian|binary_big_endian "
                                 f"1.0', got {raw.decode('latin-1').strip()!r}")
            fmt = _FORMATS[toks[1]]
        elif toks[0] == "element":
            if len(toks) != 3 or not toks[2].isdigit():
                raise SceneError(path, lineno, "expected 'element NAME COUNT' with a count >= 0, got "
                                 f"{raw.decode('latin-1').strip()!r}")
            elements.append(_Element(toks[1], int(toks[2]), lineno))
        elif toks[0] == "property":
            if not elements:
                raise SceneError(path, lineno, "a 'property' line before any 'element' line")
            elements[-1].properties.append(_property(toks, lineno, path, raw))
        else:
            raise SceneError(path, lineno, f"unknown header keyword {toks[0]!r} (expected format, element, "
                             "property, comment, obj_info or end_header)")
    if fmt == "?":
        raise SceneError(path, 0, "the header has no 'format' line")
    names = [e.name for e in elements]
    for e in elements:
        seen = [p.name for p in e.properties]
        dup = next((n for n in seen if seen.count(n) > 1), None)
        if dup is not None:
            raise SceneError(path, e.line, f"element {e.name!r} declares property {dup!r} twice")
        if names.count(e.name) > 1 and e.name in ("vertex", "face", "tristrips"):
            raise SceneError(path, e.line, f"element {e.name!r} is declared twice")
    vertex = next((e for e in elements if e.name == "vertex"), None)
    if vertex is None:
        raise SceneError(path, 0, "no 'vertex' element: a PLY model needs one with properties x, y, z")
    for axis in ("x", "y", "z"):
        if not any(p.name == axis and p.count_kind is None for p in vertex.properties):
            raise SceneError(path, vertex.line, f"element 'vertex' has no scalar property {axis!r}")
    return fmt, elements, end[1], len(lines) + 1


def _property(toks: list[str], lineno: int, path: str, raw: bytes) -> _Property:
    if len(toks) == 3 and toks[1] in _TYPES:
        return _Property(toks[2], _TYPES[toks[1]], None, lineno)
    if len(toks) == 5 and toks[1] == "list" and toks[2] in _TYPES and toks[3] in _TYPES:
        if _TYPES[toks[2]][0] == "f":
            raise SceneError(path, lineno, f"a list's length must have an integer type, got {toks[2]!r}")
        return _Property(toks[4], _TYPES[toks[3]], _TYPES[toks[2]], lineno)
    raise SceneError(path, lineno, "expected 'property TYPE NAME' or 'property list COUNT_TYPE TYPE NAME' "
                     f"with TYPE one of {', '.join(sorted(set(_TYPES)))}, got {raw.decode('latin-1').strip()!r}")


# ----------------------------------------------------------------------------------------------- binary

# Per element: {property name: array}; a list property gives (flat values, lengths)
_Values = dict[str, dict[str, object]]
_LINES = " lines"          # ascii only: the file line of each row (not a property name: it has a space)


def _read_binary(data: bytes, pos: int, order: str, elements: list[_Element], path: str) -> _Values:
    out: _Values = {}
    size = len(data)
    for e in elements:
        wanted = e.name in ("vertex", "face", "tristrips")
        if e.fixed:
            dtype = np.dtype([(f"p{k}", order + p.kind) for k, p in enumerate(e.properties)])
            need = e.count * dtype.itemsize
            if need > size - pos:
                raise SceneError(path, 0, f"element {e.name!r} (header line {e.line}): {e.count} rows of "
                                 f"{dtype.itemsize} bytes need {need} bytes at offset {pos}, but the file has "
                                 f"{size - pos} left")
            if wanted and dtype.itemsize == 0:        # no properties: nothing to read
                out[e.name] = {}
            elif wanted:
                rows = np.frombuffer(data, dtype=dtype, count=e.count, offset=pos)
                out[e.name] = {p.name: rows[f"p{k}"] for k, p in enumerate(e.properties)}
            pos += need
        else:
            values, pos = _binary_lists(data, pos, order, e, path, wanted)
            if wanted:
                out[e.name] = values
    return out


def _binary_lists(data: bytes, pos: int, order: str, e: _Element, path: str, wanted: bool
                  ) -> tuple[dict[str, object], int]:
    """Rows of an element with list properties: a fast path when every row has the lengths of the
    first (triangle or quad meshes), else a walk over the rows that reads only the lengths."""
    size = len(data)
    min_row = sum(np.dtype(p.count_kind or p.kind).itemsize for p in e.properties)
    if e.count * min_row > size - pos:
        raise SceneError(path, 0, f"element {e.name!r} (header line {e.line}): {e.count} rows need at least "
                         f"{e.count * min_row} bytes at offset {pos}, but the file has {size - pos} left")
    if e.count == 0:
        return {p.name: (np.zeros(0, p.kind), np.zeros(0, np.int64)) if p.count_kind else np.zeros(0, p.kind)
                for p in e.properties}, pos
    # lengths of the first row
    fields, offset, first_lengths = [], pos, []
    for k, p in enumerate(e.properties):
        if p.count_kind is None:
            fields.append((f"p{k}", order + p.kind))
            offset += np.dtype(p.kind).itemsize
            continue
        n = _read_length(data, offset, order, p, e, 0, path)
        first_lengths.append(n)
        fields.append((f"n{k}", order + p.count_kind))
        if n:
            fields.append((f"p{k}", order + p.kind, (n,)))
        offset += np.dtype(p.count_kind).itemsize + n * np.dtype(p.kind).itemsize
    dtype = np.dtype(fields)
    if e.count * dtype.itemsize <= size - pos:
        rows = np.frombuffer(data, dtype=dtype, count=e.count, offset=pos)
        same = all(np.all(rows[f"n{k}"] == n) for k, n in zip(
            [k for k, p in enumerate(e.properties) if p.count_kind], first_lengths))
        if same:
            values: dict[str, object] = {}
            if wanted:
                for k, p in enumerate(e.properties):
                    if p.count_kind is None:
                        values[p.name] = rows[f"p{k}"]
                    else:
                        n = int(rows[f"n{k}"][0])
                        flat = rows[f"p{k}"].reshape(-1) if n else np.zeros(0, p.kind)
                        # every row's length is n: one broadcast value, not an array of them
                        values[p.name] = (flat, np.broadcast_to(np.int64(n), (e.count,)))
            return values, pos + e.count * dtype.itemsize
    return _walk_lists(data, pos, order, e, path, wanted)


def _read_length(data: bytes, offset: int, order: str, p: _Property, e: _Element, row: int, path: str) -> int:
    width = np.dtype(p.count_kind).itemsize
    if offset + width > len(data):
        raise SceneError(path, 0, f"element {e.name!r} row {row}: the file ends inside property {p.name!r} "
                         f"(offset {offset})")
    n = int(np.frombuffer(data, dtype=order + p.count_kind, count=1, offset=offset)[0])
    if n < 0 or n > MAX_LIST_LENGTH:
        raise SceneError(path, 0, f"element {e.name!r} row {row}: list {p.name!r} has length {n} at offset "
                         f"{offset}; expected 0 to {MAX_LIST_LENGTH}")
    return n


def _walk_lists(data: bytes, pos: int, order: str, e: _Element, path: str, wanted: bool
                ) -> tuple[dict[str, object], int]:
    """Rows of varying list lengths: one pass that reads the lengths and records the offsets, then
    every property gathered with numpy from those offsets."""
    size = len(data)
    codes = {"i1": "b", "u1": "B", "i2": "h", "u2": "H", "i4": "i", "u4": "I"}
    layout = []      # per property: (is_list, struct format of its length or scalar width, item width)
    for p in e.properties:
        if p.count_kind is None:
            layout.append((False, None, np.dtype(p.kind).itemsize))
        else:
            layout.append((True, struct.Struct(order + codes[p.count_kind]), np.dtype(p.kind).itemsize))
    starts = [np.zeros(e.count, np.int64) for _ in e.properties]
    lengths = [np.zeros(e.count, np.int64) for _ in e.properties]
    offset = pos
    for row in range(e.count):
        for k, (is_list, fmt, width) in enumerate(layout):
            if not is_list:
                starts[k][row] = offset
                offset += width
                continue
            if offset + fmt.size > size:
                raise SceneError(path, 0, f"element {e.name!r} row {row}: the file ends inside property "
                                 f"{e.properties[k].name!r} (offset {offset})")
            n = fmt.unpack_from(data, offset)[0]
            if n < 0 or n > MAX_LIST_LENGTH:
                raise SceneError(path, 0, f"element {e.name!r} row {row}: list {e.properties[k].name!r} has "
                                 f"length {n} at offset {offset}; expected 0 to {MAX_LIST_LENGTH}")
            offset += fmt.size
            starts[k][row] = offset
            lengths[k][row] = n
            offset += n * width
        if offset > size:
            raise SceneError(path, 0, f"element {e.name!r} row {row} ends at byte {offset}, beyond the file's "
                             f"{size} bytes")
    values: dict[str, object] = {}
    if wanted:
        buf = np.frombuffer(data, dtype=np.uint8)
        for k, p in enumerate(e.properties):
            width = layout[k][2]
            if p.count_kind is None:
                idx = starts[k][:, None] + np.arange(width)
                values[p.name] = buf[idx].copy().view(order + p.kind).reshape(-1)
            else:
                n = lengths[k]
                item_start = np.repeat(starts[k], n) + width * (np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n))
                idx = item_start[:, None] + np.arange(width)
                values[p.name] = (buf[idx].copy().view(order + p.kind).reshape(-1), n)
    return values, offset


# ------------------------------------------------------------------------------------------------ ascii

def _read_ascii(data: bytes, pos: int, header_lines: int, elements: list[_Element], path: str) -> _Values:
    """One row per line (blank lines skipped), as every ascii PLY writer does."""
    body = data[pos:].replace(b"\r\n", b"\n").replace(b"\r", b"\n")
    lines = body.split(b"\n")
    numbers = [k for k, ln in enumerate(lines) if ln.strip()]
    total = sum(e.count for e in elements)
    if total > len(numbers):
        raise SceneError(path, 0, f"the header declares {total} rows but the data has {len(numbers)} lines")
    out: _Values = {}
    at = 0
    for e in elements:
        rows = numbers[at:at + e.count]
        at += e.count
        if e.name not in ("vertex", "face", "tristrips"):
            continue
        first_line = header_lines + 1
        out[e.name] = _ascii_element([lines[k] for k in rows], [first_line + k for k in rows], e, path)
        out[e.name][_LINES] = [first_line + k for k in rows]
    return out


def _ascii_element(rows: list[bytes], line_of: list[int], e: _Element, path: str) -> dict[str, object]:
    if e.fixed:
        width = len(e.properties)
        for r, ln in zip(rows, line_of):
            if len(r.split()) != width:
                raise SceneError(path, ln, f"element {e.name!r}: expected {width} numbers, got {len(r.split())}")
        toks = b" ".join(rows).split()
        table = _ascii_numbers(toks, lambda k: line_of[k // width], path, e).reshape(len(rows), width)
        return {p.name: _ascii_cast(table[:, k], p, e, path, line_of) for k, p in enumerate(e.properties)}
    if len(e.properties) == 1 and rows:
        fast = _ascii_uniform_list(rows, line_of, e, path)
        if fast is not None:
            return fast
    # rows with lists: per row, walk the properties
    per_prop: list[list] = [[] for _ in e.properties]
    lens: list[list[int]] = [[] for _ in e.properties]
    for r, ln in zip(rows, line_of):
        toks = r.split()
        at = 0
        for k, p in enumerate(e.properties):
            if at >= len(toks):
                raise SceneError(path, ln, f"element {e.name!r}: the line ends before property {p.name!r}")
            if p.count_kind is None:
                per_prop[k].append(toks[at])
                at += 1
                continue
            try:
                n = int(toks[at])
            except ValueError:
                raise SceneError(path, ln, f"element {e.name!r}: expected the length of list {p.name!r}, got "
                                 f"{toks[at].decode('latin-1')!r}") from None
            if n < 0 or n > MAX_LIST_LENGTH or at + 1 + n > len(toks):
                raise SceneError(path, ln, f"element {e.name!r}: list {p.name!r} of length {n} does not fit the "
                                 f"line's {len(toks) - at - 1} remaining numbers")
            per_prop[k].extend(toks[at + 1:at + 1 + n])
            lens[k].append(n)
            at += 1 + n
        if at != len(toks):
            raise SceneError(path, ln, f"element {e.name!r}: {len(toks) - at} numbers left over after the last "
                             "property")
    out: dict[str, object] = {}
    for k, p in enumerate(e.properties):
        n = np.asarray(lens[k], np.int64)
        owner = np.repeat(np.arange(len(rows)), n) if p.count_kind else np.arange(len(rows))
        owner_lines = [line_of[i] for i in owner] if len(owner) else []
        vals = _ascii_cast(_ascii_numbers(per_prop[k], owner_lines.__getitem__, path, e), p, e, path, owner_lines)
        out[p.name] = (vals, n) if p.count_kind else vals
    return out


def _ascii_uniform_list(rows: list[bytes], line_of: list[int], e: _Element, path: str) -> dict | None:
    """An element of one list property whose rows all hold the same number of tokens, each starting
    with that number less one (a triangle mesh's faces): one table instead of a walk per row."""
    width = len(rows[0].split())
    toks = b" ".join(rows).split()
    if width < 1 or len(toks) != width * len(rows):
        return None
    try:
        table = np.fromiter(map(float, toks), np.float64, len(toks)).reshape(len(rows), width)
    except ValueError:
        return None                     # the walk names the bad token's line
    if not np.all(table[:, 0] == width - 1) or width - 1 > MAX_LIST_LENGTH:
        return None
    p = e.properties[0]
    owner = np.repeat(np.asarray(line_of), width - 1)
    values = _ascii_cast(table[:, 1:].reshape(-1), p, e, path, owner.tolist() if len(owner) < 2 else owner)
    return {p.name: (values, np.full(len(rows), width - 1, np.int64))}


def _ascii_numbers(toks: list[bytes], line_of_token, path: str, e: _Element) -> np.ndarray:
    """float64 values of the tokens (integers up to 2**53 are exact); a bad token names its line
    (``line_of_token(k)``)."""
    try:
        return np.fromiter(map(float, toks), np.float64, len(toks))   # 5x numpy's bytes-to-float astype
    except ValueError:
        for k, t in enumerate(toks):
            try:
                float(t)
            except ValueError:
                raise SceneError(path, line_of_token(k), f"element {e.name!r}: expected a number, got "
                                 f"{t.decode('latin-1')!r}") from None
        raise


def _ascii_cast(values: np.ndarray, p: _Property, e: _Element, path: str, line_of: list[int]) -> np.ndarray:
    """Values of type ``p.kind``: integers must be whole and in the type's range, floats finite."""
    bad = ~np.isfinite(values)
    if p.kind[0] != "f":
        info = np.iinfo(p.kind)
        bad |= (values != np.round(values)) | (values < info.min) | (values > info.max)
    if bad.any():
        k = int(np.argmax(bad))
        kind = "a finite number" if p.kind[0] == "f" else f"an integer of type {p.kind}"
        raise SceneError(path, line_of[k] if k < len(line_of) else 0,
                         f"element {e.name!r} property {p.name!r}: expected {kind}, got {values[k]:g}")
    return values.astype(p.kind)


# ------------------------------------------------------------------------------------------- assembling

def _assemble(values: _Values, elements: list[_Element], path: str) -> ObjData:
    by_name = {e.name: e for e in elements}
    if "vertex" not in values:
        raise SceneError(path, 0, "no 'vertex' element: a PLY model needs one with properties x, y, z")
    vert, ve = values["vertex"], by_name["vertex"]
    for axis in ("x", "y", "z"):
        if axis not in vert or isinstance(vert[axis], tuple):
            raise SceneError(path, ve.line, f"element 'vertex' has no scalar property {axis!r}")
    nv = len(vert["x"])
    positions = np.empty((nv, 3))
    for k, a in enumerate(("x", "y", "z")):
        positions[:, k] = vert[a]
    # columns' extremes first (NaN propagates, infinities exceed the limit), rows only to name a bad one
    lo, hi = column_range(positions) if nv else (np.zeros(3), np.zeros(3))
    if not np.all(np.maximum(-lo, hi) <= MAX_COORDINATE):
        a = np.abs(positions)
        bad = ~(np.maximum(np.maximum(a[:, 0], a[:, 1]), a[:, 2]) <= MAX_COORDINATE)
        k = int(np.argmax(bad))
        raise SceneError(path, 0, f"vertex {k}: coordinate {positions[k].tolist()} is not finite or beyond the "
                         f"supported range of +-{MAX_COORDINATE:g}")
    normals = _vector(vert, ("nx", "ny", "nz"))
    uv = next((_vector(vert, names) for names in _UV_NAMES if _vector(vert, names) is not None), None)
    colours = next((_colour(vert, names, ve) for names in _COLOUR_NAMES if _vector(vert, names) is not None), None)
    for what, a in (("normal", normals), ("texture coordinate", uv), ("colour", colours)):
        if a is not None and not np.isfinite(a).all():
            k = int(np.argmax(~np.isfinite(a).all(axis=1)))
            raise SceneError(path, 0, f"vertex {k}: {what} {a[k].tolist()} is not finite")
    faces = []
    if "face" in values:
        faces.append(_polygons(values["face"], by_name["face"], nv, path))
    if "tristrips" in values:
        strips, _joins = _strips(values["tristrips"], by_name["tristrips"], nv, path)
        faces.append(strips)
    tri = np.concatenate(faces) if faces else np.zeros((0, 3), np.int32)
    keep = nonzero_area(positions, tri)
    if not keep.all():
        tri = tri[keep]
    # "no such corner data" (-1 everywhere) is one broadcast value, not two more (F, 3) arrays
    has = lambda a: tri if a is not None else np.broadcast_to(np.int32(-1), tri.shape)      # noqa: E731
    names = [CHECKER_NAME]
    materials: dict[str, Material] = {}
    texcoords = uv.astype(np.float32) if uv is not None else np.zeros((0, 2), np.float32)
    face_tex = has(uv)
    notes = []
    if colours is not None and not colour_texture_fits(len(tri)):
        notes.append(colour_texture_note(path, len(tri)))
        colours = None
    if colours is not None and len(tri):
        texcoords, face_tex, image = vertex_colour_texture(colours, tri)
        # named after the file: several coloured files in one scene each keep their own texture
        name = f"{os.path.basename(path)}: {VERTEX_COLOUR_MATERIAL}"
        names.append(name)
        materials[name] = Material(
            name, diffuse=(1.0, 1.0, 1.0), roughness=1.0, fuzz=0.0, ior=1.0,  # diffuse, as clay
            diffuse_map=TextureRef(
                f"{os.path.basename(path)}#vertex-colours", path, 0, image=image),
            source=path, seed_dialect=False)
    return ObjData(
        path=path, positions=positions, texcoords=texcoords,
        normals=normals.astype(np.float32) if normals is not None else np.zeros((0, 3), np.float32),
        faces=tri.astype(np.int32, copy=False), face_texcoords=face_tex.astype(np.int32, copy=False),
        face_normals=has(normals).astype(np.int32, copy=False),
        face_material=np.full(len(tri), len(names) - 1, np.int32),
        spheres=np.zeros((0, 4)), sphere_material=np.zeros(0, np.int32),
        material_names=names, material_lines=[0] * len(names),
        dropped_degenerate=int(len(keep) - np.count_nonzero(keep)),
        materials=materials, warnings=notes,
    )


def _vector(vert: dict, names: tuple[str, ...]) -> np.ndarray | None:
    if not all(n in vert and not isinstance(vert[n], tuple) for n in names):
        return None
    return np.stack([np.asarray(vert[n], np.float64) for n in names], axis=1)


def _colour(vert: dict, names: tuple[str, ...], e: _Element) -> np.ndarray:
    kinds = {p.name: p.kind for p in e.properties}
    cols = []
    for n in names:
        v = np.asarray(vert[n], np.float64)
        if kinds[n][0] in "iu":
            v = v / float(np.iinfo(kinds[n]).max)
        cols.append(np.clip(v, 0.0, 1.0))
    return np.stack(cols, axis=1)


def _index_list(values: dict, e: _Element, path: str) -> tuple[np.ndarray, np.ndarray]:
    for name in ("vertex_indices", "vertex_index"):
        if name in values and isinstance(values[name], tuple):
            flat, lengths = values[name]
            prop = next(p for p in e.properties if p.name == name)
            if prop.kind[0] == "f":
                raise SceneError(path, prop.line, f"element {e.name!r}: list {name!r} has a float type; vertex indices "
                                 "must be integers")
            flat = np.asarray(flat)
            # signed types up to int32 compare and convert as they are (no int64 copy of a large
            # mesh's indices); unsigned and wider ones as int64, so that a huge value is not wrapped
            if not (flat.dtype.kind == "i" and flat.dtype.itemsize <= 4):
                flat = flat.astype(np.int64)
            return flat, np.asarray(lengths, np.int64)
    raise SceneError(path, e.line, f"element {e.name!r} has no list property 'vertex_indices'")


def _row_line(values: dict, row: int) -> int:
    """The file line of an element's row (ascii), else 0."""
    lines = values.get(_LINES)
    return lines[row] if lines is not None and row < len(lines) else 0


def _polygons(values: dict, e: _Element, nv: int, path: str) -> np.ndarray:
    flat, n = _index_list(values, e, path)
    short = n < 3
    if short.any():
        k = int(np.argmax(short))
        raise SceneError(path, _row_line(values, k), f"face {k} has {n[k]} corners; a face needs at least 3")
    bad = (flat < 0) | (flat >= nv)
    if bad.any():
        k = int(np.argmax(bad))
        row = int(np.searchsorted(np.cumsum(n), k, side="right"))
        raise SceneError(path, _row_line(values, row), f"face {row}: vertex index {flat[k]} is out of range: the "
                         f"file has {nv} vertices")
    if np.all(n == 3):
        return flat.reshape(-1, 3).astype(np.int32, copy=not flat.flags.writeable)
    from warp_spt.io.obj import _fan
    return flat[_fan(n)].astype(np.int32)


def _strips(values: dict, e: _Element, nv: int, path: str) -> tuple[np.ndarray, int]:
    """Triangles of the strips (restarts at -1, alternate triangles swapped), and how many triangles
    repeated an index (strip joins, dropped)."""
    flat, n = _index_list(values, e, path)
    bad = (flat < -1) | (flat >= nv)
    if bad.any():
        k = int(np.argmax(bad))
        row = int(np.searchsorted(np.cumsum(n), k, side="right"))
        raise SceneError(path, _row_line(values, row), f"tristrips row {row}: vertex index {flat[k]} is out of range: expected -1 "
                         f"(restart) or 0 to {nv - 1}")
    # a strip starts at index 0, after each -1 and at each row's start; positions count from there
    j = np.arange(len(flat))
    row_start = np.zeros(len(flat), bool)
    row_start[(np.cumsum(n) - n)[n > 0]] = True
    is_start = row_start | np.concatenate([[True], flat[:-1] == -1])
    pos_in_strip = j - np.maximum.accumulate(np.where(is_start, j, 0))
    i = np.arange(len(flat) - 2)
    if len(i) == 0:
        return np.zeros((0, 3), np.int32), 0
    a, b, c = flat[i], flat[i + 1], flat[i + 2]
    # (i, i+1, i+2) lies in one strip when none is -1 and no strip starts at i+1 or i+2
    same = (a >= 0) & (b >= 0) & (c >= 0) & (pos_in_strip[i + 2] == pos_in_strip[i] + 2)
    odd = (pos_in_strip[i] % 2) == 1
    tri = np.stack([np.where(odd, b, a), np.where(odd, a, b), c], axis=1)[same]
    join = (tri[:, 0] == tri[:, 1]) | (tri[:, 1] == tri[:, 2]) | (tri[:, 0] == tri[:, 2])
    return tri[~join].astype(np.int32), int(np.count_nonzero(join))


# --------------------------------------------------------------------------------------- vertex colours

def colour_texture_fits(triangles: int) -> bool:
    """Whether the vertex colours of ``triangles`` triangles fit the texel budget (4 texels each,
    checked before the texture is made)."""
    return 4 * (triangles + 2 * int(np.sqrt(triangles)) + 1) <= TEXEL_BUDGET


def colour_texture_note(path: str, triangles: int) -> str:
    return (f"{path}: the vertex colours of {triangles:,} triangles need more than the texture budget of "
            f"{TEXEL_BUDGET:,} texels (4 per triangle); they are ignored")


def vertex_colour_texture(colours: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(texcoords (3F, 2), face_texcoords (F, 3), image (H, W, 3) float32): every triangle's corner
    colours at the centres of three texels of its own 2x2 block; the fourth texel is c1 + c2 - c0
    (clipped), which makes bilinear filtering inside the triangle the linear interpolation."""
    f = len(faces)
    per_row = max(1, int(np.ceil(np.sqrt(f))))
    rows = -(-f // per_row)
    w, h = 2 * per_row, 2 * rows
    image = np.zeros((h, w, 3), np.float32)
    k = np.arange(f)
    bx, by = 2 * (k % per_row), 2 * (k // per_row)
    c = colours[faces].astype(np.float32)                 # (F, 3 corners, 3)
    image[by, bx] = c[:, 0]
    image[by, bx + 1] = c[:, 1]
    image[by + 1, bx] = c[:, 2]
    image[by + 1, bx + 1] = np.clip(c[:, 1] + c[:, 2] - c[:, 0], 0.0, 1.0)
    # texel (row, col) centre: u = (col + 0.5) / w, v = 1 - (row + 0.5) / h (v = 0 is the bottom row)
    cols = np.stack([bx, bx + 1, bx], axis=1)
    rws = np.stack([by, by, by + 1], axis=1)
    uv = np.stack([(cols + 0.5) / w, 1.0 - (rws + 0.5) / h], axis=-1).reshape(-1, 2).astype(np.float32)
    return uv, np.arange(3 * f, dtype=np.int32).reshape(f, 3), image
