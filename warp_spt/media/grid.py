"""The grid medium kind: a density grid (NanoVDB through ``wp.Volume``) and its majorant grid.

The density at a point is the grid's trilinear interpolation (0 outside it) in its index space, to
which the medium's 4x4 ``to_grid`` takes scene points (the user's placement, then the grid's own
transform); coefficients are the medium's per-unit-density ones times it. A coarse majorant grid,
built on the host, holds the largest density that can be interpolated in each of its cells (every
voxel counts in every cell within one voxel of it, the reach of trilinear interpolation); free
flights and ratio tracking walk it cell by cell (``segment``: the majorant that holds from ``t``
to the next cell wall, a 3-D DDA step recomputed from the position), so empty cells are crossed in
one step and thin ones with few tentative collisions. Outside the grid's box the majorant is 0.
"""

from __future__ import annotations

import os
import struct
import zlib
from types import SimpleNamespace

import numpy as np
import warp as wp

from warp_spt.device.media_table import Media
from warp_spt.io.tokens import read_file
from warp_spt.scene.errors import SceneError
from warp_spt.scene.limits import MAX_COORDINATE
from warp_spt.scene.media import MAX_GRID_BYTES, MAX_GRID_VOXELS, Medium, check_densities

NAME = "grid"
# a grid's index-to-world matrix may stretch one axis up to this much more than another (a voxel a
# million times longer than wide is already a modelling slip; beyond it the inverse loses digits)
MAX_CONDITION = 1e8


def declare(medium) -> frozenset:
    """What a medium of this kind needs compiled in (``Features.media``): its name: no code path of its own."""
    return frozenset({NAME})
_INF = wp.constant(1.0e30)


def make(features) -> SimpleNamespace:
    """``coefficients(media, m, x)``, ``segment(media, m, o, d, t, t_max) -> (t_end, majorant)``."""

    @wp.func
    def density(media: Media, m: int, x: wp.vec3) -> float:
        q = wp.transform_point(media.to_grid[m], x)
        return wp.volume_sample_f(media.volume[m], q, wp.Volume.LINEAR)

    @wp.func
    def coefficients(media: Media, m: int, x: wp.vec3):
        rho = density(media, m, x)
        return media.sigma_a[m] * rho, media.sigma_s[m] * rho

    @wp.func
    def segment(media: Media, m: int, o: wp.vec3, d: wp.vec3, t: float, t_max: float):
        M = media.to_grid[m]
        oi = wp.transform_point(M, o)
        di = wp.transform_vector(M, d)
        lo = media.mg_lo[m]
        cs = media.mg_cell[m]
        res = media.mg_res[m]
        zero = wp.vec3(0.0, 0.0, 0.0)
        # the ray's interval inside the majorant grid's box
        t_in = float(0.0)
        t_out = float(_INF)
        for a in range(3):
            hi_a = lo[a] + float(res[a]) * cs[a]
            if wp.abs(di[a]) < 1.0e-20:
                if oi[a] < lo[a] or oi[a] > hi_a:
                    return t_max, zero
            else:
                ta = (lo[a] - oi[a]) / di[a]
                tb = (hi_a - oi[a]) / di[a]
                t_in = wp.max(t_in, wp.min(ta, tb))
                t_out = wp.min(t_out, wp.max(ta, tb))
        if t_in >= t_out or t >= t_out:
            return t_max, zero
        if t < t_in:
            return wp.min(t_in, t_max), zero
        # the cell a little past t (a wall at t itself belongs to the cell the ray leaves)
        big = wp.max(wp.max(wp.abs(di[0]) / cs[0], wp.abs(di[1]) / cs[1]), wp.abs(di[2]) / cs[2])
        nudge = 1.0e-4 / big
        p = oi + di * (t + nudge)
        t_exit = float(t_out)
        cell = wp.vec3i(0, 0, 0)
        for a in range(3):
            c = wp.clamp(int(wp.floor((p[a] - lo[a]) / cs[a])), 0, res[a] - 1)
            cell[a] = c
            if di[a] > 1.0e-20:
                t_exit = wp.min(t_exit, (lo[a] + float(c + 1) * cs[a] - oi[a]) / di[a])
            elif di[a] < -1.0e-20:
                t_exit = wp.min(t_exit, (lo[a] + float(c) * cs[a] - oi[a]) / di[a])
        t_end = wp.min(wp.max(t_exit, t + nudge), t_max)
        k = media.mg_offset[m] + (cell[2] * res[1] + cell[1]) * res[0] + cell[0]
        return t_end, media.majorant[m] * media.mg_values[k]

    return SimpleNamespace(coefficients=coefficients, segment=segment)


