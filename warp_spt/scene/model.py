"""Host-side scene: plain numpy arrays, validated, ready to be uploaded by the engine.

Data flows one way: ``obj``/``mtl`` parse text into :class:`ObjData` and :class:`Material`;
:func:`load_scene` resolves materials and textures and assembles a :class:`Scene`; the engine
(``warp_spt.core.device_scene``) turns a Scene into Warp meshes, a top-level BVH and a texture atlas.
Nothing in this module imports Warp.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

# Texture slot values in MaterialTable.tex: an index >= 0 names Scene.textures[k].
TEX_NONE = -1      # use the constant colour
TEX_CHECKER = -2   # the built-in Inner_CheckerTexture pattern (SEMANTICS §10)
TEX_PROC_BASE = -3  # -3 - k: procedural texture instance k (Scene.procedural, warp_spt.core.proctex)

# Column order of MaterialTable.tex
SLOT_DIFFUSE, SLOT_REFLECT, SLOT_REFRACT, SLOT_EMISSION = 0, 1, 2, 3

CHECKER_NAME = "Inner_CheckerTexture"


@dataclass
class TextureRef:
    """A texture path as written in an MTL file, with where it was written (for errors)."""

    path: str
    mtl_file: str
    line: int


@dataclass
class Material:
    """One material of the seed's model (SEMANTICS §6), before textures are loaded.

    ``roughness`` is the probability of the diffuse lobe (the seed's diffuseWeight);
    ``fuzz`` is 1 - reflectClearness; ``ior`` is the seed's ``Kn``.
    """

    name: str
    diffuse: tuple[float, float, float] = (0x9F / 256, 0x8F / 256, 0x7C / 256)
    reflect: tuple[float, float, float] = (0xAF / 256, 0xBF / 256, 0xCF / 256)
    refract: tuple[float, float, float] = (0xBB / 256, 0xBC / 256, 0xB1 / 256)
    emission: tuple[float, float, float] = (0.0, 0.0, 0.0)
    diffuse_map: TextureRef | None = None
    reflect_map: TextureRef | None = None
    refract_map: TextureRef | None = None
    emission_map: TextureRef | None = None
    roughness: float = 0.85
    fuzz: float = 0.62
    ior: float = 1.0
    refractable: bool = False
    checker: bool = False          # diffuse and reflect use the built-in checker pattern
    source: str = "<builtin>"      # file that defined it
    line: int = 0                  # line of its ``newmtl``


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


@dataclass
class MeshData:
    """The triangles of one OBJ file, in world space, ready for one ``wp.Mesh``."""

    name: str
    positions: np.ndarray       # (V, 3) float64 (or float32), world space; see Scene.rounded
    indices: np.ndarray         # (F, 3) int32
    corner_uv: np.ndarray       # (F, 3, 2) float32, zeros where the OBJ gave none
    corner_normal: np.ndarray | None  # (F, 3, 3) float32 unit vectors, or None: flat shading
    face_material: np.ndarray   # (F,) int32 into Scene.materials


@dataclass
class MaterialTable:
    """Materials as structure-of-arrays; row 0 is always Inner_CheckerTexture."""

    names: list[str]
    diffuse: np.ndarray      # (M, 3) float32
    reflect: np.ndarray      # (M, 3) float32
    refract: np.ndarray      # (M, 3) float32
    emission: np.ndarray     # (M, 3) float32
    tex: np.ndarray          # (M, 4) int32 per slot (SLOT_*): TEX_NONE, TEX_CHECKER or a texture index
    roughness: np.ndarray    # (M,) float32 in [0, 1]
    fuzz: np.ndarray         # (M,) float32 >= 0
    ior: np.ndarray          # (M,) float32 > 0
    refractable: np.ndarray  # (M,) bool

    def __len__(self) -> int:
        return len(self.names)


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
    # procedural texture instances (warp_spt.core.proctex.ProcRef); slot value TEX_PROC_BASE - k names k
    procedural: list = field(default_factory=list)

    @property
    def num_triangles(self) -> int:
        return int(sum(len(m.indices) for m in self.meshes))

    def rounded(self) -> "Scene":
        """This scene as the float32 engine sees it: positions and spheres rounded to float32.

        Positions stay float64 from the parser until the scene is recentred
        (:func:`warp_spt.scene.recentre.recentre`), so a scene far from the origin is shifted before
        anything is rounded; the upload (:class:`warp_spt.core.device_scene.DeviceScene`) rounds once,
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
        lo = np.full(3, np.inf)
        hi = np.full(3, -np.inf)
        for m in self.meshes:
            if len(m.indices):
                mask = np.zeros(len(m.positions), dtype=bool)
                mask[m.indices.reshape(-1)] = True          # O(F), unlike np.unique's sort
                used = _as_float32(m.positions[mask])
                lo = np.minimum(lo, used.min(0))
                hi = np.maximum(hi, used.max(0))
        if len(self.spheres):
            s = _as_float32(self.spheres)
            c, r = s[:, :3], s[:, 3:4]
            lo = np.minimum(lo, (c - r).min(0))
            hi = np.maximum(hi, (c + r).max(0))
        return np.stack([lo, hi])


def _as_float32(a: np.ndarray) -> np.ndarray:
    """``a`` rounded to float32 (what the engine stores), as float64 for exact host arithmetic."""
    return a.astype(np.float32).astype(np.float64)
