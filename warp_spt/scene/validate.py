"""validate_scene(): the last gate before device upload; nothing it accepts can upset a kernel.

Every array of a :class:`Scene` is checked for dtype, shape, finiteness and range. Values out of
range are errors, never clamped: a roughness outside [0, 1] or an IOR <= 0 means the input is
wrong, and silently changing it would hide that.
"""

from __future__ import annotations

import numpy as np

from warp_spt.scene.errors import SceneError
from warp_spt.scene.limits import (  # noqa: F401 (obj, mtl import them from here)
    MAX_COORDINATE,
    MAX_IOR,
    MAX_RADIANCE,
    MAX_TRIANGLE_EDGE,
    MIN_IOR,
)
from warp_spt.scene.material_schema import (
    COLUMNS,
    SLOT_COLUMNS,
    SLOTS,
    host_dtype,
    range_text,
    row_shape,
)
from warp_spt.scene.model import (
    CHECKER_NAME,
    TEX_CHECKER,
    TEX_NONE,
    TEX_PROC_BASE,
    MaterialTable,
    MeshData,
    Scene,
    column_range,
)

_WHERE = "<scene>"
COORDINATES = (np.float64, np.float32)   # parsed coordinates stay float64 until the upload rounds them


def _fail(message: str) -> None:
    raise SceneError(_WHERE, 0, message)


def _check_array(a: object, name: str, dtype: type | tuple[type, ...], shape: tuple[int | None, ...]) -> np.ndarray:
    """``a`` is an ndarray of ``dtype`` (or one of them) whose shape matches (None = any length), finite if float."""
    dtypes = dtype if isinstance(dtype, tuple) else (dtype,)
    if not isinstance(a, np.ndarray) or a.dtype not in dtypes:
        want = " or ".join(np.dtype(d).name for d in dtypes)
        _fail(f"{name} must be a numpy {want} array, got {getattr(a, 'dtype', type(a).__name__)}")
    if a.ndim != len(shape) or any(want is not None and got != want for got, want in zip(a.shape, shape)):
        want = ", ".join("N" if s is None else str(s) for s in shape)
        _fail(f"{name} must have shape ({want}), got {a.shape}")
    if a.dtype.kind == "f" and not np.isfinite(a).all():
        _fail(f"{name} holds NaN or infinite values")
    return a


def _check_index(a: np.ndarray, name: str, n: int) -> None:
    if a.size and (a.min() < 0 or a.max() >= n):
        _fail(f"{name} holds indices outside [0, {n})")


_EDGE_BLOCK = 1 << 16         # triangles per block of longest_edges


