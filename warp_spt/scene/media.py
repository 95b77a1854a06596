"""Participating media on the host: the :class:`Medium` record, its checks and its text form.

A medium fills a region of space: the whole scene (``Scene.fog``: the camera starts in it) or the
inside of a closed mesh (``Scene.interiors``: material name -> Medium; a ray that crosses a surface
of that material, by transmission, enters or leaves it). Coefficients are per unit length of the
scene, RGB: ``sigma_a`` absorbs, ``sigma_s`` scatters with the Henyey-Greenstein phase function of
asymmetry ``g`` (|g| <= MAX_G = 0.999999: 0 isotropic, > 0 forward), ``emission`` is radiance emitted per unit of
absorption (the medium adds ``sigma_a * emission`` per unit length). ``majorant`` (>= 1) scales the
bound free-flight sampling and ratio tracking use (sigma_t per channel times it): 1 is exact delta
tracking; larger values add null collisions, cost time and leave the mean unchanged. Nothing here
imports Warp.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from warp_spt.scene.numbers import plain_float

from warp_spt.scene import families
from warp_spt.scene.families import MEDIUM_KINDS  # noqa: F401 (re-exported: the medium kinds, by index)

# |g| at most: beyond it the forward peak is narrower than 0.2 arc-seconds, and float32 cannot tell
# 1 - |g| apart from 0 much further on (1 - 2^-24 is the last value below 1)
MAX_G = 0.999999
MAX_GRID_VOXELS = 256 ** 3                  # a dense grid's voxels (the memory budget: 4 bytes each)
# a NanoVDB file's grids, uncompressed: twice a dense grid of MAX_GRID_VOXELS floats (the tree's nodes
# and masks add about a tenth), so the bytes read or inflated stay within what the voxel budget allows
MAX_GRID_BYTES = 8 * MAX_GRID_VOXELS
MAX_SIGMA = 1.0e6                    # per unit length: beyond it a medium is a surface
MAX_MAJORANT = 64.0


@dataclass(frozen=True)
class Medium:
    """A medium (docs/volumes.md). RGB tuples; a single number means grey.

    Homogeneous (``density`` None): ``sigma_a``, ``sigma_s`` per unit length everywhere in its region.
    A grid (``density`` given: a dense (nx, ny, nz) array, or the path of a ``.nvdb`` file holding a
    float grid): the coefficients are per unit density, times ``density_scale`` times the grid's
    trilinearly interpolated value (0 outside it). An array's voxel (i, j, k) lies at
    ``origin + (i, j, k) * voxel_size`` in the grid's own space; a file keeps its own transform;
    ``to_world`` (4x4, row-major, applied to column vectors) places the grid's space in the scene.
    """

    sigma_a: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sigma_s: tuple[float, float, float] = (0.0, 0.0, 0.0)
    g: float = 0.0
    emission: tuple[float, float, float] = (0.0, 0.0, 0.0)
    majorant: float = 1.0
    density: object = field(default=None, compare=False, repr=False)
    density_scale: float = 1.0
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    voxel_size: float = 1.0
    to_world: object = field(default=None, compare=False, repr=False)
    majorant_cells: int = 16          # the majorant grid's cells along the grid's longest axis
    # the medium kind (scene.families.MEDIUM_KINDS: its device code, warp_spt.media.<model>); "": by its
    # data, "grid" with a density and "homogeneous" without
    model: str = ""

    def __post_init__(self):
        for name in ("sigma_a", "sigma_s", "emission"):
            object.__setattr__(self, name, _rgb(getattr(self, name), name))
        for name in ("g", "majorant", "density_scale", "voxel_size"):
            object.__setattr__(self, name, float(getattr(self, name)))

    @property
    def kind(self) -> str:
        """Its medium kind: ``model``, or the one its data gives."""
        if self.model:
            return self.model
        return "homogeneous" if self.density is None else "grid"

    def check(self, where: str = "medium") -> "Medium":
        """ValueError naming ``where`` and the field for a value a kernel must not see (a grid's
        file is read, and its values checked, when it is uploaded: ``media.grid``)."""
        if self.kind not in families.MEDIUM_KINDS:
            raise ValueError(f"{where}: model must be a medium kind ({', '.join(families.MEDIUM_KINDS)}), "
                             f"got {self.model!r}")
        if self.density is not None:
            _check_grid(self, where)
        for name in ("sigma_a", "sigma_s", "emission"):
            for v in getattr(self, name):
                hi = MAX_SIGMA if name != "emission" else 1.0e6
                if not math.isfinite(v) or v < 0.0 or v > hi:
                    raise ValueError(f"{where}: {name} must be finite numbers in [0, {hi:g}], got {getattr(self, name)}")
        if not math.isfinite(self.g) or not -MAX_G <= self.g <= MAX_G:
            raise ValueError(f"{where}: g (Henyey-Greenstein asymmetry) must lie in [-{MAX_G}, {MAX_G}], got {self.g}")
        if not math.isfinite(self.majorant) or not 1.0 <= self.majorant <= MAX_MAJORANT:
            raise ValueError(f"{where}: majorant must lie in [1, {MAX_MAJORANT:g}], got {self.majorant}")
        return self

    @property
    def sigma_t(self) -> tuple[float, float, float]:
        return tuple(a + s for a, s in zip(self.sigma_a, self.sigma_s))


def _check_grid(m: Medium, where: str) -> None:
    for name in ("density_scale", "voxel_size"):
        v = getattr(m, name)
        if not math.isfinite(v) or v <= 0.0 or v > MAX_SIGMA:
            raise ValueError(f"{where}: {name} must be a positive finite number, got {v}")
    if not isinstance(m.majorant_cells, int) or not 1 <= m.majorant_cells <= 256:
        raise ValueError(f"{where}: majorant_cells must be an int in [1, 256], got {m.majorant_cells!r}")
    if m.to_world is not None:
        t = np.asarray(m.to_world, dtype=np.float64)
        if t.shape != (4, 4) or not np.isfinite(t).all() or abs(np.linalg.det(t[:3, :3])) < 1e-12:
            raise ValueError(f"{where}: to_world must be an invertible, finite 4x4 matrix")
    if isinstance(m.density, (str, bytes)) or hasattr(m.density, "__fspath__"):
        return
    a = np.asarray(m.density)
    if a.ndim != 3 or min(a.shape) < 1:
        raise ValueError(f"{where}: density must be a 3-D array (nx, ny, nz) or a .nvdb path, got shape {a.shape}")
    if a.size > MAX_GRID_VOXELS:
        raise ValueError(f"{where}: a density grid of {a.size:,} voxels is over the budget of {MAX_GRID_VOXELS:,}")
    check_densities(a, where)


def check_densities(a: np.ndarray, where: str) -> None:
    """ValueError unless every density is finite and >= 0 (naming the first bad voxel)."""
    bad = ~np.isfinite(a) | (a < 0)
    if bad.any():
        idx = tuple(int(i) for i in np.argwhere(bad)[0])
        raise ValueError(f"{where}: densities must be finite and >= 0; voxel {idx} is {a[idx]}")


def open_boundary_warnings(scene) -> list[str]:
    """A line per material with an interior medium whose triangles do not close: some edge is not
    shared by exactly two of them, and light leaks in and out of the medium there."""
    out = []
    names = {n: i for i, n in enumerate(scene.materials.names)}
    for name in scene.interiors:
        row = names.get(name)
        if row is None:
            continue
        for mesh in scene.meshes:
            tris = mesh.indices[mesh.face_material == row]
            if not len(tris):
                continue
            n_open = open_edges(mesh.positions, tris)
            if n_open:
                out.append(f"material {name!r} has an interior medium but its surface in {mesh.name} is not "
                           f"closed ({n_open} edges not shared by two triangles): the medium's boundary leaks")
    return out


def open_edges(positions: np.ndarray, tris: np.ndarray) -> int:
    """How many edges of the triangles ``tris`` are not shared by exactly two of them, edges taken by
    welded position (an OBJ's or a glTF's corners may repeat a point under another index)."""
    if not len(tris):
        return 0
    _, weld = np.unique(np.asarray(positions, dtype=np.float64), axis=0, return_inverse=True)
    t = weld.reshape(-1)[tris]
    e = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    _, counts = np.unique(e, axis=0, return_counts=True)
    return int((counts != 2).sum())


def interface_rows(table) -> np.ndarray:
    """Per material row: it is a pass-through interface (MTL ``index_matched``: a smooth, white pbr
    dielectric of IOR 1 without a specular layer, no maps), which shadow rays may cross."""
    from warp_spt.scene.material_schema import KIND_PBR

    return ((np.asarray(table.kind) == KIND_PBR) & (np.asarray(table.transmission) == 1.0)
            & (np.asarray(table.ior) == 1.0) & (np.asarray(table.roughness) == 0.0)
            & (np.asarray(table.specular) == 0.0) & (np.asarray(table.metallic) == 0.0)
            & (np.asarray(table.base_color) == 1.0).all(axis=1) & ~np.asarray(table.thin, dtype=bool)
            & (np.asarray(table.emission) == 0.0).all(axis=1) & (np.asarray(table.opacity) == 1.0)
            & (np.asarray(table.tex) == -1).all(axis=1))


def _rgb(value, name: str) -> tuple[float, float, float]:
    if isinstance(value, (int, float)):
        return (float(value),) * 3
    try:
        t = tuple(float(v) for v in value)
    except TypeError:
        raise ValueError(f"medium {name} must be a number or 3 numbers, got {value!r}") from None
    if len(t) == 1:
        return t * 3
    if len(t) != 3:
        raise ValueError(f"medium {name} must be a number or 3 numbers, got {value!r}")
    return t


# the text form's keys (the command line's --fog KEY=VALUE, and MTL's medium_KEY lines)
KEYS = ("sigma_a", "sigma_s", "g", "emission", "majorant")


# A fog given without coefficients (the command line's and the viewer's alike) gets these optical
# depths across the scene (its bounds' diagonal), whatever the scene's units: about 0.6 in all,
# mostly scattering. Coefficients that are given are per scene unit, as everywhere.
FOG_DEPTH_SCATTER = 0.5
FOG_DEPTH_ABSORB = 0.1
SIGMA_KEYS = ("sigma_a", "sigma_s")


def scene_fog(size: float) -> dict:
    """The ``sigma_s`` and ``sigma_a`` (grey, per scene unit) of the default fog for a scene ``size``
    across (its bounds' diagonal)."""
    size = max(float(size), 1.0 / MAX_SIGMA)
    return {"sigma_s": (min(FOG_DEPTH_SCATTER / size, MAX_SIGMA),) * 3,
            "sigma_a": (min(FOG_DEPTH_ABSORB / size, MAX_SIGMA),) * 3}


def given_keys(pairs: list[str]) -> set[str]:
    """The keys that ``KEY=VALUE`` words name."""
    return {item.partition("=")[0] for word in pairs for item in word.split()}


def parse_medium(pairs: list[str], where: str = "--fog") -> Medium:
    """A Medium from ``KEY=VALUE`` words (``sigma_s=0.1``, ``sigma_a=0.01,0.02,0.05``, ``g=0.5``,
    ``emission=...``, ``majorant=2``), checked; ValueError naming ``where``, the word and what
    was expected."""
    fields: dict[str, object] = {}
    for word in pairs:
        for item in word.split():
            key, eq, text = item.partition("=")
            if not eq or key not in KEYS:
                raise ValueError(f"{where}: expected KEY=VALUE with KEY one of {', '.join(KEYS)}, got {item!r}")
            try:
                nums = [plain_float(t) for t in text.split(",")]
            except ValueError:
                raise ValueError(f"{where}: {key} expects plain numbers, got {text!r}") from None
            if key in ("g", "majorant"):
                if len(nums) != 1:
                    raise ValueError(f"{where}: {key} expects one number, got {text!r}")
                fields[key] = nums[0]
            else:
                if len(nums) not in (1, 3):
                    raise ValueError(f"{where}: {key} expects 1 or 3 numbers (R,G,B), got {text!r}")
                fields[key] = tuple(nums) if len(nums) == 3 else nums[0]
    return Medium(**fields).check(where)


__all__ = ["Medium", "MEDIUM_KINDS", "parse_medium", "scene_fog", "given_keys", "SIGMA_KEYS", "KEYS", "check_densities", "open_boundary_warnings", "open_edges", "interface_rows"]
