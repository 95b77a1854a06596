"""Host-side scene: plain numpy arrays, validated, ready to be uploaded by the engine.

Data flows one way: ``obj``/``mtl`` parse text into :class:`ObjData` and :class:`Material`;
:func:`load_scene` resolves materials and textures and assembles a :class:`Scene`; the engine
(``warp_spt.upload.device_scene``) turns a Scene into Warp meshes, a top-level BVH and a texture atlas.
Nothing in this module imports Warp.
"""

from __future__ import annotations

from dataclasses import dataclass, field, make_dataclass, replace
from typing import Callable, Iterator

import numpy as np

from warp_spt.scene.sky import Sky
from warp_spt.scene.material_schema import (
    COLOR,
    COLUMN,
    COLUMNS,
    FLAG,
    INDEX,
    NUM_SLOTS,
    SCALAR,
    SLOT_COLUMNS,
    SLOTS,
    host_dtype,
    row_shape,
)

# Texture slot values in MaterialTable.tex: an index >= 0 names Scene.textures[k].
TEX_NONE = -1      # use the constant colour
TEX_CHECKER = -2   # the built-in Inner_CheckerTexture pattern (SEMANTICS §10)
TEX_PROC_BASE = -3  # -3 - k: procedural texture instance k (Scene.procedural, warp_spt.device.proctex)

# Columns of MaterialTable.tex (the texture slots of the schema's colours)
SLOT_DIFFUSE, SLOT_REFLECT, SLOT_REFRACT, SLOT_EMISSION = (
    COLUMN[n].slot for n in ("diffuse", "reflect", "refract", "emission"))

CHECKER_NAME = "Inner_CheckerTexture"


@dataclass
class TextureRef:
    """A texture path as written in an MTL file, with where it was written (for errors).

    ``image``, when given, is the texture itself: an encoded image file's bytes (a glTF's embedded
    PNG or JPEG) or an (H, W, 3) float32 array in [0, 1] (a PLY's baked vertex colours); ``path`` then
    only names it (it must be unique: the loader reads each name once). A baked array holds linear
    values: the loader takes it as it is, whatever its slot's decoding. ``neutral``: an image that
    cannot be decoded is a warning and one neutral texel (white; a flat normal), as glTF viewers draw
    a file whose texture is broken, instead of an error."""

    path: str
    mtl_file: str
    line: int
    image: bytes | np.ndarray | None = field(default=None, compare=False, repr=False)
    neutral: bool = field(default=False, compare=False)


def _material_fields() -> list[tuple]:
    """Material's fields from the schema: the name, the colours, their texture maps, the other columns."""
    types = {COLOR: "tuple[float, float, float]", SCALAR: "float", FLAG: "bool", INDEX: "int"}
    return ([("name", "str")]
            + [(c.name, types[c.type], field(default=c.default)) for c in COLUMNS if c.type == COLOR]
            + [(f"{c.name}_map", "TextureRef | None", field(default=None)) for c in SLOT_COLUMNS]
            + [(c.name, types[c.type], field(default=c.default)) for c in COLUMNS if c.type in (SCALAR, FLAG, INDEX)]
            + [("checker", "bool", field(default=False)),      # the checker pattern fills the Column.checker slots
               ("source", "str", field(default="<builtin>")),  # file that defined it
               ("seed_dialect", "bool", field(default=True)),  # its file uses the seed's own MTL tags
               ("line", "int", field(default=0)),              # line of its ``newmtl``
               ("interior", "object", field(default=None))])   # its interior Medium (load_scene: Scene.interiors)


# The pbr kind's defaults for Material.pbr: a grey dielectric of medium roughness, glass's IOR. (glTF's
# own defaults, metallic 1 and roughness 1, are the glTF reader's to apply.)
PBR_DEFAULTS = {"base_color": (0.8, 0.8, 0.8), "metallic": 0.0, "roughness": 0.5, "ior": 1.5,
                "specular": 1.0, "specular_color": (1.0, 1.0, 1.0), "transmission": 0.0, "seed_dialect": False}


