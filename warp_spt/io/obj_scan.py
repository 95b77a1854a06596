"""The OBJ grammar and its reference scanner: statements read one line at a time into a :class:`RawObj`.

:mod:`warp_spt.io.obj_bulk` is the vectorised scanner for the bulk ``v``/``vt``/``vn``/``f`` lines;
both produce the same :class:`RawObj`, which :mod:`warp_spt.io.obj` resolves into an ObjData.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from warp_spt.io.tokens import (
    decode_name,
    iter_lines,
    parse_float,
    parse_floats,
    parse_int,
    show,
)
from warp_spt.scene.errors import SceneError

# How many numbers each vertex statement takes (the first 3, or 2 for vt, are kept).
V_COUNTS = (3, 4, 6)


VT_COUNTS = (1, 2, 3)


VN_COUNTS = (3,)


@dataclass
class RawObj:
    """An OBJ as written, before indices are resolved: what both scanners produce.

    Corner indices are the integers of the file (1-based or negative); 0 marks an absent vt/vn.
    Every element carries its 1-based line number, which resolves relative indices and materials.
    """

    positions: np.ndarray   # (V, 3) float64 (rounded to float32 only at upload)
    v_line: np.ndarray      # (V,) int64
    texcoords: np.ndarray   # (T, 2) float32
    vt_line: np.ndarray
    normals: np.ndarray     # (N, 3) float32
    vn_line: np.ndarray
    corner_v: np.ndarray    # (C,) int64
    corner_vt: np.ndarray   # (C,) int64, 0 = absent
    corner_vn: np.ndarray   # (C,) int64, 0 = absent
    poly_size: np.ndarray   # (P,) int64, >= 3
    poly_line: np.ndarray   # (P,) int64
    spheres: np.ndarray     # (S, 4) float64
    sphere_line: np.ndarray
    usemtl: list[tuple[int, str]]
    mtllib: list[tuple[int, list[bytes]]]


@dataclass
class LineReader:
    """Accumulates statements line by line (the reference scanner, also used for rare statements)."""

    path: str
    v: list[float] = field(default_factory=list)
    v_line: list[int] = field(default_factory=list)
    vt: list[float] = field(default_factory=list)
    vt_line: list[int] = field(default_factory=list)
    vn: list[float] = field(default_factory=list)
    vn_line: list[int] = field(default_factory=list)
    corners: list[int] = field(default_factory=list)   # flat (v, vt, vn) triples
    poly_size: list[int] = field(default_factory=list)
    poly_line: list[int] = field(default_factory=list)
    spheres: list[float] = field(default_factory=list)
    sphere_line: list[int] = field(default_factory=list)
    usemtl: list[tuple[int, str]] = field(default_factory=list)
    mtllib: list[tuple[int, list[bytes]]] = field(default_factory=list)   # (line, file name tokens)

    def statement(self, lineno: int, toks: list[bytes]) -> None:
        """Read one line's tokens (comment already stripped)."""
        tag, args = toks[0], toks[1:]
        if tag == b"v":
            self.v += parse_floats(args, V_COUNTS, self.path, lineno, "v")[:3]
            self.v_line.append(lineno)
        elif tag == b"vt":
            uv = parse_floats(args, VT_COUNTS, self.path, lineno, "vt") + [0.0]
            self.vt += uv[:2]
            self.vt_line.append(lineno)
        elif tag == b"vn":
            self.vn += parse_floats(args, VN_COUNTS, self.path, lineno, "vn")
            self.vn_line.append(lineno)
        elif tag == b"f":
            self._face(lineno, args)
        elif tag == b"b":
            self._sphere(lineno, args)
        elif tag == b"usemtl":
            if not args:
                raise SceneError(self.path, lineno, "expected a material name after 'usemtl'")
            self.usemtl.append((lineno, decode_name(args)))
        elif tag == b"mtllib" and args:
            self.mtllib.append((lineno, args))

    def _face(self, lineno: int, args: list[bytes]) -> None:
        if len(args) < 3:
            raise SceneError(self.path, lineno, f"expected at least 3 vertices after 'f', got {len(args)}")
        for tok in args:
            self.corners += self._corner(lineno, tok)
        self.poly_size.append(len(args))
        self.poly_line.append(lineno)

    def _corner(self, lineno: int, tok: bytes) -> list[int]:
        parts = tok.split(b"/")
        if len(parts) > 3 or (len(parts) == 2 and not parts[1]) or (len(parts) == 3 and not parts[2]):
            raise SceneError(self.path, lineno, f"expected a face corner v, v/vt, v/vt/vn or v//vn, got {show(tok)}")
        out = [0, 0, 0]
        for k, part in enumerate(parts):
            if k == 1 and not part and len(parts) == 3:
                continue  # v//vn
            what = f"{_INDEX_NAMES[('v', 'vt', 'vn')[k]]} index"
            out[k] = parse_int(part, self.path, lineno, what)
            if out[k] == 0:
                raise SceneError(self.path, lineno, f"{what} 0 is invalid: OBJ indices start at 1")
            if abs(out[k]) >= 2**62:  # the bulk scanner's integers saturate there
                raise SceneError(self.path, lineno, f"{what} {out[k]} is out of range")
        return out

    def _sphere(self, lineno: int, args: list[bytes]) -> None:
        if len(args) != 4:
            raise SceneError(self.path, lineno, f"expected 4 numbers (x y z r) after 'b', got {len(args)}")
        vals = [parse_float(t, self.path, lineno, "b") for t in args]
        if not np.float32(vals[3]) > 0:
            raise SceneError(self.path, lineno, f"expected a sphere radius > 0, got {show(args[3])}")
        self.spheres += vals
        self.sphere_line.append(lineno)

    def raw(self) -> RawObj:
        """The accumulated statements as arrays."""
        corners = np.asarray(self.corners, dtype=np.int64).reshape(-1, 3)
        return RawObj(
            positions=_f64(self.v, 3), v_line=_i64(self.v_line),
            texcoords=_f32(self.vt, 2), vt_line=_i64(self.vt_line),
            normals=_f32(self.vn, 3), vn_line=_i64(self.vn_line),
            corner_v=corners[:, 0].copy(), corner_vt=corners[:, 1].copy(), corner_vn=corners[:, 2].copy(),
            poly_size=_i64(self.poly_size), poly_line=_i64(self.poly_line),
            spheres=_f64(self.spheres, 4), sphere_line=_i64(self.sphere_line),
            usemtl=self.usemtl, mtllib=self.mtllib,
        )


def _f64(values: list[float], width: int) -> np.ndarray:
    return np.asarray(values, dtype=np.float64).reshape(-1, width)


def _f32(values: list[float], width: int) -> np.ndarray:
    return np.asarray(values, dtype=np.float64).astype(np.float32).reshape(-1, width)


def _i64(values: list[int]) -> np.ndarray:
    return np.asarray(values, dtype=np.int64)


def scan_lines(data: bytes, path: str) -> RawObj:
    """The reference scanner: every statement read one line at a time."""
    reader = LineReader(path)
    for lineno, toks in iter_lines(data):
        reader.statement(lineno, toks)
    return reader.raw()


_INDEX_NAMES = {"v": "vertex", "vt": "texture coordinate", "vn": "normal"}
