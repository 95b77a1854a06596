"""Wavefront OBJ: the seed's dialect plus what real exporters write, read into :class:`ObjData`.

Grammar (one statement per line, see :mod:`warp_spt.io.tokens` for lines, tokens and comments):

* ``v x y z`` (an optional ``w`` or an ``r g b`` vertex colour may follow and is ignored),
  ``vt u [v [w]]`` (v defaults to 0, w is dropped), ``vn x y z``;
* ``f`` with 3 or more corners ``v``, ``v/vt``, ``v/vt/vn`` or ``v//vn``; indices are 1-based,
  negative ones count back from the last element defined above the line; a positive index may
  point at an element defined further down. Polygons are triangulated as a fan from their first
  corner. Triangles of zero area are dropped and counted (``ObjData.dropped_degenerate``);
* ``b x y z r``: the seed's sphere, r > 0;
* ``usemtl NAME`` (faces and spheres before any ``usemtl`` get ``Inner_CheckerTexture``),
  ``mtllib FILE...`` (resolved relative to the OBJ; see :func:`_mtllib_paths`);
* every other statement (``o``, ``g``, ``s``, ``l``, ``p``, free-form geometry...) is ignored.

Everything else is a :class:`SceneError` naming the file and line: a malformed number, NaN or
infinity (also after float32 conversion), a wrong count of values, an index of 0 or out of range,
a face with fewer than 3 corners, a sphere radius <= 0.

Two scanners produce the same :class:`RawObj`: a vectorised one (:mod:`warp_spt.io.obj_bulk`) for the
bulk ``v``/``vt``/``vn``/``f`` lines, and a line-by-line one here, which is the reference and the
fallback. The fast scanner gives up on anything irregular, and the line scanner then either reads
the file or reports the first bad line, so error messages never depend on the scanner.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import numpy as np

from warp_spt.io.paths import confine
from warp_spt.io.obj_scan import _INDEX_NAMES, RawObj, scan_lines
from warp_spt.io.tokens import decode_name, is_regular_file, normalise_text, read_file
from warp_spt.scene.errors import SceneError
from warp_spt.scene.model import CHECKER_NAME, ObjData

# Geometry within +-MAX_COORDINATE: the ray-triangle test forms products of two coordinates in float32
# (1e30, far below 3.4e38) and a sphere's box must be finite in float32; no triangle's edge longer than
# MAX_TRIANGLE_EDGE (scene.limits says why).
from warp_spt.scene.validate import (
    MAX_COORDINATE,
    MAX_TRIANGLE_EDGE,
    box_bounds_edges,
    edge_problem,
    longest_edges,
    nonzero_area,
)


def load_obj(path: str | os.PathLike[str]) -> ObjData:
    """Read one OBJ file (one object of the scene) into validated arrays; see the module docs.

    Raises :class:`SceneError` for a missing file or bad content, with the file and line.
    """
    path = str(path)
    return parse_obj_bytes(read_file(path, "OBJ"), path)


def parse_obj_bytes(data: bytes, path: str = "<input>", *, fast: bool = True) -> ObjData:
    """Parse OBJ text given as bytes; ``path`` names it in errors and anchors ``mtllib`` paths.

    ``fast=False`` forces the line-by-line scanner (the tests compare the two).
    """
    from warp_spt.io.obj_bulk import (  # the vectorised scanners build on this module's grammar
        scan_bulk,
        scan_plain,
    )

    data = normalise_text(data, path, "OBJ")
    raw = (scan_plain(data, path) or scan_bulk(data, path)) if fast else None
    if raw is None:
        raw = scan_lines(data, path)
    return resolve(raw, path)


def resolve(raw: RawObj, path: str) -> ObjData:
    """Resolve indices and materials, triangulate polygons and drop zero-area triangles."""
    _check_extent(raw.positions, raw.v_line, path, "vertex coordinate")
    sphere_box = np.abs(raw.spheres[:, :3].astype(np.float64)) + raw.spheres[:, 3:4].astype(np.float64)
    _check_extent(sphere_box, raw.sphere_line, path, "sphere (|centre| + radius)")
    corner_line = np.repeat(raw.poly_line, raw.poly_size)
    cv = _resolve_index(raw.corner_v, raw.v_line, corner_line, "v", path)
    ct = _resolve_index(raw.corner_vt, raw.vt_line, corner_line, "vt", path)
    cn = _resolve_index(raw.corner_vn, raw.vn_line, corner_line, "vn", path)
    tri = _fan(raw.poly_size)
    faces, ftex, fnrm = cv[tri], ct[tri], cn[tri]
    tri_line = np.repeat(raw.poly_line, raw.poly_size - 2)
    keep = nonzero_area(raw.positions, faces)
    edges = None if box_bounds_edges(raw.positions, MAX_TRIANGLE_EDGE) else longest_edges(raw.positions, faces)
    if edges is not None and (keep & ~(edges <= MAX_TRIANGLE_EDGE)).any():
        k = int(np.argmax(keep & ~(edges <= MAX_TRIANGLE_EDGE)))
        raise SceneError(path, int(tri_line[k]), edge_problem(float(edges[k])))
    names, lines, event_index = _material_names(raw.usemtl)
    face_mat = _material_at(raw.usemtl, event_index, tri_line[keep])
    sphere_mat = _material_at(raw.usemtl, event_index, raw.sphere_line)
    libs = _mtllib_paths(raw.mtllib, path)
    return ObjData(
        path=path, format="OBJ",
        positions=raw.positions, texcoords=raw.texcoords, normals=raw.normals,
        faces=faces[keep], face_texcoords=ftex[keep], face_normals=fnrm[keep],
        face_material=face_mat,
        spheres=raw.spheres, sphere_material=sphere_mat,
        material_names=names, material_lines=lines,
        mtllibs=[p for p, _ in libs], mtllib_lines=[ln for _, ln in libs],
        dropped_degenerate=int(len(keep) - np.count_nonzero(keep)),
    )


def _check_extent(values: np.ndarray, lines: np.ndarray, path: str, what: str) -> None:
    """Every coordinate within +-MAX_COORDINATE (so the kernel's products stay finite in float32)."""
    if len(values) == 0:
        return
    bad = np.abs(values.astype(np.float64)).max(axis=1) > MAX_COORDINATE
    if bad.any():
        k = int(np.argmax(bad))
        raise SceneError(path, int(lines[k]), f"{what} {np.abs(values[k]).max():g} is beyond the supported "
                                              f"range of +-{MAX_COORDINATE:g}")


def _resolve_index(raw: np.ndarray, ref_line: np.ndarray, corner_line: np.ndarray, kind: str, path: str) -> np.ndarray:
    """0-based int32 indices (-1 where absent) from the file's 1-based or negative ones."""
    n = len(ref_line)
    idx = raw - 1
    neg = raw < 0
    if neg.any():
        # elements defined above the corner's line; ref_line is sorted (file order)
        idx[neg] = np.searchsorted(ref_line, corner_line[neg]) + raw[neg]
    bad = (raw != 0) & ((idx < 0) | (idx >= n))
    if bad.any():
        k = int(np.argmax(bad))
        noun = _INDEX_NAMES[kind]
        if raw[k] > 0:
            msg = f"{noun} index {raw[k]} is out of range: the file has {n} '{kind}' lines"
        else:
            above = int(idx[k] - raw[k])
            msg = f"relative {noun} index {raw[k]} is out of range: {above} '{kind}' lines precede it"
        raise SceneError(path, int(corner_line[k]), msg)
    idx[raw == 0] = -1
    return idx.astype(np.int32)


def _fan(poly_size: np.ndarray) -> np.ndarray:
    """(F, 3) corner numbers of the fan triangulation (c0, ci, ci+1) of every polygon."""
    ntri = poly_size - 2
    first = np.cumsum(poly_size) - poly_size          # corner number of each polygon's c0
    tri_first = np.cumsum(ntri) - ntri                # triangle number of each polygon's first triangle
    c0 = np.repeat(first, ntri)
    step = np.arange(len(c0), dtype=np.int64) - np.repeat(tri_first, ntri)
    return np.stack([c0, c0 + step + 1, c0 + step + 2], axis=1)


def _material_names(usemtl: list[tuple[int, str]]) -> tuple[list[str], list[int], np.ndarray]:
    """(names with the default first, line of each name's first usemtl, name index per usemtl)."""
    names, lines = [CHECKER_NAME], [0]
    where = {CHECKER_NAME: 0}
    per_event = []
    for lineno, name in usemtl:
        if name not in where:
            where[name] = len(names)
            names.append(name)
            lines.append(lineno)
        per_event.append(where[name])
    return names, lines, np.asarray(per_event, dtype=np.int32)


def _material_at(usemtl: list[tuple[int, str]], event_index: np.ndarray, lines: np.ndarray) -> np.ndarray:
    """The material in force at each line: the last usemtl above it, else the default (0)."""
    if not usemtl:
        return np.zeros(len(lines), dtype=np.int32)
    event_line = np.asarray([ln for ln, _ in usemtl], dtype=np.int64)
    k = np.searchsorted(event_line, lines, side="right") - 1
    return np.where(k >= 0, event_index[np.maximum(k, 0)], 0).astype(np.int32)


def _mtllib_paths(args_list: list[tuple[int, list[bytes]]], obj_path: str) -> list[tuple[str, int]]:
    """(MTL path, line) of the ``mtllib`` lines, relative to the OBJ's folder, ``\\`` read as ``/``.

    A line names several files separated by spaces, unless the whole rest of the line names an
    existing file (a file name with spaces).
    """
    base = Path(obj_path).parent

    def inside(name: str, lineno: int) -> Path:          # the rule of warp_spt.io.paths
        found, refused = confine(name, base, "mtllib")
        if refused:
            raise SceneError(obj_path, lineno, refused)
        return found[0]

    out: list[tuple[str, int]] = []
    for lineno, args in args_list:
        whole = inside(decode_name(args), lineno)
        names = [whole] if is_regular_file(whole) else [inside(decode_name([a]), lineno) for a in args]
        out += [(str(p), lineno) for p in names if str(p) not in (q for q, _ in out)]
    return out


def write_obj(
    path: str | os.PathLike[str],
    positions: np.ndarray,
    faces: np.ndarray,
    *,
    texcoords: np.ndarray | None = None,
    face_texcoords: np.ndarray | None = None,
    normals: np.ndarray | None = None,
    face_normals: np.ndarray | None = None,
    material_names: Sequence[str] | None = None,
    face_material: np.ndarray | None = None,
    spheres: np.ndarray | None = None,
    sphere_material: np.ndarray | None = None,
    mtllib: str | None = None,
) -> None:
    """Write a mesh (0-based arrays, -1 for an absent vt/vn corner) as an OBJ that :func:`load_obj` reads back.

    Positions and spheres are written with 17 significant digits, which round-trips float64 exactly
    (the reader keeps them float64), texture coordinates and normals with 9, which round-trips their
    float32 exactly. Faces keep
    their order; a ``usemtl`` line is written wherever ``face_material`` changes.
    """
    nf = len(faces)
    ft = _corner_array(face_texcoords, nf)
    fn = _corner_array(face_normals, nf)
    names = list(material_names) if material_names is not None else [CHECKER_NAME]
    fmat = np.zeros(nf, np.int64) if face_material is None else np.asarray(face_material)
    with open(path, "w", encoding="utf-8", newline="\n") as out:
        if mtllib:
            out.write(f"mtllib {mtllib}\n")
        out.write(_rows("v", positions, 3, np.float64))
        out.write(_rows("vt", texcoords, 2))
        out.write(_rows("vn", normals, 3))
        out.write(_face_block(faces, ft, fn, fmat, names))
        if spheres is not None and len(spheres):
            smat = np.zeros(len(spheres), np.int64) if sphere_material is None else np.asarray(sphere_material)
            for s, m in zip(np.asarray(spheres, dtype=np.float64), smat):
                out.write(f"usemtl {names[m]}\nb {s[0]:.17g} {s[1]:.17g} {s[2]:.17g} {s[3]:.17g}\n")


def _corner_array(a: np.ndarray | None, nf: int) -> np.ndarray:
    return np.full((nf, 3), -1, np.int64) if a is None else np.asarray(a, dtype=np.int64)


def _rows(tag: str, values: np.ndarray | None, width: int, dtype=np.float32) -> str:
    """``tag`` lines for an (N, width) array of ``dtype`` values, with the digits that round-trip that
    type (9 for float32, 17 for float64), formatted in one C-level operation."""
    if values is None or len(values) == 0:
        return ""
    digits = 17 if dtype == np.float64 else 9
    flat = np.asarray(values, dtype=dtype).reshape(-1, width).astype(np.float64).ravel().tolist()
    return ((tag + f" %.{digits}g" * width + "\n") * (len(flat) // width)) % tuple(flat)


def _face_block(faces: np.ndarray, ft: np.ndarray, fn: np.ndarray, fmat: np.ndarray, names: list[str]) -> str:
    """``f`` lines (1-based), with a ``usemtl`` line wherever the material changes."""
    v = np.asarray(faces, dtype=np.int64) + 1
    cuts = np.flatnonzero(np.diff(fmat)) + 1
    parts = []
    for lo, hi in zip(np.r_[0, cuts], np.r_[cuts, len(v)]):
        if hi > lo:
            parts.append(f"usemtl {names[fmat[lo]]}\n")
            parts.append(_faces_text(v[lo:hi], ft[lo:hi], fn[lo:hi]))
    return "".join(parts)


def _faces_text(v: np.ndarray, ft: np.ndarray, fn: np.ndarray) -> str:
    """Face lines; one C-level format when every corner has the same form, else face by face."""
    has_t, has_n = ft >= 0, fn >= 0
    if has_t.all() == has_t.any() and has_n.all() == has_n.any():
        corner = {(True, True): "%d/%d/%d", (False, True): "%d//%d", (True, False): "%d/%d", (False, False): "%d"}
        cols = [v] + ([ft + 1] if has_t.any() else []) + ([fn + 1] if has_n.any() else [])
        flat = np.stack(cols, axis=2).ravel().tolist()
        line = "f " + " ".join([corner[bool(has_t.any()), bool(has_n.any())]] * 3) + "\n"
        return (line * len(v)) % tuple(flat)
    return "".join(
        "f " + " ".join(_corner_text(v[r, k], ft[r, k], fn[r, k]) for k in range(3)) + "\n" for r in range(len(v))
    )


def _corner_text(v: int, t: int, n: int) -> str:
    if n >= 0:
        return f"{v}/{t + 1}/{n + 1}" if t >= 0 else f"{v}//{n + 1}"
    return f"{v}/{t + 1}" if t >= 0 else f"{v}"
