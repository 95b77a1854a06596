"""load_scene(): OBJ and MTL files to one validated :class:`Scene`.

Unlike the seed, materials resolve after every file is read, so the order of the files does not
matter. Materials come from each OBJ's ``mtllib`` files that exist (a missing one is a warning:
the seed's own demo names one that does not exist), then from the explicit MTL files, whose
definitions replace ``mtllib`` ones of the same name; among files of one kind the later wins.
The name ``Inner_CheckerTexture`` is reserved for the built-in material: an MTL definition of it
is ignored with a warning. A ``usemtl`` name that no file defines gives the built-in material
and ONE warning per name.

The material table holds row 0 (the built-in checker) and the materials that some triangle or
sphere uses, in order of first use. Textures are read only for those materials (so an MTL whose
unused materials name absent textures still loads), once per resolved file, as RGB float32 =
8-bit value / 255 (no sRGB decoding, alpha ignored, as the seed), row 0 = the image's top row.
A texture path is tried relative to its MTL file's folder, then to the working directory;
``\\`` is read as ``/``.

Warnings go to ``Scene.warnings`` and to the ``warn`` callback (by default
``warnings.warn(message, UserWarning)``; pass ``warn=lambda message: None`` to only collect them).
"""

from __future__ import annotations

import os
import warnings as _warnings
from pathlib import Path
from typing import Callable, Iterable

import numpy as np
from PIL import Image

from .errors import SceneError
from .mtl import builtin_checker, load_mtl
from .obj import load_obj
from .scene import (CHECKER_NAME, SLOT_DIFFUSE, SLOT_EMISSION, SLOT_REFLECT, SLOT_REFRACT, TEX_CHECKER,
                    TEX_NONE, TEX_PROC_BASE, Material, MaterialTable, MeshData, ObjData, Scene, TextureRef)
from .validate import validate_scene

__all__ = ["load_scene", "validate_scene"]

WarnFn = Callable[[str], None]
PathLike = str | os.PathLike[str]
_SLOT_FIELDS = ((SLOT_DIFFUSE, "diffuse_map"), (SLOT_REFLECT, "reflect_map"),
                (SLOT_REFRACT, "refract_map"), (SLOT_EMISSION, "emission_map"))


def _default_warn(message: str) -> None:
    _warnings.warn(message, UserWarning, stacklevel=3)


def load_scene(objs: Iterable[PathLike], mtls: Iterable[PathLike] = (), *, warn: WarnFn | None = None) -> Scene:
    """Read OBJ files (one object each) and MTL files into a validated :class:`Scene`.

    Raises :class:`SceneError` (file, line, what was expected) for unreadable or bad input,
    including a scene with no triangles and no spheres. See the module docs for the rules.
    """
    notes: list[str] = []

    def note(message: str) -> None:
        notes.append(message)
        (warn or _default_warn)(message)

    data = [load_obj(p) for p in objs]
    library = _read_materials(data, [str(p) for p in mtls], note)
    table_rows, obj_rows = _assign_rows(data, library, note)
    textures = _TextureCache()
    scene = Scene(
        meshes=[_mesh(d, rows, note) for d, rows in zip(data, obj_rows) if len(d.faces)],
        spheres=np.concatenate([d.spheres for d in data]) if data else np.zeros((0, 4), np.float32),
        sphere_material=np.concatenate([rows[d.sphere_material] for d, rows in zip(data, obj_rows)]
                                       ).astype(np.int32) if data else np.zeros(0, np.int32),
        materials=_table(table_rows, textures),
        textures=textures.images,
        procedural=textures.procedural,
        warnings=notes,
        dropped_degenerate=sum(d.dropped_degenerate for d in data),
    )
    for d in data:
        if d.dropped_degenerate:
            note(f"{d.path}: dropped {d.dropped_degenerate} zero-area triangles")
    validate_scene(scene)
    return scene


def _read_materials(data: list[ObjData], mtls: list[str], note: WarnFn) -> dict[str, Material]:
    """{name: Material}: existing mtllib files first, then the explicit files (which win)."""
    library: dict[str, Material] = {}
    seen: set[str] = set()
    for d in data:
        for lib in d.mtllibs:
            if lib in seen:
                continue
            seen.add(lib)
            if Path(lib).is_file():
                library.update(load_mtl(lib))
            else:
                note(f"{d.path}: mtllib {lib} not found; its materials are not loaded")
    for path in mtls:
        library.update(load_mtl(path))
    if CHECKER_NAME in library:
        m = library.pop(CHECKER_NAME)
        note(f"{m.source}:{m.line}: {CHECKER_NAME} is the built-in material; this definition is ignored")
    return library