@wp.kernel
def _lookup(volume: wp.uint64, ijk: wp.array(dtype=wp.vec3i), out: wp.array(dtype=float)):
    i = wp.tid()
    c = ijk[i]
    out[i] = wp.volume_lookup_f(volume, c[0], c[1], c[2])


def load_grid(medium: Medium, device: str, where: str):
    """(wp.Volume, active voxels' (N, 3) int ijk, their densities): from the medium's array or file.
    SceneError naming the file (the command line's one line) for one Warp cannot read as a float
    NanoVDB grid, too large, or with negative or non-finite densities (ValueError for an array's)."""
    src = medium.density
    if isinstance(src, (str, bytes)) or hasattr(src, "__fspath__"):
        path = os.fsdecode(src)
        # a regular file (not /dev/zero) of at most MAX_GRID_BYTES, whose zip and blosc chunks are
        # inflated here within that budget: Warp's loader inflates them without a bound (4.2 MB of zip
        # took it to 8.7 GB; blosc allocates whatever a chunk's header declares)
        data = nvdb_uncompressed(read_file(path, "density grid", limit=MAX_GRID_BYTES, binary=True), path)
        if grid_class(data) == LEVEL_SET:      # its values are distances, negative inside: not densities
            raise SceneError(path, 0, "a signed-distance (level-set) grid; a density (fog) grid is expected "
                                      "(OpenVDB's tools::sdfToFogVolume makes one from it)")
        try:
            vol = wp.Volume.load_from_nvdb(data, device=device)
            kind = vol.get_grid_info().type_str
        except Exception as err:            # Warp validates the tree: its message, on one line
            text = " ".join(str(err).split()) or type(err).__name__
            raise SceneError(path, 0, f"not a valid NanoVDB grid ({text})") from None
        if kind != "float":
            raise SceneError(path, 0, f"the density grid holds {kind!r} values; a float grid was expected")
        problem = transform_problem(vol)
        if problem:
            raise SceneError(path, 0, problem)
        ijk = vol.get_voxels().numpy().astype(np.int32)
        if len(ijk) > MAX_GRID_VOXELS:
            raise SceneError(path, 0, f"{len(ijk):,} active voxels are over the budget of {MAX_GRID_VOXELS:,}")
        vals = wp.zeros(len(ijk), dtype=float, device=device)
        if len(ijk):
            wp.launch(_lookup, dim=len(ijk), inputs=[vol.id, wp.array(ijk, dtype=wp.vec3i, device=device), vals],
                      device=device)
        vals = vals.numpy()
        bad = ~np.isfinite(vals) | (vals < 0)
        if bad.any():               # the voxel by its index coordinates, as a dense grid's are named
            k = int(np.argmax(bad))
            raise SceneError(path, 0, f"densities must be finite and >= 0; voxel {tuple(int(i) for i in ijk[k])} "
                                      f"is {vals[k]}")
        return vol, ijk, vals
    a = np.ascontiguousarray(np.asarray(src, dtype=np.float32))
    check_densities(a, where)
    vol = wp.Volume.load_from_numpy(a, min_world=medium.origin, voxel_size=medium.voxel_size, bg_value=0.0,
                                    device=device)
    ijk = np.argwhere(a != 0).astype(np.int32)
    return vol, ijk, a[a != 0]


# NanoVDB's GridClass values (its file header's per-grid metadata, a uint32 at byte 36 of each)
LEVEL_SET = 1