class MaterialValueError(ValueError):
    """A field of ``Material.pbr`` of the wrong shape or out of its range: ``problem`` names the field,
    so a reader can say which file and place the material came from."""

    def __init__(self, name: str, problem: str):
        self.name, self.problem = name, problem
        super().__init__(f"Material.pbr({name!r}): {problem}")


def _pbr(cls, name: str, **fields) -> "Material":
    """A material of the physically based kind (``kind`` = KIND_PBR) with :data:`PBR_DEFAULTS` for the
    fields not given (docs/materials.md: base_color, metallic, roughness, anisotropy, ior, specular,
    transmission, thin, emission, normal/bump/opacity maps, ...)."""
    from warp_spt.scene.material_schema import COLUMN, KIND_PBR, SLOTS, material_problem, row_shape

    for key, value in fields.items():       # each field's shape, then its range, by name
        c = COLUMN.get(key)
        if c is None or c.type == SLOTS:
            continue
        shape = row_shape(c)
        try:
            ok = np.shape(np.asarray(value, dtype=np.float64)) == shape
        except (TypeError, ValueError):
            ok = False
        if not ok:
            what = f"{shape[0]} numbers" if shape else "a number"
            raise MaterialValueError(name, f"{key} must be {what}, got {value!r:.60}")
    material = cls(name=name, **{**PBR_DEFAULTS, **fields, "kind": KIND_PBR})
    problem = material_problem(material)
    if problem:
        raise MaterialValueError(name, problem)
    return material


Material = make_dataclass("Material", _material_fields(), namespace={"__module__": __name__, "pbr": classmethod(_pbr),
                                                                     "__doc__": """\
One material row (the seed's model, SEMANTICS §6, unless ``kind`` names another), before textures are
loaded. ``Material.pbr(name, **fields)`` makes one of the physically based kind.

Its fields and defaults come from the material schema (``warp_spt.scene.material_schema``): a
field per column (``roughness`` is the probability of the diffuse lobe, the seed's diffuseWeight;
``fuzz`` is 1 - reflectClearness; ``ior`` is the seed's ``Kn``), ``<colour>_map`` (a
:class:`TextureRef` or a procedural texture) for each colour with a texture slot, and ``checker``
(the built-in checker pattern), ``source`` and ``line`` (where it was defined) and
``seed_dialect`` (its file uses the seed's own MTL tags; see :mod:`warp_spt.io.mtl`).
"""})


@dataclass
class ObjData:
    """One parsed OBJ file: a single object of the scene. All indices are 0-based and validated."""

    path: str
    positions: np.ndarray        # (V, 3) float64 as written (rounded to float32 once, at upload)
    texcoords: np.ndarray        # (T, 2) float32 (u, v); a third vt component is dropped
    normals: np.ndarray          # (N, 3) float32
    faces: np.ndarray            # (F, 3) int32 into positions (polygons already triangulated)
    face_texcoords: np.ndarray   # (F, 3) int32 into texcoords, -1 where the corner has none
    face_normals: np.ndarray     # (F, 3) int32 into normals, -1 where the corner has none
    face_material: np.ndarray    # (F,) int32 into material_names
    spheres: np.ndarray          # (S, 4) float64 as written: cx, cy, cz, r (r > 0)
    sphere_material: np.ndarray  # (S,) int32 into material_names
    material_names: list[str]    # names used by usemtl; index 0 is always CHECKER_NAME (the default)
    material_lines: list[int]    # line of the first usemtl naming each entry (0 for the default)
    mtllibs: list[str] = field(default_factory=list)  # mtllib paths resolved relative to the OBJ
    mtllib_lines: list[int] = field(default_factory=list)  # the line naming each of them
    dropped_degenerate: int = 0  # zero-area triangles dropped while parsing
    # materials the file defines itself (PLY vertex colours, glTF), by name; an MTL of the same name wins
    materials: dict[str, Material] = field(default_factory=dict)
    extras: object = None        # what else the format holds (glTF: gltf.GltfExtras, cameras and lights)
    warnings: list[str] = field(default_factory=list)   # the reader's notes; the loader passes them on
    # the file's format as users name it ("OBJ", "PLY", "glTF", "USD"; set by its reader, or by
    # io.loader.read_model), and an up axis the file itself states with what states it, e.g.
    # ("z", "written by Blender") from a PLY header (scene.conventions.up_axis)
    format: str = ""
    up_hint: tuple[str, str] | None = None


