"""Scene upload: numpy Scene -> Warp meshes (one per OBJ), our top-level BVH, texture atlas, material table.

The high half of the device scene: the structs it fills are ``warp_spt.device.structs`` (the low half,
what kernels read). The result, :class:`DeviceScene`, carries one small struct per concept that
kernels take (:class:`Geometry`, :class:`Materials`, :class:`Textures` with procedural instances; the
light table is built by ``warp_spt.emitters``), plus the :class:`Features` the scene actually uses
(its material part declared by the material kinds, ``warp_spt.bsdfs.declare``), from which
the integrators specialise their kernels.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace
from typing import Any, Callable, Hashable, MutableMapping

import numpy as np
import warp as wp

from warp_spt.accel.tlas import build_tlas
from warp_spt.emitters.base import emitting_rows
from warp_spt.emitters.registry import declare as declare_lights
from warp_spt.device.material_table import upload_materials
from warp_spt.bsdfs import declare
from warp_spt.device.proctex import MAX_PARAMS, ProcParams, features_key, instance_arrays
from warp_spt.media.registry import declare as declare_media
from warp_spt.media.upload import upload_media
from warp_spt.device.structs import (  # noqa: F401 (re-exported: the structs' old home)
    BVH_STACKS,
    Features,
    Geometry,
    Materials,
    Textures,
    vec_wide_f,
    vec_wide_i,
)
from warp_spt.upload.tangents import corner_tangents
from warp_spt.device.textures import pack_atlas
from warp_spt.accel.wide_bvh import MAX_TRIANGLES as WIDE_MAX_TRIANGLES
from warp_spt.accel.wide_bvh import WIDTH, WideBvh, build_wide
from warp_spt.runtime.memory import map_large_allocations
from warp_spt.runtime.warp_init import init_warp
from warp_spt.scene.model import TEX_CHECKER, TEX_PROC_BASE, Scene, column_range
from warp_spt.scene.validate import validate_scene

# Meshes of more triangles than this keep Warp's own BVH (wp.mesh_query_ray) instead of a wide BVH:
# every mesh the wide BVH can encode (its int32 leaf code). Its build is one compiled kernel plus a
# numpy collapse, about 1-2 us per triangle (benchmarks/bench_wide_build.py), and its traversal runs
# 1.7-1.9x Warp's query rate, so it pays for itself at every size.
WIDE_BVH_MAX_TRIANGLES = WIDE_MAX_TRIANGLES



# Triangles per leaf of each mesh's BVH (Warp's default is 4). Two traces the same hits (same triangle
# test, same order of visits for ties) 11-24% faster on the demo and bench_vs_mitsuba's rooms; 1 and 4
# are slower, 3 is no better (docs/performance.md, Where the time goes).
MESH_LEAF_SIZE = 2
# ... and of a mesh traced by our wide BVH, whose wp.Mesh only serves vertex look-ups (mesh_get_point)
# and is never queried: one leaf, Warp's tree is its root box (at 1M triangles 0.02 instead of 0.3-0.9
# CPU s, 14 instead of 64 MB).
WIDE_MESH_LEAF_SIZE = 1 << 30


@dataclass
class _Uploaded:
    """What a scene keeps of a wide BVH once its arrays are on the device."""

    stack_bound: int


@dataclass
class UploadedMesh:
    """One mesh on the device, its wide BVH (host arrays; None: the mesh uses Warp's BVH) and its
    float64 bounds (for the top-level BVH)."""

    mesh: wp.Mesh
    wide: WideBvh | None
    lower: np.ndarray
    upper: np.ndarray
    leaf_size: int = 0          # of the wp.Mesh's own BVH

    @classmethod
    def of(cls, m, device: str, wide: bool = True, alias: bool = False) -> "UploadedMesh":
        """``m`` uploaded, with its wide BVH built if ``wide``. ``alias``: on the CPU the wp.Mesh's
        points and indices are ``m``'s own float32 / int32 arrays, not copies (18 MB at a million
        triangles), for an upload that no cache keeps beyond its scene (nothing writes them: a mesh
        changed in place needs a new upload anyway, as its wide BVH does)."""
        # the tree first: its build's peak (binary and wide nodes at once) then holds no wp.Mesh arrays
        tree = _wide_tree(m) if wide else None
        share = alias and wp.get_device(device).is_cpu
        points = wp.array(np.ascontiguousarray(m.positions, dtype=np.float32), dtype=wp.vec3, device=device,
                          copy=not share)
        idx = wp.array(np.ascontiguousarray(m.indices, dtype=np.int32).reshape(-1), dtype=wp.int32, device=device,
                       copy=not share)
        used = np.zeros(len(m.positions), dtype=bool)
        used[m.indices.reshape(-1)] = True        # the used vertices' bounds without a per-corner copy
        p = m.positions[used] if not used.all() else m.positions
        leaf = MESH_LEAF_SIZE if not wide else WIDE_MESH_LEAF_SIZE
        mesh = wp.Mesh(points=points, indices=idx, bvh_constructor="sah" if not wide else "median", bvh_leaf_size=leaf)
        lo, hi = column_range(p)
        return cls(mesh, tree, lo.astype(np.float64), hi.astype(np.float64), leaf)


class DeviceScene:
    """A Scene on a Warp device. Keeps the Warp objects alive while kernels use them.

    ``meshes`` caches :class:`UploadedMesh` objects by :func:`mesh_key`: a mesh found there is reused
    instead of uploaded and rebuilt (animation frames share their static meshes), new ones are added, and
    ``mesh_keys`` lists this scene's keys so that the cache's owner can drop the ones no scene uses.
    Meshes of at most ``wide_bvh_max_triangles`` triangles are traced through a wide BVH of ours,
    larger ones through Warp's (0: every mesh through Warp's; the images are the same). The default,
    None, is ``WIDE_BVH_MAX_TRIANGLES`` on the CPU and 0 on a CUDA device: the wide BVH's eight-lane
    node test is laid out for a CPU's vector registers, while Warp's BVH has a CUDA traversal of its
    own (``benchmarks/gpu_check.py`` measures both on a GPU).
    """

    def __init__(self, scene: Scene, device: str = "cpu", meshes: MutableMapping[str, UploadedMesh] | None = None,
                 wide_bvh_max_triangles: int | None = None):
        if not isinstance(scene, Scene):
            raise TypeError(f"scene must be a warp_spt.Scene (from warp_spt.load_scene), got {type(scene).__name__}")
        map_large_allocations()       # a large mesh's freed temporaries go back to the system
        scene = flatten_emitters(scene)
        scene = scene.rounded()       # positions were float64 until now (recentring needs them): round once
        validate_scene(scene)
        init_warp()            # quietly, once, before the first Warp array (not at import time)
        self.device = device
        self.scene = scene
        self.features = _features(scene)
        self._meshes: list[wp.Mesh] = []
        self._wide: list[WideBvh | None] = []
        if wide_bvh_max_triangles is None:
            wide_bvh_max_triangles = 0 if wp.get_device(device).is_cuda else WIDE_BVH_MAX_TRIANGLES
        self._wide_limit = wide_bvh_max_triangles
        self._mesh_cache = meshes
        self._mesh_bounds: list[tuple[np.ndarray, np.ndarray]] = []
        self.mesh_keys: list[str] = []
        self.geometry = Geometry()
        self._upload_meshes(self.geometry, scene, device)
        self._upload_spheres_and_tlas(self.geometry, scene, device)
        b = scene.bounds
        self.geometry.extent = float(np.max(b[1] - b[0])) if np.all(np.isfinite(b)) else 1.0
        self.geometry.media, self._volumes = upload_media(scene, device)    # the grids' wp.Volumes, kept alive
        self.materials = upload_materials(scene.materials, device)
        self._atlas = _upload_atlas(scene, device)
        self.proc_kind, self.proc_params = _upload_procedural(scene, self.features.procedural, device)
        self._lights: dict = {}          # light tables per sky (warp_spt.emitters.light_table)

    def update_geometry(self, scene: Scene) -> None:
        """Upload ``scene``'s meshes and spheres in place of this scene's (its materials, textures and
        media stay; ``scene`` has this scene's materials): what a geometry parameter's change does
        (``warp_spt.diff.geometry_params``). A mesh whose float32 positions and triangles are unchanged
        keeps its wp.Mesh and BVH (the mesh cache's key, ``mesh_key``: an instance's new transforms
        only rebuild the top-level BVH); the light tables are rebuilt (area lights move)."""
        scene = scene.rounded()
        validate_scene(scene)
        kept = {key: UploadedMesh(mm, w, lo, hi) for key, mm, w, (lo, hi) in
                zip(self.mesh_keys, self._meshes, self._wide, self._mesh_bounds)
                if key and not isinstance(w, _Uploaded)}
        cache = self._mesh_cache if self._mesh_cache is not None else kept
        if self._mesh_cache is None and not kept:      # keys are only made with a cache: make one now
            cache = {}
        g = Geometry()
        media = self.geometry.media
        self.scene = scene
        self._meshes, self._wide, self._mesh_bounds, self.mesh_keys = [], [], [], []
        saved, self._mesh_cache = self._mesh_cache, cache
        try:
            self._upload_meshes(g, scene, self.device)
        finally:
            self._mesh_cache = saved
        self._upload_spheres_and_tlas(g, scene, self.device)
        b = scene.bounds
        g.extent = float(np.max(b[1] - b[0])) if np.all(np.isfinite(b)) else 1.0
        g.media = media
        self.geometry = g
        self.refresh_features()

    def light_cache(self, key: Hashable, build: Callable[[], Any]) -> Any:
        """What ``build()`` makes for ``key``, kept with this scene until :meth:`invalidate_lights`
        (the light tables of :func:`warp_spt.emitters.light_table`, per sky and up axis)."""
        if key not in self._lights:
            self._lights[key] = build()
        return self._lights[key]

    def invalidate_lights(self) -> None:
        """Forget the light tables: the scene's emission or textures changed."""
        self._lights.clear()

    def refresh_features(self) -> None:
        """Recompute the feature set from the host scene (after its materials changed) and forget
        the light tables built from the old values."""
        self.features = replace(_features(self.scene), bvh_stack=self.features.bvh_stack,
                                warp_meshes=self.features.warp_meshes)
        self.invalidate_lights()

    def atlas_arrays(self) -> tuple[wp.array, wp.array]:
        """(texels (N,) vec3, tiles (textures, 4) int32): the texture atlas on the device; write
        texels through ``assign`` (the arrays are shared with every Textures struct made from it)."""
        return self._atlas

    def atlas_tiles(self) -> np.ndarray:
        """The atlas's tile table on the host: (offset, w, h, stride) per texture."""
        return self._atlas[1].numpy()

    def textures(self, texture_filter: str = "nearest") -> Textures:
        """The atlas with the given filter ("nearest" or "bilinear")."""
        t = Textures()
        t.texels, t.tiles = self._atlas
        t.bilinear = int(texture_filter == "bilinear")
        t.proc_kind, t.proc_params = self.proc_kind, self.proc_params
        return t

    def _upload_meshes(self, s: Geometry, scene: Scene, device: str) -> None:
        offsets, mats, uvs, normals, tangents = [], [], [], [], []
        start = 0
        cache = self._mesh_cache
        for m in scene.meshes:
            key = mesh_key(m, device, placements=False) if cache is not None else ""
            wide = len(m.indices) <= self._wide_limit
            uploaded = cache.get(key) if cache is not None else None
            if uploaded is not None and not wide and uploaded.leaf_size != MESH_LEAF_SIZE:
                uploaded = None             # built for the wide BVH: Warp's tree is too coarse to trace
            if uploaded is None:
                uploaded = UploadedMesh.of(m, device, wide, alias=cache is None)
                if cache is not None:
                    cache[key] = uploaded
            elif wide and uploaded.wide is None:        # cached by a scene that traced it with Warp's BVH
                uploaded.wide = _wide_tree(m)
            self._meshes.append(uploaded.mesh)
            self._wide.append(uploaded.wide if wide else None)
            self._mesh_bounds.append((uploaded.lower, uploaded.upper))
            self.mesh_keys.append(key)
            offsets.append(start)
            start += len(m.indices)
            mats.append(m.face_material.astype(np.int32, copy=False))
            uvs.append(m.corner_uv.reshape(-1, 2).astype(np.float32, copy=False))
            if self.features.smooth:
                normals.append(_corner_normals(m).reshape(-1, 3))
            if self.features.needs("frame.uv"):
                tangents.append(corner_tangents(m.positions, m.indices, m.corner_uv, _corner_normals(m)).reshape(-1, 4))
        s.num_meshes = len(self._meshes)
        s.mesh_ids = _arr([mm.id for mm in self._meshes], wp.uint64, device, np.uint64)
        # without a cache nothing reads the host trees again once the device arrays hold them
        self._upload_wide(s, scene, device, release=cache is None)
        s.face_offset = _arr(offsets, wp.int32, device, np.int32)
        # several meshes' arrays are concatenated into fresh arrays: those become the device arrays
        fresh = len(scene.meshes) > 1
        s.face_material = _arr(_cat(mats, (0,), np.int32), wp.int32, device, np.int32, alias=fresh)
        s.corner_uv = _arr(_cat(uvs, (0, 2), np.float32), wp.vec2, device, np.float32, alias=fresh)
        s.corner_normal = _arr(_cat(normals, (0, 3), np.float32), wp.vec3, device, np.float32)
        s.has_corner_normals = int(self.features.smooth)
        s.corner_tangent = _arr(_cat(tangents, (0, 4), np.float32), wp.vec4, device, np.float32)
        s.has_corner_tangents = int(bool(tangents))
        s.corner_point = _arr(np.zeros((0, 3)), wp.vec3, device, np.float32)    # filled by gradients only
        s.has_corner_points = 0

    def _upload_wide(self, s: Geometry, scene: Scene, device: str, release: bool = False) -> None:
        """Concatenate the meshes' wide BVHs (node and triangle numbers offset per mesh), size the
        traversal stack (Features.bvh_stack) for the deepest, and note meshes left to Warp's BVH.
        ``release``: drop each host tree once copied (a scene without a mesh cache)."""
        wides = [(k, w) for k, w in enumerate(self._wide) if w is not None]
        bound = max((w.stack_bound for _, w in wides), default=0)
        stack = 0 if bound == 0 else next((n for n in BVH_STACKS if n >= bound), None)
        if stack is None:       # wide_bvh.DEPTH_BUDGET keeps stack_bound <= 337
            raise ValueError(f"a mesh's BVH is too deep: its traversal needs {bound} stack entries, more than "
                             f"{BVH_STACKS[-1]}")
        self.features = replace(self.features, bvh_stack=stack, warp_meshes=len(wides) < len(self._wide))
        roots = np.full(len(self._wide), -1, dtype=np.int32)
        corners = []
        if not wides:
            box, child, faces = np.zeros((0, WIDTH), np.float32), np.zeros((0, WIDTH), np.int32), np.zeros(0, np.int32)
        elif len(wides) == 1:             # one tree: its own arrays become the device arrays
            k, w = wides.pop()
            roots[k] = 0
            box, child, faces = w.box.reshape(-1, WIDTH), w.child, w.order
            corners.append((scene.meshes[k], w.order, 0))
            del w
        else:
            # The largest tree is stored first, in its own arrays where they have room for the others
            # (the collapse allocates its worst case, and pages it never wrote take no memory) and
            # belong to this scene alone (``release``): only the small trees are copied, after it.
            # Where there is no room, every tree is copied into place, each host tree dropped after
            # its copy (with ``release``) and before the corners are gathered. Node and triangle
            # numbers are offsets only: the hits do not depend on the order the trees are stored in.
            wides.sort(key=lambda kw: -len(kw[1].child))
            n_nodes = sum(len(w.child) for _, w in wides)
            n_tris = sum(len(w.order) for _, w in wides)
            first = wides[0][1]
            # (never a cached tree: other scenes share its arrays, with other trees after it)
            box = _grown(first.box.reshape(-1, WIDTH), 6 * n_nodes) if release else None
            child = _grown(first.child, n_nodes) if release else None
            own = box is not None and child is not None
            if not own:
                box = np.empty((6 * n_nodes, WIDTH), dtype=np.float32)
                child = np.empty((n_nodes, WIDTH), dtype=np.int32)
            del first
            faces = np.empty(n_tris, dtype=np.int32)
            nodes = tris = 0
            for i in range(len(wides)):
                k, w = wides[i]
                wides[i] = None
                n, t = len(w.child), len(w.order)
                roots[k] = nodes
                if not (own and i == 0):        # the first tree at offset 0 is where it is already
                    box[6 * nodes:6 * (nodes + n)] = w.box.reshape(-1, WIDTH)
                    child[nodes:nodes + n] = w.child_shifted(nodes, tris)
                faces[tris:tris + t] = w.order
                corners.append((scene.meshes[k], faces[tris:tris + t], tris))
                if release:
                    self._wide[k] = _Uploaded(w.stack_bound)
                del w
                nodes += n
                tris += t
        if release:
            self._wide = [None if w is None else _Uploaded(w.stack_bound) for w in self._wide]
        # every mesh's leaf-ordered corners gathered straight into one array (no per-mesh copies to join)
        tris = len(faces)
        v = np.empty((max(tris, 1), 3, 3), dtype=np.float32) if tris else np.zeros((0, 3, 3), np.float32)
        for m, order, first in corners:
            p, idx = np.asarray(m.positions, dtype=np.float32), np.asarray(m.indices)
            # in blocks, and mode="clip" (the indices were validated): with the default mode="raise",
            # np.take fills a temporary copy of ``out`` and copies it over (36 MB at a million triangles)
            for k in range(0, len(order), _GATHER_BLOCK):
                np.take(p, idx[order[k:k + _GATHER_BLOCK]], axis=0, mode="clip",
                        out=v[first + k:first + min(k + _GATHER_BLOCK, len(order))])
        # On the CPU these device arrays are the host arrays themselves (nothing else writes them): the
        # trees' own arrays, fresh corner copies and concatenations are not copied a second time.
        _set_arrays(s, device, alias=True, bvh_box=(box, vec_wide_f), bvh_child=(child, vec_wide_i),
                    mesh_root=(roots, wp.int32),
                    tri_v0=(v[:, 0], wp.vec3), tri_v1=(v[:, 1], wp.vec3), tri_v2=(v[:, 2], wp.vec3),
                    tri_face=(faces, wp.int32))

    def _upload_spheres_and_tlas(self, s: Geometry, scene: Scene, device: str) -> None:
        lowers, uppers = self._upload_instances(s, scene, device)
        sph = scene.spheres.astype(np.float64).reshape(-1, 4)
        lowers.extend(sph[:, :3] - sph[:, 3:4])
        uppers.extend(sph[:, :3] + sph[:, 3:4])
        self.tlas = build_tlas(np.asarray(lowers).reshape(-1, 3), np.asarray(uppers).reshape(-1, 3))
        t = self.tlas
        _set_arrays(s, device, spheres=(scene.spheres.reshape(-1, 4), wp.vec4),
                    sphere_material=(scene.sphere_material, wp.int32),
                    node_lower=(t.lower, wp.vec3), node_upper=(t.upper, wp.vec3),
                    node_left=(t.left, wp.int32), node_right=(t.right, wp.int32),
                    node_first=(t.first, wp.int32), node_count=(t.count, wp.int32), items=(t.items, wp.int32))


    def _upload_instances(self, s: Geometry, scene: Scene, device: str) -> tuple[list, list]:
        """The top-level mesh items' boxes; with instances (Features.instances) also their transforms:
        one item per placement of a mesh (an identity one for a mesh in world space)."""
        if not self.features.instances:
            # identity placements, one per mesh: a kernel compiled with instances (Features.general())
            # traces this scene too, with the same hits
            n = s.num_meshes
            s.num_instances = n
            eye = np.tile(np.eye(3, dtype=np.float32), (n, 1, 1))
            _set_arrays(s, device, inst_mesh=(np.arange(n, dtype=np.int32), wp.int32), inst_linear=(eye, wp.mat33),
                        inst_offset=(np.zeros((n, 3)), wp.vec3), inst_to_object=(eye, wp.mat33),
                        inst_to_object_offset=(np.zeros((n, 3)), wp.vec3), inst_normal=(eye, wp.mat33))
            return [lo for lo, _ in self._mesh_bounds], [hi for _, hi in self._mesh_bounds]
        mesh_of, xf = [], []
        for k, m in enumerate(scene.meshes):
            x = np.eye(4)[None] if m.transforms is None else np.asarray(m.transforms, np.float64)
            mesh_of.append(np.full(len(x), k, np.int32))
            xf.append(x)
        mesh_of, xf = np.concatenate(mesh_of), np.concatenate(xf)
        linear, offset = xf[:, :3, :3], xf[:, :3, 3]
        inv = np.linalg.inv(linear)
        # world boxes: each mesh box's corners mapped in float64, padded by the float32 rounding of the
        # ray's transform, so that no hit the object-space query finds lies outside its item's box
        lo = np.array([b[0] for b in self._mesh_bounds])[mesh_of]
        hi = np.array([b[1] for b in self._mesh_bounds])[mesh_of]
        corners = np.stack([np.where(np.array([(i >> a) & 1 for a in range(3)], bool), hi, lo) for i in range(8)], 1)
        world = np.einsum("nij,nkj->nki", linear, corners) + offset[:, None]
        wlo, whi = world.min(1), world.max(1)
        moved = ~np.all(xf == np.eye(4), axis=(1, 2))
        pad = np.where(moved[:, None], 1e-6 * (whi - wlo).max(1, keepdims=True)
                       + 1e-6 * np.abs(world).max(axis=(1, 2))[:, None], 0.0)
        s.num_instances = len(mesh_of)
        _set_arrays(s, device, inst_mesh=(mesh_of, wp.int32), inst_linear=(linear, wp.mat33),
                    inst_offset=(offset, wp.vec3), inst_to_object=(inv, wp.mat33),
                    inst_to_object_offset=(-np.einsum("nij,nj->ni", inv, offset), wp.vec3),
                    inst_normal=(np.transpose(inv, (0, 2, 1)), wp.mat33))
        return list(wlo - pad), list(whi + pad)


def flatten_emitters(scene: Scene) -> Scene:
    """``scene`` with every instanced mesh that emits light copied into world space, its placements
    joined into one mesh: the emissive-triangle light table samples world-space triangles (its areas
    and probabilities per face), so an emitter is never instanced; everything else stays shared."""
    if not scene.instanced:
        return scene
    emits = emitting_rows(scene)
    meshes: list = []
    for m in scene.meshes:
        if m.transforms is not None and emits[m.face_material].any():
            meshes.append(_joined(list(m.placed())))      # one world-space mesh: one BVH, not one per copy
        else:
            meshes.append(m)
    return replace(scene, meshes=meshes) if len(meshes) != len(scene.meshes) or any(
        a is not b for a, b in zip(meshes, scene.meshes)) else scene


def _joined(copies: list) -> Any:
    """World-space copies of one mesh (MeshData.placed) as a single mesh."""
    if len(copies) == 1:
        return copies[0]
    starts = np.cumsum([0] + [len(c.positions) for c in copies[:-1]])
    normals = None if copies[0].corner_normal is None else np.concatenate([c.corner_normal for c in copies])
    return replace(copies[0], positions=np.concatenate([c.positions for c in copies]),
                   indices=np.concatenate([c.indices + k for c, k in zip(copies, starts)]).astype(np.int32),
                   corner_uv=np.concatenate([c.corner_uv for c in copies]), corner_normal=normals,
                   face_material=np.concatenate([c.face_material for c in copies]))


def mesh_key(m, device: str = "cpu", placements: bool = True) -> str:
    """What a ``wp.Mesh`` is built from (float32 positions, int32 triangles, the device), hashed; with
    ``placements``, an instanced mesh's transforms too (a MeshData moved between animation frames is
    another MeshData to ship, while its ``wp.Mesh`` and BVH, cached by the key without them, stay)."""
    h = hashlib.sha256(str(device).encode())
    arrays = [(m.positions, np.float32), (m.indices, np.int32)]
    if placements and getattr(m, "transforms", None) is not None:
        arrays.append((m.transforms, np.float64))
    for a, dtype in arrays:
        a = np.ascontiguousarray(a, dtype=dtype)
        h.update(str(a.shape).encode())
        h.update(a.data)
    return h.hexdigest()


def _wide_tree(m) -> WideBvh:
    """Mesh ``m``'s wide BVH, over the float32 positions its wp.Mesh and the kernels use."""
    return build_wide(np.asarray(m.positions, dtype=np.float32), m.indices)


def _upload_atlas(scene: Scene, device: str) -> tuple[wp.array, wp.array]:
    atlas = pack_atlas(scene.textures)
    texels = wp.array(np.ascontiguousarray(atlas.texels, dtype=np.float32), dtype=wp.vec3, device=device)
    return texels, _arr(atlas.tiles, wp.vec4i, device, np.int32)


def _upload_procedural(scene: Scene, key: tuple, device: str) -> tuple[wp.array, wp.array]:
    """Per-instance kinds and parameter vectors (``proc_params`` is what parameter gradients flow into)."""
    kinds, params = instance_arrays(scene.procedural, key)
    return (_arr(kinds, wp.int32, device, np.int32),
            wp.array(params if len(params) else np.zeros((1, MAX_PARAMS), np.float32), dtype=ProcParams, device=device))


def _features(scene: Scene) -> Features:
    """Which code paths the scene's used materials, geometry, lights and media need: the materials'
    part declared by their kinds (``warp_spt.bsdfs.declare``), the lights' and the media's by theirs
    (``warp_spt.emitters.declare``, ``warp_spt.media.declare``)."""
    used = np.unique(np.concatenate([m.face_material for m in scene.meshes] + [scene.sphere_material]).astype(np.int64))
    empty = not len(used)       # an animation's frame that hides everything: every ray misses, and the
    if empty:                   # kernel of a sphere of the checker (the seed's kind of scene) traces it
        used = np.zeros(1, np.int64)
    mt = scene.materials
    tex = mt.tex[used]
    kinds, lobes, flags = declare(mt, used)
    base = Features(
        meshes=any(len(m.indices) for m in scene.meshes),
        spheres=len(scene.spheres) > 0 or empty,
        textures=bool((tex >= 0).any()),
        checker=bool((tex == TEX_CHECKER).any()),
        emitters=bool(emitting_rows(scene)[used].any()),
        smooth=any(m.corner_normal is not None for m in scene.meshes),
        procedural=features_key(scene.procedural[TEX_PROC_BASE - k].name for k in np.unique(tex[tex <= TEX_PROC_BASE])),
        material_kinds=kinds,
        lobes=lobes,
        material_flags=flags,
        media=declare_media(scene),
        instances=scene.instanced,
    )
    return replace(base, lights=declare_lights(scene, used, base))


def _corner_normals(m) -> np.ndarray:
    """Per-corner unit normals; meshes without vn get their flat face normal at every corner."""
    if m.corner_normal is not None:
        return m.corner_normal.astype(np.float32)
    p = m.positions[m.indices].astype(np.float64)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    return np.repeat(n[:, None, :], 3, axis=1).astype(np.float32)


def _grown(a: np.ndarray, rows: int) -> np.ndarray | None:
    """``a``'s first ``rows`` rows of the array it is the start of (a view, ``rows`` >= len(a)), or
    None when ``a`` is not the start of a C-contiguous array that long."""
    base = a.base
    while isinstance(base, np.ndarray) and base.base is not None and isinstance(base.base, np.ndarray):
        base = base.base
    if not isinstance(base, np.ndarray) or not base.flags.c_contiguous or not a.flags.c_contiguous:
        return None
    if base.dtype != a.dtype or base.__array_interface__["data"][0] != a.__array_interface__["data"][0]:
        return None
    row = a.itemsize * int(np.prod(a.shape[1:]))
    if row == 0 or base.nbytes < rows * row or not base.flags.writeable:
        return None
    return base.reshape(-1)[:rows * (row // a.itemsize)].reshape(rows, *a.shape[1:])


_GATHER_BLOCK = 1 << 16      # triangles per block of the leaf-ordered corner gather


def _cat(parts: list[np.ndarray], empty_shape: tuple[int, ...], dtype) -> np.ndarray:
    """The parts end to end (a single part as it is: no copy of a large mesh's array).

    Parts whose bits are all zero (the uv of a mesh without texture coordinates) are not copied: a
    fresh large array is zero pages that take no memory until written (24 MB at a million triangles)."""
    if len(parts) == 1:
        return parts[0].astype(dtype, copy=False)
    if not parts:
        return np.zeros(empty_shape, dtype)
    out = np.zeros((sum(len(p) for p in parts), *parts[0].shape[1:]), dtype)
    k = 0
    for p in parts:
        if _any_bit(p):
            out[k:k + len(p)] = p
        k += len(p)
    return out


def _any_bit(a: np.ndarray) -> bool:
    """Whether any bit of ``a`` is set (-0.0 counts: it is not +0.0's bits)."""
    a = np.ascontiguousarray(a)
    return bool(a.size) and bool(a.reshape(-1).view(f"u{a.dtype.itemsize}").any())


def _set_arrays(s, device: str, alias: bool = False, **fields: tuple) -> None:
    """Upload each ``name=(data, warp dtype)`` into the struct field of that name (``alias``: see _arr)."""
    for name, (data, dtype) in fields.items():
        np_dtype = np.int32 if getattr(dtype, "_wp_scalar_type_", dtype) is wp.int32 else np.float32
        setattr(s, name, _arr(data, dtype, device, np_dtype, alias))


def _arr(data, dtype, device: str, np_dtype, alias: bool = False) -> wp.array:
    """A device array; empty inputs become one zero element so no kernel sees a null pointer.

    ``alias``: on the CPU the Warp array is ``data`` itself (it keeps a reference), not a copy, for
    host arrays that nothing writes afterwards; Warp arrays carry strides, so a column of an (N, 3, 3)
    array needs no contiguous copy either."""
    a = np.asarray(data, dtype=np_dtype)
    if a.shape[0] == 0:
        a = np.zeros((1, *a.shape[1:]), dtype=np_dtype)
    if alias and wp.get_device(device).is_cpu and a.strides[-1] == a.itemsize:
        return wp.array(a, dtype=dtype, device=device, copy=False)
    return wp.array(np.ascontiguousarray(a), dtype=dtype, device=device)