def grid_class(data: bytes) -> int | None:
    """The first grid's class in a NanoVDB file's header (None for data too short to say)."""
    if len(data) < 16 + 40 or data[:8] not in (b"NanoVDB0", b"NanoVDB2"):
        return None
    return struct.unpack("<I", data[16 + 36:16 + 40])[0]


def grid_bounds(medium: Medium, device: str = "cpu", where: str = "volume") -> np.ndarray:
    """(2, 3) float64: the scene box the medium's grid can be non-zero in (its active voxels, and one
    voxel more on every side, the reach of trilinear interpolation), through the grid's own
    index-to-world map and the medium's ``to_world``. SceneError as :func:`load_grid`'s."""
    vol, ijk, vals = load_grid(medium, device, where)
    ijk = ijk[vals != 0]            # a file's active voxels include zeros (a dense grid's whole leaves)
    if not len(ijk):
        raise SceneError(os.fsdecode(medium.density) if isinstance(medium.density, (str, bytes, os.PathLike))
                         else None, 0, "the grid holds no density above 0: there is nothing to place")
    lo, hi = ijk.min(0) - 1.0, ijk.max(0) + 1.0
    corners = np.array([[(lo, hi)[(k >> a) & 1][a] for a in range(3)] + [1.0] for k in range(8)])
    world = (np.linalg.inv(grid_index_transform(vol, medium)) @ corners.T).T[:, :3]
    return np.array([world.min(0), world.max(0)])


def add_volume(scene, density, *, name: str | None = None, device: str = "cpu", **medium):
    """``scene`` (a host :class:`~warp_spt.scene.model.Scene`) plus a density grid in the box of its
    own bounds (:func:`grid_bounds`): a closed pass-through box (MTL ``index_matched``) whose
    interior medium is the grid. ``density``: a ``.nvdb`` path or a dense array (with ``origin`` and
    ``voxel_size``); ``medium``: the other :class:`Medium` fields (coefficients per unit density and
    scene unit; default ``sigma_s=1``). Returns (the new scene, the box's (2, 3) bounds)."""
    from dataclasses import replace

    from warp_spt.scene.model import Material, MeshData

    medium.setdefault("sigma_s", 1.0)
    m = Medium(density=density, **medium).check("volume")
    box = grid_bounds(m, device)
    names = set(scene.materials.names)
    base = name or (f"volume {os.path.basename(os.fsdecode(density))}" if isinstance(density, (str, os.PathLike))
                    else "volume")
    label = next(n for n in (base, *(f"{base} {k}" for k in range(2, len(names) + 3))) if n not in names)
    wall = Material.pbr(label, base_color=(1.0, 1.0, 1.0), transmission=1.0, ior=1.0, roughness=0.0,
                        specular=0.0, metallic=0.0)
    row = len(scene.materials)
    positions, faces = box_triangles(box)
    mesh = MeshData(name=label, positions=positions, indices=faces,
                    corner_uv=np.zeros((len(faces), 3, 2), np.float32), corner_normal=None,
                    face_material=np.full(len(faces), row, np.int32))
    return replace(scene, meshes=[*scene.meshes, mesh], materials=scene.materials.with_rows([replace(wall, interior=m)]),
                   interiors={**scene.interiors, label: m}), box