@dataclass
class MeshData:
    """The triangles of one OBJ file, in world space, ready for one ``wp.Mesh``; or, with
    ``transforms``, a mesh in its own object space placed once per transform (instances: uploaded once,
    docs/formats.md "Instances")."""

    name: str
    positions: np.ndarray       # (V, 3) float64 (or float32), world space; see Scene.rounded
    indices: np.ndarray         # (F, 3) int32
    corner_uv: np.ndarray       # (F, 3, 2) float32, zeros where the OBJ gave none
    corner_normal: np.ndarray | None  # (F, 3, 3) float32 unit vectors, or None: flat shading
    face_material: np.ndarray   # (F,) int32 into Scene.materials
    # (I, 4, 4) float64 object-to-world affine maps, one per instance (invertible linear part); None:
    # the positions are world space (one placement, no transform)
    transforms: np.ndarray | None = None
    # a stage prop (the studio's ground): drawn and lit, but not the subject: left out of the bounds
    # that weigh the sky's light selection (a ground 30 times the model's size made a user's point
    # light one pick in a hundred, and a fog lit by it black at low spp)
    prop: bool = False

    def world_bounds(self, rounded: bool = True) -> tuple[np.ndarray, np.ndarray] | None:
        """(lower, upper) float64 bounds of the used vertices in world space, every placement
        included (``rounded``: of the positions rounded to float32, as the engine stores them); None
        for a mesh without triangles."""
        b = self.placement_bounds(rounded)
        return None if b is None else (b[:, 0].min(0), b[:, 1].max(0))

    def placement_bounds(self, rounded: bool = True) -> np.ndarray | None:
        """(I, 2, 3) float64: each placement's world bounds (one row without transforms), or None for
        a mesh without triangles. From one matrix product per batch of placements (each placement's
        rows against every used vertex), not from copies."""
        if not len(self.indices):
            return None
        mask = np.zeros(len(self.positions), dtype=bool)
        mask[self.indices.reshape(-1)] = True          # O(F), unlike np.unique's sort
        used = self.positions if mask.all() else self.positions[mask]
        if self.transforms is None:
            # rounding to float32 is monotonic: the rounded extremes are the extremes' rounding
            b = np.stack(column_range(used))[None]
            return _as_float32(b) if rounded else b.astype(np.float64)
        used = _as_float32(used) if rounded else used.astype(np.float64)
        out = np.empty((len(self.transforms), 2, 3))
        batch = max(1, (1 << 22) // (3 * len(used)))          # at most ~32 MB of projections at a time
        for k in range(0, len(self.transforms), batch):
            x = self.transforms[k:k + batch]
            proj = used @ x[:, :3, :3].reshape(-1, 3).T            # (V, 3 * batch): row r of placement j
            out[k:k + batch, 0] = proj.min(0).reshape(-1, 3) + x[:, :3, 3]
            out[k:k + batch, 1] = proj.max(0).reshape(-1, 3) + x[:, :3, 3]
        return out

    def world_part(self, k: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """(positions, triangles) of placement ``k`` in world space, positions only (no per-corner
        data): what host-side geometry cues read. A mirroring placement reverses the winding."""
        if self.transforms is None:
            return self.positions, self.indices
        x = self.transforms[k]
        tri = self.indices[:, ::-1] if np.linalg.det(x[:3, :3]) < 0 else self.indices
        return np.asarray(self.positions, dtype=np.float64) @ x[:3, :3].T + x[:3, 3], tri

    @property
    def placements(self) -> int:
        """How many times the mesh is placed (1 without transforms)."""
        return 1 if self.transforms is None else len(self.transforms)

    def placed(self) -> Iterator["MeshData"]:
        """This mesh as world-space copies, one per placement (itself when it has no transforms).
        Host-side geometry code (bounds, framing cues) walks these; a copy holds its own positions
        only, so at most one instance's positions exist at a time."""
        if self.transforms is None:
            yield self
            return
        p = np.asarray(self.positions, dtype=np.float64)
        for x in self.transforms:
            linear = x[:3, :3]
            normals = self.corner_normal
            if normals is not None:           # normals map by A^-T (as row vectors: n @ A^-1)
                n = normals.astype(np.float64) @ np.linalg.inv(linear)
                normals = (n / np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-300)).astype(np.float32)
            tri, uv = self.indices, self.corner_uv
            if np.linalg.det(linear) < 0:
                # a mirroring transform reverses the winding, so that the winding normal stays A^-T n;
                # the per-corner data follows its corners
                tri, uv = tri[:, ::-1].copy(), uv[:, ::-1].copy()
                normals = None if normals is None else normals[:, ::-1].copy()
            yield replace(self, positions=p @ linear.T + x[:3, 3], indices=tri, corner_uv=uv, corner_normal=normals,
                          transforms=None)


def _table_post_init(self) -> None:
    for c in COLUMNS:
        if getattr(self, c.name) is None:
            setattr(self, c.name, _default_column(c, len(self.names)))


def _default_column(c, rows: int) -> np.ndarray:
    """The column's array with its default in every row."""
    if c.type == SLOTS:
        return np.full((rows, NUM_SLOTS), TEX_NONE, dtype=np.int32)
    return np.tile(np.asarray(c.default, dtype=host_dtype(c)), (rows,) + (1,) * len(row_shape(c)))


def _from_rows(cls, rows: list, texture_index: Callable[[object], int] | None = None) -> "MaterialTable":
    """The table of ``rows`` (Materials); ``texture_index(ref)`` gives the slot value of a texture map
    (the loader's texture cache; needed only when some row has a map)."""
    columns = {}
    for c in COLUMNS:
        if c.type == SLOTS:
            columns[c.name] = _slots(rows, texture_index)
        else:
            columns[c.name] = np.asarray([getattr(m, c.name) for m in rows],
                                         dtype=host_dtype(c)).reshape((len(rows),) + row_shape(c))
    return cls(names=[m.name for m in rows], **columns)


def _slots(rows: list, texture_index: Callable[[object, str], int] | None) -> np.ndarray:
    """(M, NUM_SLOTS) int32: the checker in the checker slots of checker materials, then each map,
    read by ``texture_index(ref, decode)`` as :func:`texture_decode` says."""
    tex = np.full((len(rows), NUM_SLOTS), TEX_NONE, dtype=np.int32)
    for r, m in enumerate(rows):
        if m.checker:
            tex[r, [c.slot for c in SLOT_COLUMNS if c.checker]] = TEX_CHECKER
        for c in SLOT_COLUMNS:
            ref = getattr(m, f"{c.name}_map")
            if ref is not None:
                tex[r, c.slot] = texture_index(ref, texture_decode(m, c.name))
    return tex


def texture_decode(m, column: str) -> str:
    """How material ``m``'s map of ``column`` is read into linear values: ``"raw"`` (the seed's kind
    keeps its maps' values as stored, SEMANTICS Q18), ``"srgb"`` (a colour map of another kind:
    decoded from sRGB), ``"alpha"`` (an opacity map: its alpha channel, else its grey value) or
    ``"linear"`` (a data map: roughness, metallic, bump), ``"normal"`` (a tangent-space normal map:
    linear, checked to be one)."""
    from warp_spt.scene.material_schema import COLUMN, KIND_SEED, NORMAL_MAPS
    if m.kind == KIND_SEED:
        return "raw"
    if column == "opacity":
        return "alpha"
    if column in NORMAL_MAPS:
        return "normal"
    return "srgb" if COLUMN[column].srgb else "linear"


def _with_rows(self, rows: list) -> "MaterialTable":
    """This table followed by ``rows`` (Materials without texture maps)."""
    more = MaterialTable.from_rows(rows)
    return MaterialTable(names=[*self.names, *more.names],
                         **{c.name: np.concatenate([getattr(self, c.name), getattr(more, c.name)]) for c in COLUMNS})


MaterialTable = make_dataclass(
    "MaterialTable", [("names", "list[str]")] + [(c.name, "np.ndarray", field(default=None)) for c in COLUMNS],
    namespace={"__module__": __name__, "__post_init__": _table_post_init, "__len__": lambda self: len(self.names),
               "from_rows": classmethod(_from_rows), "with_rows": _with_rows, "__doc__": """\
Materials as structure-of-arrays, one array per schema column; row 0 is always Inner_CheckerTexture.

Column ``name`` is an array of ``material_schema.host_dtype`` with rows of ``row_shape``: colours
(M, 3) float32, scalars (M,) float32, flags (M,) bool, ``tex`` (M, NUM_SLOTS) int32 per slot
(SLOT_*): TEX_NONE, TEX_CHECKER, a texture index or a procedural instance. A column not given
takes its default in every row. ``MaterialTable.from_rows(materials, texture_index)`` assembles one.
"""})


@dataclass
class Scene:
    """Everything the engine needs, as validated numpy arrays."""

    meshes: list[MeshData]
    spheres: np.ndarray          # (S, 4) float64 (or float32); see Scene.rounded
    sphere_material: np.ndarray  # (S,) int32 into materials
    materials: MaterialTable
    textures: list[np.ndarray]   # each (H, W, 3) float32 in [0, 1]; row 0 is the image's top row
    warnings: list[str] = field(default_factory=list)
    dropped_degenerate: int = 0
    # procedural texture instances (warp_spt.scene.proctex_registry.ProcRef); slot value TEX_PROC_BASE - k names k
    procedural: list = field(default_factory=list)
    # Where it came from (the CLI's conventions, warp_spt.scene.conventions): written in the seed's
    # dialect (its spheres or MTL tags), and bare (no material library read: every face has the
    # default material). Scenes built in code count as the seed's and not bare.
    seed_dialect: bool = True
    bare: bool = False
    # the model files' formats in file order (ObjData.format; empty for a scene built in code) and the
    # first up axis a file states (ObjData.up_hint): what the up-axis rule reads besides the geometry
    formats: tuple[str, ...] = ()
    up_hint: tuple[str, str] | None = None
    # cameras and lights the model files define (glTF: gltf.GltfCamera, GltfLight), in file order
    cameras: list = field(default_factory=list)
    lights: list = field(default_factory=list)
    # participating media (warp_spt.scene.media.Medium, docs/volumes.md): the scene-wide medium the
    # camera starts in, and the interior medium of the closed meshes of a material, by material name
    fog: object = None
    interiors: dict = field(default_factory=dict)
    # the scene's infinite light (warp_spt.scene.sky.Sky: a constant, the gradient, an environment
    # map), uploaded and shipped to cluster workers with the scene; None: the seed's blue BlackSky.
    # RenderSettings.sky, when given, overrides it.
    sky: Sky | None = None
    # every object is hidden (an animation's frame that scales them all to nothing): the scene may hold
    # no geometry at all, and renders empty (every ray misses); otherwise that is an error
    hidden: bool = False

    @classmethod
    def empty(cls, row0: Material) -> "Scene":
        """A scene of nothing yet, to add to (a volume alone: ``warp_spt.add_volume``); ``row0``: the
        table's reserved first row (``io.mtl.builtin_clay()`` or ``builtin_checker()``)."""
        if row0.name != CHECKER_NAME:
            raise ValueError(f"materials row 0 must be {CHECKER_NAME}, got {row0.name!r}")
        return cls(meshes=[], spheres=np.zeros((0, 4)), sphere_material=np.zeros(0, np.int32),
                   materials=MaterialTable.from_rows([row0]), textures=[], seed_dialect=False)

    def add_light(self, light) -> "Scene":
        """Add a sun, point or spot light (``warp_spt.SunLight``, ``PointLight``, ``SpotLight``, made
        with their parameters by name) and return the scene; before it is uploaded (a DeviceScene
        made earlier keeps the lights it had)."""
        from warp_spt.scene.lights import PUNCTUAL_TYPES

        if not isinstance(light, PUNCTUAL_TYPES):
            raise TypeError(f"add_light takes a SunLight, PointLight or SpotLight, got {light!r:.80}")
        self.lights.append(light)
        return self

    @property
    def num_triangles(self) -> int:
        return int(sum(len(m.indices) for m in self.meshes))

    @property
    def instanced(self) -> bool:
        """Some mesh is placed by transforms (MeshData.transforms)."""
        return any(m.transforms is not None for m in self.meshes)

    def placed_meshes(self) -> Iterator[MeshData]:
        """Every mesh in world space, instances as copies made one at a time (MeshData.placed)."""
        for m in self.meshes:
            yield from m.placed()

    def flattened(self) -> "Scene":
        """This scene with every instance copied into a world-space mesh of its own (what a renderer
        without instances would upload; the reference instancing is checked against)."""
        if not self.instanced:
            return self
        return replace(self, meshes=list(self.placed_meshes()))

    def rounded(self) -> "Scene":
        """This scene as the float32 engine sees it: positions and spheres rounded to float32.

        Positions stay float64 from the parser until the scene is recentred
        (:func:`warp_spt.scene.recentre.recentre`), so a scene far from the origin is shifted before
        anything is rounded; the upload (:class:`warp_spt.upload.device_scene.DeviceScene`) rounds once,
        here. Returns ``self`` when nothing needs rounding.
        """
        meshes = [m if m.positions.dtype == np.float32 else replace(m, positions=m.positions.astype(np.float32))
                  for m in self.meshes]
        spheres = self.spheres.astype(np.float32, copy=False)
        if spheres is self.spheres and all(a is b for a, b in zip(meshes, self.meshes)):
            return self
        return replace(self, meshes=meshes, spheres=spheres)

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float64 world bounds of all geometry as the engine sees it (float32 coordinates)."""
        return self._bounds(props=True)

    @property
    def subject_bounds(self) -> np.ndarray:
        """:attr:`bounds` without the stage props (``MeshData.prop``: the studio's ground)."""
        return self._bounds(props=False)

    def _bounds(self, props: bool) -> np.ndarray:
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for m in self.meshes:
            if m.prop and not props:
                continue
            b = m.world_bounds()
            if b is not None:
                lo = np.minimum(lo, b[0])
                hi = np.maximum(hi, b[1])
        if len(self.spheres):
            s = _as_float32(self.spheres)
            c, r = s[:, :3], s[:, 3:4]
            lo = np.minimum(lo, (c - r).min(0))
            hi = np.maximum(hi, (c + r).max(0))
        return np.stack([lo, hi])


def column_range(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) of each column of a non-empty (N, C) array, NaN propagating as in ``a.min(0)``.

    One column at a time: numpy reduces a C-ordered (N, 3) array along axis 0 row by row, about 30 ms
    for 500k float64 rows where a column's reduction takes under 1 ms."""
    lo = np.array([a[:, k].min() for k in range(a.shape[1])], dtype=a.dtype)
    hi = np.array([a[:, k].max() for k in range(a.shape[1])], dtype=a.dtype)
    return lo, hi


def _as_float32(a: np.ndarray) -> np.ndarray:
    """``a`` rounded to float32 (what the engine stores), as float64 for exact host arithmetic."""
    return a.astype(np.float32).astype(np.float64)
