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
8-bit value / 255 or 16-bit value / 65535 (no sRGB decoding, alpha ignored, as the seed), row 0 =
the image's top row. Every texture, and the atlas they share, must fit the texel budget
(:data:`warp_spt.scene.atlas_layout.TEXEL_BUDGET`).
A texture path is tried relative to its MTL file's folder, then to the working directory;
``\\`` is read as ``/``.

The default material (faces and spheres before any ``usemtl``, table row 0) is the seed's
``Inner_CheckerTexture`` or a neutral grey clay, chosen by ``default_material``: ``"checker"`` (the
API's default, the seed's), ``"clay"``, or ``"auto"`` (the CLI's default): checker when a material
library was read (an MTL file given, or an OBJ's ``mtllib`` found), as in every seed scene; clay for
a bare model, also one whose ``usemtl`` names resolve nowhere. Row 0 keeps its reserved name either way.

The scene records where it came from (:attr:`Scene.seed_dialect`: an OBJ has the seed's spheres or
an MTL file read uses the seed's own tags; :attr:`Scene.bare`: no material library was read), for
the command line's conventions (:mod:`warp_spt.scene.conventions`).

Zero-area triangles (every UV sphere's poles have them) are dropped and counted in
:attr:`Scene.dropped_degenerate`, without a warning.

Warnings go to ``Scene.warnings`` and to the ``warn`` callback (by default
``warnings.warn(message, UserWarning)``; pass ``warn=lambda message: None`` to only collect them).
"""

from __future__ import annotations

import os
import warnings as _warnings
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterable

import numpy as np

from warp_spt.io.mtl import builtin_checker, builtin_clay, load_mtl
from warp_spt.io.paths import confine
from warp_spt.io.tokens import file_problem
from warp_spt.runtime.memory import map_large_allocations
from warp_spt.scene.atlas_layout import TEXEL_BUDGET, atlas_problem
from warp_spt.scene.errors import SceneError
from warp_spt.scene.media import open_boundary_warnings
from warp_spt.scene.normals import DEFAULT_SMOOTH_ANGLE, check_smooth_angle, smooth_normals
from warp_spt.scene.model import (
    CHECKER_NAME,
    TEX_PROC_BASE,
    Material,
    MaterialTable,
    MeshData,
    ObjData,
    Scene,
    TextureRef,
)
from warp_spt.scene.validate import validate_scene

if TYPE_CHECKING:
    from PIL import Image

__all__ = ["load_scene", "validate_scene"]

WarnFn = Callable[[str], None]
PathLike = str | os.PathLike[str]


def _default_warn(message: str) -> None:
    _warnings.warn(message, UserWarning, stacklevel=3)


DEFAULT_MATERIALS = ("checker", "clay", "auto")


def load_scene(objs: Iterable[PathLike | ObjData], mtls: Iterable[PathLike] = (), *, warn: WarnFn | None = None,
               default_material: str = "checker", smooth_angle: float | str | None = None,
               hidden_ok: bool = False) -> Scene:
    """Read OBJ files (one object each) and MTL files into a validated :class:`Scene`.

    An item of ``objs`` may also be an already parsed :class:`ObjData` (animations re-use static files).

    ``smooth_angle`` (degrees, :mod:`warp_spt.scene.normals`) gives an OBJ without any ``vn``
    smooth normals by angle; ``"auto"`` (the command line's default) is 30 degrees unless the scene
    is in the seed's dialect; None or 0: flat, as the seed.

    Raises :class:`SceneError` (file, line, what was expected) for unreadable or bad input,
    including a scene with no triangles and no spheres. With ``hidden_ok`` (an animation's frame), a
    scene whose every mesh placement is scaled to nothing is a :attr:`Scene.hidden` scene instead,
    rendered empty. See the module docs for the rules.
    """
    for what, given in (("objs", objs), ("mtls", mtls)):
        if isinstance(given, (str, bytes, os.PathLike)):      # iterated, a path is its characters
            raise TypeError(f"{what} must be a list of files, got one {type(given).__name__}: [{str(given)!r}]?")
    notes: list[str] = []

    def note(message: str) -> None:
        notes.append(message)
        (warn or _default_warn)(message)

    if default_material not in DEFAULT_MATERIALS:
        raise ValueError(f"default_material must be one of {DEFAULT_MATERIALS}, got {default_material!r}")
    auto_smooth = isinstance(smooth_angle, str) and smooth_angle == "auto"
    angle = DEFAULT_SMOOTH_ANGLE if auto_smooth else check_smooth_angle(smooth_angle)
    mtls = [str(p) for p in mtls]
    map_large_allocations()        # a large model's freed temporaries go back to the system
    data = [p if isinstance(p, ObjData) else read_model(p) for p in objs]   # parsed ones: OBJ sequences
    hidden = _require_geometry(data, hidden_ok)
    for d in data:
        for message in d.warnings:
            note(message)
    library, libraries_read = _read_materials(data, mtls, note)
    # an OBJ's spheres are the seed's ('b' lines); a stage's or glTF's (extras set) are their own
    seed_dialect = any(len(d.spheres) and d.extras is None for d in data) or any(
        m.seed_dialect for m in library.values())
    if auto_smooth and seed_dialect:
        angle = None
    clay = default_material == "clay" or (default_material == "auto" and not libraries_read)
    table_rows, obj_rows = _assign_rows(data, library, note, builtin_clay() if clay else builtin_checker())
    textures = _TextureCache(note)
    table_rows = _normal_maps_named_bump(table_rows, textures, note)
    meshes, sources = [], []             # each mesh and the file it came from (named in its errors)
    for d, rows in zip(data, obj_rows):
        for m in _meshes(d, rows, note, angle):
            meshes.append(m)
            sources.append(d.path)
    scene = Scene(
        meshes=meshes,
        spheres=np.concatenate([d.spheres for d in data]) if data else np.zeros((0, 4), np.float64),
        sphere_material=np.concatenate([rows[d.sphere_material] for d, rows in zip(data, obj_rows)]
                                       ).astype(np.int32) if data else np.zeros(0, np.int32),
        materials=MaterialTable.from_rows(table_rows, textures.index),   # reads the rows' textures
        textures=textures.images,
        procedural=textures.procedural,
        warnings=notes,
        dropped_degenerate=sum(d.dropped_degenerate for d in data),
        seed_dialect=seed_dialect,
        bare=not libraries_read,
        formats=tuple(d.format for d in data if d.format),
        up_hint=next((d.up_hint for d in data if d.up_hint is not None), None),
        cameras=[c for d in data for c in getattr(d.extras, "cameras", ())],
        lights=[c.to_scene() for d in data for c in getattr(d.extras, "lights", ())],
        sky=next((d.extras.sky for d in data if getattr(d.extras, "sky", None) is not None), None),
        interiors={m.name: m.interior for m in table_rows if m.interior is not None},
        hidden=hidden,
    )
    try:
        validate_scene(scene)   # zero-area triangles dropped: counted, not news (a UV sphere's poles)
    except SceneError as err:   # a mesh's problem (a PLY's or glTF's edge too long): its file named
        k = _mesh_index(err.message)
        if k is None or k >= len(sources):
            raise
        raise SceneError(sources[k], 0, err.message.split(": ", 1)[-1]) from None
    for message in open_boundary_warnings(scene):
        note(message)
    return scene


# Model readers by suffix, as "module:function" imported on first use (a scene of OBJ files imports neither)
MODEL_READERS = {".obj": "warp_spt.io.obj:load_obj", ".ply": "warp_spt.io.ply:load_ply",
                 ".gltf": "warp_spt.gltf:load_gltf", ".glb": "warp_spt.gltf:load_gltf",
                 **{s: "warp_spt.usd:load_usd" for s in (".usd", ".usda", ".usdc", ".usdz")}}
# The formats as users name them (ObjData.format, the up-axis line), by the reader's suffix
FORMAT_NAMES = {".obj": "OBJ", ".ply": "PLY", ".gltf": "glTF", ".glb": "glTF",
                **{s: "USD" for s in (".usd", ".usda", ".usdc", ".usdz")}}
_HEADS = ((b"ply\n", ".ply"), (b"ply\r", ".ply"), (b"glTF", ".glb"), (b"#usda", ".usda"), (b"PXR-USDC", ".usdc"))


def read_model(path: PathLike, time: float | None = None) -> ObjData:
    """One model file (OBJ, PLY, glTF or GLB) as an :class:`ObjData`: the reader is chosen by the file's
    first bytes (a PLY, binary glTF or USD magic, a JSON object with an ``"asset"``), else by its suffix, else
    OBJ (whose reader names any other format it recognises). ``time`` (seconds) poses an animated glTF or USD."""
    import importlib

    path = str(path)
    kind = _kind_by_content(path) or Path(path).suffix.lower()
    module, function = MODEL_READERS.get(kind, MODEL_READERS[".obj"]).split(":")
    reader = getattr(importlib.import_module(module), function)
    data = reader(path) if time is None else reader(path, time=time)
    if not data.format:
        data.format = FORMAT_NAMES.get(kind, "OBJ")
    return data


def _kind_by_content(path: str) -> str | None:
    if file_problem(path) is not None:          # missing, a FIFO, a directory...: the reader says so
        return None
    try:
        with open(path, "rb") as f:
            head = f.read(4096)
    except OSError:
        return None
    kind = next((k for magic, k in _HEADS if head.startswith(magic)), None)
    if kind is None and head.lstrip(b" \t\r\n\xef\xbb\xbf").startswith(b"{") and b'"asset"' in head:
        kind = ".gltf"
    return kind


def _mesh_index(message: str) -> int | None:
    """k of a validation message about ``meshes[k] (NAME): ...``, or None."""
    if not message.startswith("meshes["):
        return None
    k = message[7:message.find("]")]
    return int(k) if k.isdigit() else None


def _require_geometry(data: list[ObjData], hidden_ok: bool = False) -> bool:
    """A scene with nothing to draw is an error that names every OBJ file and says why; with
    ``hidden_ok``, one that has nothing because its objects are scaled to nothing is hidden (True)."""
    if any(len(d.faces) or len(d.spheres) or _placed(d) for d in data):
        return False
    if hidden_ok and any(getattr(d.extras, "hidden", 0) for d in data):
        return True
    if not data:
        raise SceneError(None, 0, "the scene has no geometry: no OBJ files were given")
    reasons = []
    for d in data:
        if getattr(d.extras, "hidden", 0):
            why = f"its {d.extras.hidden} mesh placement(s) are scaled to nothing"
        elif d.dropped_degenerate:
            why = f"all {d.dropped_degenerate} triangles have zero area"
        elif len(d.positions) and Path(d.path).suffix.lower() in (".ply", ".gltf", ".glb", ".usd", ".usda", ".usdc", ".usdz"):
            why = f"{len(d.positions)} vertices but no faces"
        elif len(d.positions):
            why = f"{len(d.positions)} 'v' lines but no faces ('f') or spheres ('b')"
        else:
            why = "no 'v', 'f' or 'b' lines (the file is empty or holds only comments and ignored statements)"
        reasons.append(f"{d.path}: {why}")
    raise SceneError(data[0].path, 0, "the scene has no geometry: " + "; ".join(
        [reasons[0].split(": ", 1)[1]] + reasons[1:]))


def _read_materials(data: list[ObjData], mtls: list[str], note: WarnFn) -> tuple[dict[str, Material], bool]:
    """({name: Material}, whether any library was read): existing mtllib files first, then the
    explicit files (which win)."""
    library: dict[str, Material] = {}
    seen: set[str] = set()
    read = bool(mtls)
    for d in data:
        for lib, line in zip(d.mtllibs, d.mtllib_lines or [0] * len(d.mtllibs)):
            if lib in seen:
                continue
            seen.add(lib)
            problem = file_problem(lib)
            if problem is None:
                library.update(load_mtl(lib, note))
                read = True
            else:
                where = f"{d.path}:{line}" if line else d.path
                why = "not found" if problem == "no such file or directory" else f"cannot be read ({problem})"
                note(f"{where}: mtllib {lib} {why}; its materials are not loaded")
    for d in data:
        if d.materials:
            library.update(d.materials)
            read = True
    for path in mtls:
        library.update(load_mtl(path, note))
    if CHECKER_NAME in library:
        m = library.pop(CHECKER_NAME)
        note(f"{m.source}:{m.line}: {CHECKER_NAME} is the built-in material; this definition is ignored")
    return library, read


def _assign_rows(data: list[ObjData], library: dict[str, Material], note: WarnFn, default: Material
                 ) -> tuple[list[Material], list[np.ndarray]]:
    """Table rows (``default`` first, then used materials) and, per OBJ, its material index -> row."""
    rows: list[Material] = [default]
    what = "the default material (clay)" if not default.checker else CHECKER_NAME
    row_of: dict[str, int] = {CHECKER_NAME: 0}
    warned: set[str] = set()
    obj_rows = []
    for d in data:
        used = set(np.unique(d.face_material).tolist()) | set(np.unique(d.sphere_material).tolist())
        for sub, _ in _placed(d):           # instanced meshes share the model's material names
            used |= set(np.unique(sub.face_material).tolist())
        mapping = np.zeros(len(d.material_names), dtype=np.int32)
        for k, (name, line) in enumerate(zip(d.material_names, d.material_lines)):
            if name not in library and name != CHECKER_NAME:
                if name not in warned:
                    warned.add(name)
                    note(f"{d.path}:{line}: unknown material {name!r}; using {what}")
            elif k in used and name not in row_of:
                row_of[name] = len(rows)
                rows.append(library[name])
            mapping[k] = row_of.get(name, 0)
        obj_rows.append(mapping)
    return rows, obj_rows


def _placed(d: ObjData) -> list:
    """The (object-space ObjData, (I, 4, 4) transforms) a model keeps instanced (glTF: gltf.GltfExtras.placed)."""
    return list(getattr(d.extras, "placed", ()))


def _meshes(d: ObjData, rows: np.ndarray, note: WarnFn, smooth_angle: float | None) -> list[MeshData]:
    """A model's world-space triangles as one mesh, then each of its instanced meshes with its transforms."""
    out = [_mesh(d, rows, note, smooth_angle)] if len(d.faces) else []
    return out + [replace(_mesh(sub, rows, note, smooth_angle), transforms=xf) for sub, xf in _placed(d)]


def _mesh(d: ObjData, rows: np.ndarray, note: WarnFn, smooth_angle: float | None = None) -> MeshData:
    """One OBJ's triangles with per-corner uv and normals (smooth by angle when it has none)."""
    f = len(d.faces)
    uv = np.zeros((f, 3, 2), np.float32)
    has_t = d.face_texcoords >= 0
    uv[has_t] = d.texcoords[d.face_texcoords[has_t]]
    return MeshData(
        name=Path(d.path).name,
        positions=d.positions,
        indices=d.faces,
        corner_uv=uv,
        corner_normal=(smooth_normals(d.positions, d.faces, smooth_angle)
                       if smooth_angle and not (d.face_normals >= 0).any() else _corner_normals(d, note)),
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


def _normal_maps_named_bump(rows: list[Material], textures: "_TextureCache", note: WarnFn) -> list[Material]:
    """``rows`` with every bump map that is a tangent-space normal map (:func:`looks_like_normal_map`;
    Blender's OBJ exporter, and many others, write one under ``map_Bump``) moved to the normal-map
    slot, its ``-bm`` the strength; said once per file. A seed-kind material has no maps of either."""
    from warp_spt.scene.material_schema import KIND_SEED

    said: set[str] = set()
    out = []
    for m in rows:
        ref = m.bump_map
        if m.kind != KIND_SEED and isinstance(ref, TextureRef) and m.normal_map is None and textures.is_normal_map(ref):
            if ref.path not in said:
                said.add(ref.path)
                note(f"{ref.mtl_file}:{ref.line}: the bump map {ref.path} is a tangent-space normal map (RGB, blue "
                     "near 1, red and green about 0.5), as Blender's exporter writes under map_Bump; read as one")
            m = replace(m, normal_map=ref, normal=m.bump, bump_map=None, bump=1.0)
        out.append(m)
    return out


class _TextureCache:
    """Images read once per resolved path, in the order first needed, within the texel budget."""

    def __init__(self, note: WarnFn) -> None:
        self.images: list[np.ndarray] = []
        self.refs: list[TextureRef] = []
        self._index: dict[str, int] = {}
        self._note = note
        self.procedural: list = []          # procedural instances (warp_spt.scene.proctex_registry.ProcRef)
        self._peeked: dict[tuple[str, str], np.ndarray] = {}    # read by is_normal_map, not yet placed

    def index(self, ref: TextureRef, decode: str = "raw") -> int:
        """The texture's index, reading it (``decode``: ``scene.model.texture_decode``'s modes) the
        first time that file is needed in that mode."""
        if not isinstance(ref, TextureRef):             # a proctex.ProcRef: one instance per (name, params)
            if ref not in self.procedural:
                self.procedural.append(ref)
            return TEX_PROC_BASE - self.procedural.index(ref)
        path = _find_texture(ref) if ref.image is None else f"{ref.mtl_file}#{ref.path}"
        key = (path, decode)
        if key not in self._index:
            image = self._peeked.pop(key, None)
            if image is None:
                image = _read_image(path, ref, self._note, lambda w, h: self._check_atlas(ref, w, h), decode)
            self._index[key] = len(self.images)
            self.images.append(image)
            self.refs.append(ref)
        return self._index[key]

    def is_normal_map(self, ref: TextureRef) -> bool:
        """Whether the image ``ref`` names looks like a tangent-space normal map; read once (kept for its
        use as one), without a place in the atlas."""
        path = _find_texture(ref) if ref.image is None else f"{ref.mtl_file}#{ref.path}"
        if (path, "normal") in self._peeked:
            return True
        image = _read_image(path, ref, self._note, lambda w, h: self._check_atlas(ref, w, h), "linear")
        if looks_like_normal_map(image):
            self._peeked[(path, "normal")] = image
            return True
        return False

    def _check_atlas(self, ref: TextureRef, w: int, h: int) -> None:
        """All textures so far plus a new w x h one (from its header) must fit the texel budget."""
        names = [f"{r.path} ({r.mtl_file}:{r.line})" for r in [*self.refs, ref]]
        problem = atlas_problem([im.shape[:2] for im in self.images] + [(h, w)], names, TEXEL_BUDGET)
        if problem:
            raise SceneError(ref.mtl_file, ref.line, problem)


def _find_texture(ref: TextureRef) -> str:
    """The first existing candidate: relative to the MTL's folder, then to the working directory (the
    seed's maps are written relative to it), each inside its folder (:mod:`warp_spt.io.paths`)."""
    candidates, refused = confine(ref.path, Path(ref.mtl_file).parent, "texture", also=(Path.cwd(),))
    if refused:
        raise SceneError(ref.mtl_file, ref.line, refused)
    problems = []
    for c in candidates:
        problem = file_problem(c)
        if problem is None:
            return str(c.resolve())
        problems.append(f"{c}: {problem}")
    raise SceneError(ref.mtl_file, ref.line, f"texture {ref.path!r} cannot be read ({'; '.join(problems)})")


def _read_image(path: str, ref: TextureRef, note: WarnFn, check_atlas: Callable[[int, int], None],
                decode: str = "raw") -> np.ndarray:
    """(H, W, 3) float32 in [0, 1], row 0 at the top; 8-bit values / 255, 16-bit values / 65535;
    ``decode`` (``scene.model.texture_decode``): "srgb" turns the values into linear ones, "alpha"
    reads the image's alpha channel (its grey value if it has none) into all three channels.

    The size is checked against the texel budget from the header, before anything is decoded: alone,
    then with the textures read before it (``check_atlas(w, h)`` raises if they do not fit).
    Pillow's own warnings become one-line notes naming the MTL line; its decompression-bomb check is
    replaced by the budget.
    """
    if isinstance(ref.image, np.ndarray):          # baked in memory (vertex colours): linear, taken as it is
        h, w = ref.image.shape[:2]
        if w * h > TEXEL_BUDGET:
            raise SceneError(ref.mtl_file, ref.line, f"texture {ref.path} is {w}x{h} = {w * h:,} texels, more "
                             f"than the budget of {TEXEL_BUDGET:,} (8192x8192)")
        check_atlas(w, h)
        return ref.image
    # here: scenes without image textures need no Pillow (9 ms of every start)
    import io

    from PIL import Image

    source = None
    try:
        with _warnings.catch_warnings(record=True) as caught:
            _warnings.simplefilter("always")
            source = path if ref.image is None else io.BytesIO(ref.image)
            with Image.open(source) as img:
                w, h = img.size
                if w * h > TEXEL_BUDGET:
                    raise SceneError(ref.mtl_file, ref.line, f"texture {path} is {w}x{h} = {w * h:,} texels, more "
                                     f"than the budget of {TEXEL_BUDGET:,} (8192x8192); downsample it")
                check_atlas(w, h)
                rgb = _alpha(img) if decode == "alpha" else _to_rgb(img, srgb=decode == "srgb")
    except (OSError, ValueError, Image.DecompressionBombError) as err:
        if isinstance(err, SceneError):
            raise
        text = str(err)
        if ref.image is not None:    # Pillow names in-memory bytes by their repr (<_io.BytesIO object at 0x...>)
            text = text.replace(repr(source), "(its embedded bytes)")
        if ref.neutral:
            note(f"{ref.mtl_file}: cannot read texture {ref.path}: {text}; a neutral texel stands for it")
            return np.array([[[0.5, 0.5, 1.0] if decode == "normal" else [1.0, 1.0, 1.0]]], np.float32)
        raise SceneError(ref.mtl_file, ref.line, f"cannot read texture {path}: {text}") from None
    for w in caught:
        if not issubclass(w.category, Image.DecompressionBombWarning):
            note(f"{ref.mtl_file}:{ref.line}: texture {path}: {w.message}")
    if decode == "normal":
        _check_normal_map(rgb, path, ref)
    return rgb


# A tangent-space normal map stores z = 2 b - 1 well above 0 (a normal tilted less than 84 degrees: b > 0.55)
# in nearly every texel; a height, roughness or colour image given as one (mid-grey: b = 0.5) does not.
NORMAL_MAP_MIN_BLUE = 0.55
NORMAL_MAP_MIN_SHARE = 0.95


# A bump map that is in fact a normal map (looks_like_normal_map): besides the blue test above, the
# mean blue at least this, and red and green each within this of 0.5 on average (a normal map's
# tilts average out; a grey height map has r = g = b, so it cannot pass both).
NORMAL_MAP_MEAN_BLUE, NORMAL_MAP_RG_OFF = 0.75, 0.1


def looks_like_normal_map(rgb: np.ndarray) -> bool:
    """Whether ``rgb`` (linear values in [0, 1]) is a tangent-space normal map rather than a height map."""
    r, g, b = (float(rgb[..., k].mean()) for k in range(3))
    return (float((rgb[..., 2] > NORMAL_MAP_MIN_BLUE).mean()) >= NORMAL_MAP_MIN_SHARE and b >= NORMAL_MAP_MEAN_BLUE
            and abs(r - 0.5) <= NORMAL_MAP_RG_OFF and abs(g - 0.5) <= NORMAL_MAP_RG_OFF)


def _check_normal_map(rgb: np.ndarray, path: str, ref: TextureRef) -> None:
    """SceneError unless ``rgb`` looks like a tangent-space normal map (blue above 0.5 almost everywhere)."""
    share = float((rgb[..., 2] > NORMAL_MAP_MIN_BLUE).mean())
    if share < NORMAL_MAP_MIN_SHARE:
        raise SceneError(ref.mtl_file, ref.line, f"texture {path} is not a tangent-space normal map: its blue "
                         f"channel (the normal's z, 2b - 1) is above {NORMAL_MAP_MIN_BLUE:g} in {share:.0%} of its "
                         f"texels, expected at least {NORMAL_MAP_MIN_SHARE:.0%} (a height map belongs in 'bump')")


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB transfer function inverted (IEC 61966-2-1), float32 in [0, 1]."""
    c = np.asarray(c, dtype=np.float32)
    return np.where(c <= 0.04045, c / np.float32(12.92),
                    ((c + np.float32(0.055)) / np.float32(1.055)) ** np.float32(2.4)).astype(np.float32)


# The peak memory of reading an 8-bit texture, in bytes a texel, the float32 RGB result's 12 included
# (tests/hardening/test_reader_memory.py measures load_scene's peak RSS for 2 million texels: 21)
TEXTURE_READ_BYTES_PER_TEXEL = 24
_LINEAR_8BIT = np.arange(256, dtype=np.float32) / np.float32(255.0)
_SRGB_8BIT = srgb_to_linear(_LINEAR_8BIT)


def _alpha(img: "Image.Image") -> np.ndarray:
    """The image's alpha channel as grey RGB in [0, 1], or its grey value where it has no alpha."""
    if "A" in img.getbands():
        a = np.asarray(img.getchannel("A"), dtype=np.float32) / np.float32(255.0)
        return np.repeat(a[:, :, None], 3, axis=2)
    grey = _to_rgb(img).mean(axis=2, keepdims=True)
    return np.repeat(grey, 3, axis=2).astype(np.float32)


def _to_rgb(img: "Image.Image", srgb: bool = False) -> np.ndarray:
    """Float32 RGB in [0, 1]: 16-bit and 32-bit integer grey scaled by 65535, float grey clipped;
    ``srgb``: turned into linear values. 8-bit images go through a table of their 256 values (the
    same float32 arithmetic, value by value), so the peak is the decoded image, its uint8 RGB and the
    result: float32 temporaries of the whole image took a texture's peak to 58 bytes a texel."""
    if img.mode.startswith("I;16") or img.mode == "I":
        grey = np.clip(np.asarray(img, dtype=np.float64) / 65535.0, 0.0, 1.0).astype(np.float32)
        rgb = np.repeat(grey[:, :, None], 3, axis=2)
    elif img.mode == "F":
        grey = np.clip(np.nan_to_num(np.asarray(img, dtype=np.float32)), 0.0, 1.0)
        rgb = np.repeat(grey[:, :, None], 3, axis=2)
    else:
        rgb8 = img if img.mode == "RGB" else img.convert("RGB")
        return (_SRGB_8BIT if srgb else _LINEAR_8BIT)[np.asarray(rgb8)]
    return srgb_to_linear(rgb) if srgb else rgb