def box_triangles(box: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(8, 3) corners and (12, 3) int32 triangles of the closed axis-aligned box ``box`` ((2, 3):
    lower, upper), each wound counter-clockwise seen from outside."""
    lo, hi = np.asarray(box, np.float64)
    corners = np.array([[(lo, hi)[(k >> a) & 1][a] for a in range(3)] for k in range(8)])
    faces = []
    for axis in range(3):
        a, b = (axis + 1) % 3, (axis + 2) % 3
        for side in (0, 1):
            quad = [k for k in range(8) if (k >> axis) & 1 == side]
            # the quad's corners in order around it: (0,0), (1,0), (1,1), (0,1) in the (a, b) plane
            ring = sorted(quad, key=lambda k: [(0, 0), (1, 0), (1, 1), (0, 1)].index(((k >> a) & 1, (k >> b) & 1)))
            if not side:
                ring = ring[::-1]           # the lower face looks the other way
            faces += [(ring[0], ring[1], ring[2]), (ring[0], ring[2], ring[3])]
    return corners, np.array(faces, np.int32)


def nvdb_uncompressed(data: bytes, path: str) -> bytes:
    """The NanoVDB file ``data`` with its grids uncompressed (codec 0) from zip (1) or blosc (2), the
    codecs Warp's loader takes. Every size in the header is checked against the bytes before it is
    used, the grids' uncompressed size (each grid's metadata says it) against MAX_GRID_BYTES, and
    inflating stops there: a chunk that would give more is refused, whatever its compression ratio
    (a blosc chunk from its own header, before it is decoded). Data that is not a NanoVDB file is returned as it is,
    for Warp's own message."""
    if len(data) < 16 or data[:8] not in (b"NanoVDB0", b"NanoVDB2"):
        return data
    count, codec = struct.unpack("<HH", data[12:16])
    offset, raw, stored, meta = 16, 0, 0, []
    for k in range(count):
        if offset + 176 > len(data):
            raise SceneError(path, 0, f"the header of grid {k} ends past the file's {len(data):,} bytes")
        grid_size, file_size = struct.unpack("<QQ", data[offset:offset + 16])    # uncompressed, as stored
        raw, stored = raw + grid_size, stored + file_size
        meta.append(offset)
        offset += 176 + struct.unpack("<I", data[offset + 136:offset + 140])[0]
    start = offset
    if raw > MAX_GRID_BYTES:
        raise SceneError(path, 0, f"the grids hold {raw:,} bytes, over the budget of {MAX_GRID_BYTES:,}")
    if codec not in (1, 2):     # none (0); another code is Warp's "Unsupported codec" message
        return data
    out = bytearray()
    while offset < start + stored:
        size = struct.unpack("<Q", data[offset:offset + 8])[0] if offset + 8 <= len(data) else None
        if size is None or offset + 8 + size > len(data):
            raise SceneError(path, 0, f"a compressed chunk at byte {offset:,} runs past the end of the file")
        chunk = data[offset + 8:offset + 8 + size]
        part = _inflate_zip(chunk, raw - len(out), path) if codec == 1 else _inflate_blosc(chunk, raw - len(out), path)
        if part is None:
            raise SceneError(path, 0, f"the compressed grids inflate to more than the {raw:,} bytes their "
                             "header declares")
        out += part
        offset += 8 + size
    if len(out) != raw:
        raise SceneError(path, 0, f"the compressed grids inflate to {len(out):,} bytes; their header declares {raw:,}")
    head = bytearray(data[:start])
    head[14:16] = struct.pack("<H", 0)
    for m in meta:                           # stored sizes are the uncompressed ones now, and no codec
        head[m + 8:m + 16] = head[m:m + 8]
        head[m + 168:m + 170] = b"\0\0"
    head += out
    del out
    return bytes(head)


def _inflate_zip(chunk: bytes, budget: int, path: str) -> bytes | None:
    """One zip chunk inflated, stopping one byte past ``budget`` (the bytes the header has left):
    None if it gives more."""
    inflate = zlib.decompressobj()
    try:
        part = inflate.decompress(chunk, budget + 1)
    except zlib.error as err:
        raise SceneError(path, 0, f"a compressed chunk is not valid zip data ({err})") from None
    return None if len(part) > budget or inflate.unconsumed_tail else part


# a blosc (version 1) chunk's header: version, versionlz, flags, typesize, then its uncompressed size,
# block size and stored size as uint32s; blosc allocates the uncompressed size before decoding
BLOSC_HEADER = 16


