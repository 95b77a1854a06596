"""What the scene-file readers (``gltf/``, ``usd/``) share, below both of them: the pieces of
triangles a reader collects (:class:`Part`) gathered into one :class:`ObjData`, the record of what a
file holds beyond triangles (:class:`ModelExtras`: cameras, lights, instanced meshes, its time range,
its sky) and of a camera placed in it (:class:`FileCamera`), and the ``pbr`` material a file's
material becomes (:func:`pbr_material`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from warp_spt.scene.model import Material, ObjData


@dataclass
class Part:
    """Triangles of one material: world-space (or object-space, for a placed mesh) ``positions`` and
    their ``triangles``; texture coordinates and normals indexed by ``triangles`` or, where a format
    gives them per face corner (USD's face-varying primvars), by their own ``uv_index`` /
    ``normal_index``; ``colours`` per vertex (glTF's COLOR_0) or None; ``row`` the material row."""

    positions: np.ndarray
    triangles: np.ndarray
    uv: np.ndarray | None = None
    normals: np.ndarray | None = None
    colours: np.ndarray | None = None
    row: int = 0
    uv_index: np.ndarray | None = None
    normal_index: np.ndarray | None = None


@dataclass
class FileCamera:
    """A perspective camera placed in a scene file: ``position``, view ``direction`` and ``up`` in world
    space; ``yfov`` in radians; ``aspect`` None when the file leaves it to the image. ``index`` is its
    place among the file's cameras, ``node`` the glTF node placing it (-1 for other formats), ``path``
the file."""

    name: str
    index: int
    node: int
    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    up: tuple[float, float, float]
    yfov: float
    aspect: float | None
    znear: float
    kind: str = "perspective"    # another type (orthographic) is listed but cannot be looked through
    path: str = ""               # the file that defines it, for messages ("" where none is known)

    def fov_degrees(self, width: int, height: int) -> float:
        """The full horizontal angle for an image of ``width`` x ``height`` (the renderer's ``fov``)."""
        aspect = width / height
        return math.degrees(2.0 * math.atan(math.tan(self.yfov / 2.0) * aspect))


@dataclass
class ModelExtras:
    """What a scene file holds beyond flattened triangles (``ObjData.extras``); the loader reads it."""

    cameras: list = field(default_factory=list)      # FileCamera records, in file order
    lights: list = field(default_factory=list)       # records with to_scene(): the renderer's light
    # the meshes kept in their own object space and instanced: per mesh, its triangles (an ObjData sharing
    # the file's material names) and its (I, 4, 4) world matrices, uploaded once (the TLAS's instances)
    placed: list[tuple[ObjData, np.ndarray]] = field(default_factory=list)
    # the animation's time range in seconds (None: the file has no animation)
    time_range: tuple[float, float] | None = None
    # placements of meshes scaled to nothing (a common way to hide an object), not drawn
    hidden: int = 0
    # the file's infinite light (a warp_spt.scene.sky.Sky: USD's dome light), None: the command line's
    sky: object = None


def pbr_material(name: str, source: str, fields: dict) -> Material:
    """A material of the ``pbr`` kind read from the scene file ``source`` (not the seed's dialect)."""
    material = Material.pbr(name, **fields)
    material.source, material.seed_dialect = source, False
    return material


def gather(path: str, parts: list[Part], names: list[str], materials: dict[str, Material], extras,
           warnings: list[str]) -> tuple[ObjData, list[int]]:
    """One :class:`ObjData` of ``parts`` and each part's count of triangles kept (None for a part
    without triangles, whose vertices are left out too): those of zero area are dropped and counted (a
    UV sphere's poles have them)."""
    from warp_spt.scene.validate import nonzero_area

    positions, faces, ftex, fnrm, fmat, uvs, nrms = [], [], [], [], [], [], []
    nv = nt = nn = 0
    dropped = 0
    kept = []
    for part in parts:
        tri = part.triangles
        kept.append(None)
        if len(tri) == 0:
            continue
        keep = nonzero_area(part.positions, tri)
        dropped += int(len(keep) - np.count_nonzero(keep))
        tri = tri[keep]
        kept[-1] = len(tri)
        positions.append(part.positions)
        faces.append(tri + nv)
        for values, index, out, idx_out, offset in ((part.uv, part.uv_index, uvs, ftex, nt),
                                                     (part.normals, part.normal_index, nrms, fnrm, nn)):
            if values is None:
                idx_out.append(np.full_like(tri, -1))
                continue
            idx_out.append((tri if index is None else index[keep]) + offset)
            out.append(values)
        nt += 0 if part.uv is None else len(part.uv)
        nn += 0 if part.normals is None else len(part.normals)
        fmat.append(np.full(len(tri), part.row, np.int32))
        nv += len(part.positions)
    cat = lambda xs, shape, dtype: np.concatenate(xs).astype(dtype) if xs else np.zeros(shape, dtype)  # noqa: E731
    return ObjData(
        path=path, positions=cat(positions, (0, 3), np.float64),
        texcoords=cat(uvs, (0, 2), np.float32), normals=cat(nrms, (0, 3), np.float32),
        faces=cat(faces, (0, 3), np.int32), face_texcoords=cat(ftex, (0, 3), np.int32),
        face_normals=cat(fnrm, (0, 3), np.int32), face_material=cat(fmat, (0,), np.int32),
        spheres=np.zeros((0, 4)), sphere_material=np.zeros(0, np.int32),
        material_names=names, material_lines=[0] * len(names), dropped_degenerate=dropped,
        materials=materials, extras=extras, warnings=list(warnings),
    ), kept