def longest_edges(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Each triangle's longest edge, in float64 (``faces``: (F, 3) indices into ``positions``)."""
    p = positions.astype(np.float64, copy=False)
    out = np.zeros(len(faces))
    # in blocks: a whole large mesh's float64 corners and edges would be its largest temporaries
    for k in range(0, len(faces), _EDGE_BLOCK):
        f = faces[k:k + _EDGE_BLOCK]
        corners = [p[f[:, j]] for j in range(3)]
        out[k:k + len(f)] = np.max([np.linalg.norm(corners[(j + 1) % 3] - corners[j], axis=1) for j in range(3)],
                                   axis=0)
    return out


_AREA_BLOCK = 1 << 16        # triangles per block of nonzero_area


def nonzero_area(positions: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Mask of triangles whose area is not exactly zero, in float64 (OBJ, PLY and glTF), with the cross
    product's components formed one at a time: np.cross is 3x slower on large arrays, and for
    coordinates within MAX_COORDINATE the products are finite, where a - b is 0 exactly when a == b,
    so this is np.cross(...) != 0 without its temporaries."""
    p = np.asarray(positions, np.float64)
    out = np.ones(len(faces), dtype=bool)
    # in blocks: the float64 edges of a whole large mesh would be its largest temporaries (120 B per triangle)
    for k in range(0, len(faces), _AREA_BLOCK):
        f = faces[k:k + _AREA_BLOCK]
        p0 = np.take(p, f[:, 0], axis=0)             # (2-3x faster than p[f[:, 0]])
        e1 = np.take(p, f[:, 1], axis=0) - p0
        e2 = np.take(p, f[:, 2], axis=0) - p0
        x = e1[:, 1] * e2[:, 2] != e1[:, 2] * e2[:, 1]
        x |= e1[:, 2] * e2[:, 0] != e1[:, 0] * e2[:, 2]
        x |= e1[:, 0] * e2[:, 1] != e1[:, 1] * e2[:, 0]
        out[k:k + len(f)] = x
    return out


def box_bounds_edges(positions: np.ndarray, limit: float) -> bool:
    """Whether the positions' bounding box alone proves every edge between them no longer than
    ``limit``: an edge joins two points of the box, so it is no longer than its diagonal. Almost every
    model passes, and the per-triangle pass of :func:`longest_edges` (0.35 CPU s at a million
    triangles) is skipped; the margin covers the rounding of both computations."""
    if len(positions) == 0:
        return True
    lo, hi = column_range(positions)
    ext = hi.astype(np.float64) - lo.astype(np.float64)
    return float(np.sqrt(ext @ ext)) * (1.0 + 1e-9) <= limit


def edge_problem(edge: float) -> str:
    """Why a triangle with this longest edge is refused (docs/limits.md)."""
    return (f"a triangle's edge of {edge:.3g} is longer than the supported {MAX_TRIANGLE_EDGE:g} "
            "(float32 overflows in the hit test and the shading beyond it: scale the model down)")


def _check_mesh(k: int, m: MeshData, n_materials: int) -> None:
    name = f"meshes[{k}] ({m.name})"
    pos = _check_array(m.positions, f"{name}.positions", COORDINATES, (None, 3))
    idx = _check_array(m.indices, f"{name}.indices", np.int32, (None, 3))
    f = len(idx)
    _check_index(idx, f"{name}.indices", len(pos))
    edges = None if box_bounds_edges(pos, MAX_TRIANGLE_EDGE) else longest_edges(pos, idx)
    if f and edges is not None and not edges.max() <= MAX_TRIANGLE_EDGE:
        _fail(f"{name}: {edge_problem(float(edges.max()))}")
    _check_array(m.corner_uv, f"{name}.corner_uv", np.float32, (f, 3, 2))
    if m.corner_normal is not None:
        nrm = _check_array(m.corner_normal, f"{name}.corner_normal", np.float32, (f, 3, 3))
        if f and np.abs(np.linalg.norm(nrm, axis=2) - 1.0).max() > 1e-3:
            _fail(f"{name}.corner_normal holds vectors that are not unit length")
    _check_index(_check_array(m.face_material, f"{name}.face_material", np.int32, (f,)), f"{name}.face_material",
                 n_materials)
    if m.transforms is not None:
        x = np.asarray(m.transforms)
        if x.ndim != 3 or x.shape[1:] != (4, 4) or len(x) == 0:
            _fail(f"{name}.transforms must have shape (I, 4, 4) with I >= 1, got {x.shape}")
        if not np.all(np.isfinite(x)):
            _fail(f"{name}.transforms holds a non-finite value")
        det = np.linalg.det(x[:, :3, :3].astype(np.float64))
        if np.any(np.abs(det) < 1e-30):
            _fail(f"{name}.transforms[{int(np.argmin(np.abs(det)))}]: the linear part must be invertible")
        # the world-space limits of a flattened copy: an edge grows at most by the largest singular value
        stretch = float(np.linalg.norm(x[:, :3, :3].astype(np.float64), ord=2, axis=(1, 2)).max())
        if f and edges is None and not box_bounds_edges(pos, MAX_TRIANGLE_EDGE / stretch):
            edges = longest_edges(pos, idx)
        if f and edges is not None and not edges.max() * stretch <= MAX_TRIANGLE_EDGE:
            _fail(f"{name} as placed by its transforms: {edge_problem(float(edges.max()) * stretch)}")
        b = m.world_bounds(rounded=False)
        if b is not None and not np.abs(np.asarray(b)).max() <= MAX_COORDINATE:
            _fail(f"{name} as placed by its transforms reaches {np.abs(np.asarray(b)).max():g}, beyond the supported "
                  f"range of +-{MAX_COORDINATE:g}")


def _check_materials(t: MaterialTable, n_textures: int, n_procedural: int = 0) -> None:
    """Every schema column: its dtype and shape, its range (or, for ``tex``, valid slot values)."""
    m = len(t.names)
    if m == 0 or t.names[0] != CHECKER_NAME:
        _fail(f"materials row 0 must be {CHECKER_NAME}")
    for c in COLUMNS:
        a = _check_array(getattr(t, c.name), f"materials.{c.name}", np.dtype(host_dtype(c)).type, (m, *row_shape(c)))
        if c.type == SLOTS:
            _check_slots(a, n_textures, n_procedural)
        elif (c.low is not None and (a < c.low).any()) or (c.high is not None and (a > c.high).any()):
            _fail(f"materials.{c.name} must {range_text(c)}")


def _check_slots(tex: np.ndarray, n_textures: int, n_procedural: int) -> None:
    proc = (tex <= TEX_PROC_BASE) & (tex > TEX_PROC_BASE - n_procedural)
    if ((tex < 0) & (tex != TEX_NONE) & (tex != TEX_CHECKER) & ~proc).any() or (tex >= n_textures).any():
        _fail(f"materials.tex holds slots that are neither TEX_NONE, TEX_CHECKER, a texture in [0, {n_textures}) "
              f"nor one of the {n_procedural} procedural instances")


def validate_scene(scene: Scene) -> None:
    """Raise :class:`SceneError` unless every array of ``scene`` has its dtype, shape and range.

    Checks: meshes (finite float64 or float32 positions, int32 indices in range, no triangle edge
    longer than MAX_TRIANGLE_EDGE, uv, unit normals, material rows), spheres (finite, radius > 0,
    material rows), the material table (row 0 is the checker, every column in its range of the
    material schema, texture slots valid), textures ((H, W, 3) float32 in [0, 1], non-empty), and
    that there is some geometry at all.
    """
    n_mat = len(scene.materials.names)
    _check_materials(scene.materials, len(scene.textures), len(scene.procedural))
    check_procedural_colours(scene)
    for k, tex in enumerate(scene.textures):
        _check_array(tex, f"textures[{k}]", np.float32, (None, None, 3))
        if tex.shape[0] == 0 or tex.shape[1] == 0 or tex.min(initial=0) < 0 or tex.max(initial=0) > 1:
            _fail(f"textures[{k}] must be a non-empty image with values in [0, 1]")
    for k, mesh in enumerate(scene.meshes):
        _check_mesh(k, mesh, n_mat)
    spheres = _check_array(scene.spheres, "spheres", COORDINATES, (None, 4))
    if (spheres[:, 3] <= 0).any():
        _fail("spheres must have a radius > 0")
    smat = _check_array(scene.sphere_material, "sphere_material", np.int32, (len(spheres),))
    _check_index(smat, "sphere_material", n_mat)
    if scene.num_triangles == 0 and len(spheres) == 0 and not scene.hidden:
        _fail("the scene has no geometry: no triangles and no spheres")


def check_procedural_colours(scene: Scene) -> None:
    """A procedural texture's colours within the range of the slot it fills (a reflectance colour
    in [0, 1], an emitted one up to MAX_RADIANCE), as a plain colour of that slot would be."""
    tex = scene.materials.tex
    for column in SLOT_COLUMNS:
        for row in np.flatnonzero(tex[:, column.slot] <= TEX_PROC_BASE):
            ref = scene.procedural[TEX_PROC_BASE - int(tex[row, column.slot])]
            values = np.array([ref.params[o:o + 3] for o in ref.colours], dtype=np.float64).reshape(-1)
            low = 0.0 if column.low is None else column.low
            high = MAX_RADIANCE if column.high is None else column.high
            if values.size and (values.min() < low or values.max() > high):
                _fail(f"proc:{ref.name} fills {scene.materials.names[row]}.{column.name}: its colours must "
                      f"lie in [{low:g}, {high:g}]")