def _inflate_blosc(chunk: bytes, budget: int, path: str) -> bytes | None:
    """One blosc chunk decoded, its header's sizes checked first: the stored size against the chunk,
    the uncompressed size against ``budget`` (None if more: python-blosc allocates what a header
    declares, up to 2 GiB, and Warp's loader hands it every chunk unchecked)."""
    if len(chunk) < BLOSC_HEADER:
        raise SceneError(path, 0, f"a blosc chunk of {len(chunk)} bytes is shorter than its {BLOSC_HEADER}-byte header")
    nbytes, _, cbytes = struct.unpack("<III", chunk[4:16])
    if cbytes != len(chunk):
        raise SceneError(path, 0, f"a blosc chunk's header says {cbytes:,} bytes are stored; the chunk holds "
                                  f"{len(chunk):,}")
    if nbytes > budget:
        return None
    try:
        import blosc
    except ImportError:
        raise SceneError(path, 0, "the grids are blosc-compressed, which needs the 'blosc' package "
                                  "(pip install blosc); or save them with zip compression or none") from None
    try:
        part = blosc.decompress(chunk)
    except Exception as err:            # blosc's own (its error types differ between versions)
        raise SceneError(path, 0, f"a compressed chunk is not valid blosc data ({err})") from None
    if len(part) != nbytes:
        raise SceneError(path, 0, f"a blosc chunk decoded to {len(part):,} bytes; its header declares {nbytes:,}")
    return part


def transform_problem(vol: wp.Volume) -> str | None:
    """Why the grid's index-to-world map cannot place it (None if it can): NaN or infinite entries
    (the medium was dropped without a word), or a matrix too near singular to invert (it was
    ``internal error: LinAlgError``)."""
    info = vol.get_grid_info()
    m = np.asarray(info.transform_matrix, dtype=np.float64).reshape(3, 3)
    t = np.asarray(info.translation, dtype=np.float64)
    if not (np.all(np.isfinite(m)) and np.all(np.isfinite(t))):
        return "the grid's index-to-world map holds NaN or infinite numbers"
    if np.abs(t).max() > MAX_COORDINATE or not np.abs(m).max() > 0.0:
        return f"the grid's index-to-world map places it beyond +-{MAX_COORDINATE:g} or has no scale"
    if np.linalg.cond(m) > MAX_CONDITION:
        return (f"the grid's index-to-world map is singular or nearly so (condition number over "
                f"{MAX_CONDITION:g}): its voxels would have no volume")
    return None


def grid_index_transform(vol: wp.Volume, medium: Medium) -> np.ndarray:
    """The 4x4 matrix from scene points to the grid's index space: the inverse of the medium's
    ``to_world`` (its own space to the scene), then the grid's world-to-index map."""
    info = vol.get_grid_info()
    m = np.asarray(info.transform_matrix, dtype=np.float64).reshape(3, 3)
    t = np.asarray(info.translation, dtype=np.float64)
    to_index = np.eye(4)
    to_index[:3, :3] = np.linalg.inv(m)
    to_index[:3, 3] = -np.linalg.inv(m) @ t
    w = np.eye(4) if medium.to_world is None else np.asarray(medium.to_world, dtype=np.float64)
    return to_index @ np.linalg.inv(w)


def majorant_grid(ijk: np.ndarray, vals: np.ndarray, cells: int):
    """(lower corner, cell size (both index space), resolution (3,), max density per cell, x fastest):
    every voxel counts in each cell within one voxel of it."""
    if len(ijk) == 0:
        return np.zeros(3), np.ones(3), np.ones(3, np.int64), np.zeros(1, np.float32)
    lo = ijk.min(0).astype(np.float64) - 1.0
    hi = ijk.max(0).astype(np.float64) + 1.0
    cs = np.full(3, max((hi - lo).max() / cells, 2.0))
    res = np.maximum(np.ceil((hi - lo) / cs).astype(np.int64), 1)
    values = np.zeros(tuple(res[::-1]), np.float32)           # (z, y, x)
    first = np.clip(np.floor((ijk - 1.0 - lo) / cs).astype(np.int64), 0, res - 1)
    last = np.clip(np.floor((ijk + 1.0 - lo) / cs).astype(np.int64), 0, res - 1)
    for bits in range(8):          # a voxel's reach spans at most two cells per axis (cells >= 2 voxels)
        c = np.where([(bits >> a) & 1 for a in range(3)], last, first)
        np.maximum.at(values, (c[:, 2], c[:, 1], c[:, 0]), vals.astype(np.float32))
    return lo, cs, res, values.reshape(-1)