def _assign_rows(data: list[ObjData], library: dict[str, Material], note: WarnFn
                 ) -> tuple[list[Material], list[np.ndarray]]:
    """Table rows (checker first, then used materials) and, per OBJ, its material index -> row."""
    rows: list[Material] = [builtin_checker()]
    row_of: dict[str, int] = {CHECKER_NAME: 0}
    warned: set[str] = set()
    obj_rows = []
    for d in data:
        used = set(np.unique(d.face_material).tolist()) | set(np.unique(d.sphere_material).tolist())
        mapping = np.zeros(len(d.material_names), dtype=np.int32)
        for k, (name, line) in enumerate(zip(d.material_names, d.material_lines)):
            if name not in library and name != CHECKER_NAME:
                if name not in warned:
                    warned.add(name)
                    note(f"{d.path}:{line}: unknown material {name!r}; using {CHECKER_NAME}")
            elif k in used and name not in row_of:
                row_of[name] = len(rows)
                rows.append(library[name])
            mapping[k] = row_of.get(name, 0)
        obj_rows.append(mapping)
    return rows, obj_rows


def _mesh(d: ObjData, rows: np.ndarray, note: WarnFn) -> MeshData:
    """One OBJ's triangles with per-corner uv and normals."""
    f = len(d.faces)
    uv = np.zeros((f, 3, 2), np.float32)
    has_t = d.face_texcoords >= 0
    uv[has_t] = d.texcoords[d.face_texcoords[has_t]]
    return MeshData(
        name=Path(d.path).name,
        positions=d.positions,
        indices=d.faces,
        corner_uv=uv,
        corner_normal=_corner_normals(d, note),
        face_material=rows[d.face_material].astype(np.int32),
    )


def _corner_normals(d: ObjData, note: WarnFn) -> np.ndarray | None:
    """Unit per-corner normals, or None when no corner names a ``vn``.

    A corner without a normal, or whose ``vn`` has zero length, takes the face's geometric normal
    (cross(p1 - p0, p2 - p0), normalised; faces of zero area were dropped by the reader).
    """
    has_n = d.face_normals >= 0
    if not has_n.any():
        return None
    p = d.positions.astype(np.float64)[d.faces]
    geo = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    geo /= np.linalg.norm(geo, axis=1, keepdims=True)
    out = np.repeat(geo[:, None, :], 3, axis=1)
    given = d.normals.astype(np.float64)[d.face_normals[has_n]]
    length = np.linalg.norm(given, axis=1)
    ok = length > 0
    zero = int(np.count_nonzero(~ok))
    if zero:
        note(f"{d.path}: {zero} face corners name a zero-length normal; using the face normal")
    idx = np.argwhere(has_n)[ok]
    out[idx[:, 0], idx[:, 1]] = given[ok] / length[ok, None]
    return out.astype(np.float32)


class _TextureCache:
    """Images read once per resolved path, in the order first needed."""

    def __init__(self) -> None:
        self.images: list[np.ndarray] = []
        self._index: dict[str, int] = {}
        self.procedural: list = []          # procedural instances (warp_spt.proctex.ProcRef)

    def index(self, ref: TextureRef) -> int:
        if not isinstance(ref, TextureRef):             # a proctex.ProcRef: one instance per (name, params)
            if ref not in self.procedural:
                self.procedural.append(ref)
            return TEX_PROC_BASE - self.procedural.index(ref)
        path = _find_texture(ref)
        if path not in self._index:
            self._index[path] = len(self.images)
            self.images.append(_read_image(path, ref))
        return self._index[path]


def _find_texture(ref: TextureRef) -> str:
    """The first existing candidate: relative to the MTL's folder, then to the working directory."""
    name = ref.path.replace("\\", "/")
    candidates = [Path(name)] if Path(name).is_absolute() else [Path(ref.mtl_file).parent / name, Path.cwd() / name]
    for c in candidates:
        if c.is_file():
            return str(c.resolve())
    tried = ", ".join(str(c) for c in candidates)
    raise SceneError(ref.mtl_file, ref.line, f"texture {ref.path!r} not found (tried {tried})")


def _read_image(path: str, ref: TextureRef) -> np.ndarray:
    """(H, W, 3) float32 in [0, 1], row 0 at the top."""
    try:
        with Image.open(path) as img:
            rgb = np.asarray(img.convert("RGB"), dtype=np.float32)
    except (OSError, ValueError, Image.DecompressionBombError) as err:
        raise SceneError(ref.mtl_file, ref.line, f"cannot read texture {path}: {err}") from None
    return rgb / np.float32(255.0)


def _table(rows: list[Material], textures: _TextureCache) -> MaterialTable:
    """The structure-of-arrays table, reading the textures of its rows."""
    tex = np.full((len(rows), 4), TEX_NONE, dtype=np.int32)
    for r, m in enumerate(rows):
        if m.checker:
            tex[r, SLOT_DIFFUSE] = tex[r, SLOT_REFLECT] = TEX_CHECKER
        for slot, field in _SLOT_FIELDS:
            ref = getattr(m, field)
            if ref is not None:
                tex[r, slot] = textures.index(ref)

    def col(name: str, dtype: type = np.float32) -> np.ndarray:
        return np.asarray([getattr(m, name) for m in rows], dtype=dtype)

    return MaterialTable(
        names=[m.name for m in rows],
        diffuse=col("diffuse").reshape(-1, 3), reflect=col("reflect").reshape(-1, 3),
        refract=col("refract").reshape(-1, 3), emission=col("emission").reshape(-1, 3),
        tex=tex, roughness=col("roughness"), fuzz=col("fuzz"), ior=col("ior"),
        refractable=col("refractable", np.bool_),
    )
