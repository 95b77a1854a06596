"""Meshes: primitives to triangles in world space (strips and fans converted), their attributes,
skins and morph targets, vertex colours (baked as PLY's are), and the triangles gathered into one
:class:`ObjData`."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace

import numpy as np

from warp_spt.gltf.document import _err
from warp_spt.gltf.materials import GltfMaterial, Materials
from warp_spt.scene.model import Material, ObjData, TextureRef
from warp_spt.scene.parts import ModelExtras, Part, gather
from warp_spt.scene.validate import MAX_COORDINATE

_MODES = {0: "points", 1: "lines", 2: "line loops", 3: "line strips", 4: "triangles", 5: "triangle strips",
          6: "triangle fans"}


@dataclass
class GltfExtras(ModelExtras):
    """What a glTF holds beyond triangles (``ObjData.extras``): :class:`ModelExtras`' cameras, lights,
    placed meshes and time range, and its material records and mesh placements as written."""

    materials: list[GltfMaterial] = field(default_factory=list)
    # every placement of a mesh: (node, mesh index, 4x4 world matrix)
    instances: list[tuple[int, int, np.ndarray]] = field(default_factory=list)


class Meshes(Materials):
    def _primitives(self, mesh: int) -> list[dict]:
        ptr = f"/meshes/{mesh}"
        prims = self.get(self.item("meshes", mesh), "primitives", list, ptr, required=True)
        for k, p in enumerate(prims):
            if not isinstance(p, dict):
                raise _err(self.path, f"{ptr}/primitives/{k}", "expected an object")
        return prims

    def _primitive(self, prim: dict, ptr: str, world: np.ndarray, mat: int | None, skin=None, weights=None):
        mode = self.get(prim, "mode", int, ptr, 4)
        if mode not in _MODES:
            raise _err(self.path, f"{ptr}/mode", f"unknown mode {mode}")
        if mode < 4:            # as importers do: the file's triangles are drawn, its points and lines not
            self.warn_once(ptr, f"{ptr}/mode: {_MODES[mode]} are skipped: warp_spt draws triangles (strips and "
                           "fans are converted)")
            return np.zeros((0, 3)), np.zeros((0, 3), np.int32), None, None, None
        attrs = self.obj(prim, "attributes", ptr, required=True)
        aptr = f"{ptr}/attributes"
        pos = self.accessor(self.index(attrs, "POSITION", aptr, "accessors", required=True), widths=("VEC3",))
        nv = len(pos)

        def attribute(name: str, width: str):
            k = self.index(attrs, name, aptr, "accessors")
            if k is None:
                return None
            a = self.accessor(k, widths=(width,))
            if len(a) != nv:
                raise _err(self.path, f"{aptr}/{name}", f"accessor {k} has {len(a)} elements; POSITION has {nv}")
            return a

        normals = attribute("NORMAL", "VEC3")
        colours = self._colours(attrs, aptr, nv, mat)
        if weights is not None:
            pos, normals = self._morph(prim, ptr, weights, pos, normals)
        if skin is not None:
            joints, inverse_bind, joint_worlds = skin
            pos, normals = self._skinned(attrs, aptr, nv, pos, normals, joint_worlds @ inverse_bind)
            world = np.eye(4)           # a skinned mesh is placed by its joints; its node's transform is ignored
        uv = attribute(f"TEXCOORD_{self._uv_set(mat)}", "VEC2")
        k = self.index(prim, "indices", ptr, "accessors")
        if k is None:
            idx = np.arange(nv, dtype=np.int64)
        else:
            a = self.item("accessors", k)
            if a.get("componentType") not in (5121, 5123, 5125) or a.get("normalized", False) is not False:
                raise _err(self.path, f"/accessors/{k}", "indices must be unsigned integers (5121, 5123 or 5125), "
                           "not normalized")
            idx = self.accessor(k, widths=("SCALAR",))
            if len(idx) and (idx.max() >= nv):
                raise _err(self.path, f"/accessors/{k}", f"index {int(idx.max())} is out of range: POSITION has {nv} "
                           "elements")
        tri = _triangles(idx, mode)
        if len(tri) == 0:
            return np.zeros((0, 3)), tri, None, None, None
        p = pos @ np.ascontiguousarray(world[:3, :3].T) + world[:3, 3] if not np.array_equal(world, np.eye(4)) else pos
        if not np.abs(p).max() <= MAX_COORDINATE:          # NaN too
            raise _err(self.path, ptr, f"a vertex lies at {np.abs(p).max():g}, beyond the supported range of "
                       f"+-{MAX_COORDINATE:g}")
        linear = world[:3, :3]
        if np.linalg.det(linear) < 0:
            tri = tri[:, ::-1].copy()
        n = None
        if normals is not None:
            inv_t = np.linalg.inv(linear).T if abs(np.linalg.det(linear)) > 0 else linear
            n = normals @ np.ascontiguousarray(inv_t.T)
            length = np.linalg.norm(n, axis=1, keepdims=True)
            n = np.where(length > 0, n / np.where(length > 0, length, 1), 0.0)
        if uv is not None:
            uv = self._uv_transform(uv, mat)
            uv = np.stack([uv[:, 0], 1.0 - uv[:, 1]], axis=1)
        return p, tri, uv, n, colours

    def _colours(self, attrs: dict, aptr: str, nv: int, mat: int | None) -> np.ndarray | None:
        """COLOR_0 (RGB; alpha dropped) times the material's base colour factor, or None. With a base
        colour texture it is ignored (the renderer's texture replaces the colour: no product)."""
        k = self.index(attrs, "COLOR_0", aptr, "accessors")
        if k is None:
            return None
        a = self.accessor(k, widths=("VEC3", "VEC4"))
        if len(a) != nv:
            raise _err(self.path, f"{aptr}/COLOR_0", f"accessor {k} has {len(a)} elements; POSITION has {nv}")
        if self._base_texture(mat) is not None:
            self.warnings.append(f"{self.path}: {aptr}/COLOR_0: vertex colours beside a base colour texture are "
                                 "ignored")
            return None
        factor = np.array(self._material_record(mat).base_color[:3]) if mat is not None else np.ones(3)
        return np.clip(a[:, :3] * factor, 0.0, 1.0)

    def _skin(self, node: dict, ptr: str, worlds: dict[int, np.ndarray]):
        """(joints, inverse bind matrices (J, 4, 4), the joints' world matrices (J, 4, 4)) or None."""
        k = self.index(node, "skin", ptr, "skins")
        if k is None:
            return None
        sptr = f"/skins/{k}"
        skin = self.item("skins", k)
        joints = self.get(skin, "joints", list, sptr, required=True)
        if not joints:
            raise _err(self.path, f"{sptr}/joints", "a skin needs at least one joint")
        for j, joint in enumerate(joints):
            if not isinstance(joint, int) or isinstance(joint, bool) or joint not in worlds:
                raise _err(self.path, f"{sptr}/joints/{j}", f"joint {json.dumps(joint)[:40]} is not a node of the "
                           "scene")
        ibm_k = self.index(skin, "inverseBindMatrices", sptr, "accessors")
        if ibm_k is None:
            ibm = np.tile(np.eye(4), (len(joints), 1, 1))
        else:
            if self.item("accessors", ibm_k).get("componentType") != 5126:
                raise _err(self.path, f"/accessors/{ibm_k}", "inverse bind matrices must be floats (5126)")
            m = self.accessor(ibm_k, widths=("MAT4",))
            if len(m) < len(joints):
                raise _err(self.path, f"/accessors/{ibm_k}", f"{len(m)} inverse bind matrices for {len(joints)} joints")
            ibm = m[:len(joints)].reshape(-1, 4, 4).transpose(0, 2, 1)       # column-major
        return joints, ibm, np.stack([worlds[j] for j in joints])

    def _skinned(self, attrs: dict, aptr: str, nv: int, pos: np.ndarray, normals, joint_matrices: np.ndarray):
        """Linear blend skinning: each vertex by the weighted sum of its joints' matrices (weights
        normalised to sum 1; a vertex without weight stays put); normals by its inverse transpose."""
        out_n = None
        sets = 0
        while f"JOINTS_{sets}" in attrs and f"WEIGHTS_{sets}" in attrs:
            sets += 1
        if sets == 0:
            raise _err(self.path, aptr, "a skinned mesh needs JOINTS_0 and WEIGHTS_0")
        total = np.zeros(nv)
        blended = np.zeros((nv, 4, 4))
        for s in range(sets):
            kj = self.index(attrs, f"JOINTS_{s}", aptr, "accessors", required=True)
            if self.item("accessors", kj).get("componentType") not in (5121, 5123):
                raise _err(self.path, f"/accessors/{kj}", "joint indices must be unsigned bytes or shorts")
            joints = self.accessor(kj, widths=("VEC4",)).astype(np.int64)
            w = self.accessor(self.index(attrs, f"WEIGHTS_{s}", aptr, "accessors", required=True), widths=("VEC4",))
            if len(joints) != nv or len(w) != nv:
                raise _err(self.path, f"{aptr}/JOINTS_{s}", f"joints and weights need {nv} elements (POSITION's)")
            if joints.max() >= len(joint_matrices) or joints.min() < 0:
                raise _err(self.path, f"/accessors/{kj}", f"joint index {int(joints.max())} is out of range: the skin "
                           f"has {len(joint_matrices)} joints")
            w = np.maximum(w, 0.0)
            blended += np.einsum("nc,ncij->nij", w, joint_matrices[joints])
            total += w.sum(1)
        ok = total > 0
        blended[ok] /= total[ok, None, None]
        blended[~ok] = np.eye(4)        # unweighted vertices stay where they are
        out_p = np.einsum("nij,nj->ni", blended[:, :3, :3], pos) + blended[:, :3, 3]
        if normals is not None:
            inv_t = np.linalg.inv(blended[:, :3, :3] + np.where(
                np.abs(np.linalg.det(blended[:, :3, :3]))[:, None, None] > 0, 0, np.eye(3))).transpose(0, 2, 1)
            out_n = np.einsum("nij,nj->ni", inv_t, normals)
        return out_p, out_n

    def _morph_weights(self, node: dict, ptr: str, mesh: int, animated) -> np.ndarray | None:
        """The morph target weights of a node's mesh: animated, else the node's, else the mesh's."""
        if animated is not None and self.time is not None:
            return np.asarray(animated(self.time), np.float64)
        w = self.get(node, "weights", list, ptr)
        where = f"{ptr}/weights"
        if w is None:
            w = self.get(self.item("meshes", mesh), "weights", list, f"/meshes/{mesh}")
            where = f"/meshes/{mesh}/weights"
        if w is None:
            return None
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in w):
            raise _err(self.path, where, "expected finite numbers")
        return np.asarray(w, np.float64)

    def _morph(self, prim: dict, ptr: str, weights: np.ndarray, pos: np.ndarray, normals):
        """Positions (and normals) plus the weighted morph target displacements."""
        targets = self.get(prim, "targets", list, ptr, [])
        if len(targets) != len(weights):
            raise _err(self.path, f"{ptr}/targets", f"{len(targets)} morph targets for {len(weights)} weights")
        pos = pos.copy()
        normals = None if normals is None else normals.copy()
        for t, (target, w) in enumerate(zip(targets, weights)):
            tptr = f"{ptr}/targets/{t}"
            if not isinstance(target, dict):
                raise _err(self.path, tptr, "expected an object")
            for name, base in (("POSITION", pos), ("NORMAL", normals)):
                k = self.index(target, name, tptr, "accessors")
                if k is None or base is None or w == 0:
                    continue
                d = self.accessor(k, widths=("VEC3",))
                if len(d) != len(base):
                    raise _err(self.path, f"{tptr}/{name}", f"accessor {k} has {len(d)} elements; the base has "
                               f"{len(base)}")
                base += w * d
        return pos, normals

    def _targets_of_node(self, node: int) -> int:
        mesh = self.index(self.item("nodes", node), "mesh", f"/nodes/{node}", "meshes")
        if mesh is None:
            return 0
        prims = self._primitives(mesh)
        targets = self.get(prims[0], "targets", list, f"/meshes/{mesh}/primitives/0", []) if prims else []
        return len(targets)

    # ----------------------------------------------------------------------------------- the object

    def _object(self, parts: list[tuple], names: list[str], materials: dict[str, Material], extras: GltfExtras
                ) -> ObjData:
        data, kept = gather(self.path, [Part(p, tri, uv, n, c, row) for p, tri, uv, n, c, row in parts], names,
                            materials, extras, self.warnings)
        shown = [(part[0], part[4], nf) for part, nf in zip(parts, kept) if nf is not None]
        if any(c is not None for _, c, _ in shown):
            from warp_spt.io.ply import colour_texture_fits, colour_texture_note

            coloured = sum(nf for _, c, nf in shown if c is not None)
            if colour_texture_fits(coloured):
                self._bake_colours(data, [p for p, _, _ in shown], [(c, nf) for _, c, nf in shown])
            else:
                data.warnings.append(colour_texture_note(self.path, coloured))
        return data

    def _bake_colours(self, data: ObjData, positions: list[np.ndarray], cols: list) -> None:
        """Vertex colours as PLY's are (io.ply.vertex_colour_texture): one texture for the file, its
        coloured triangles moved to a variant of their material that names it."""
        from warp_spt.io.ply import vertex_colour_texture

        per_vertex = np.zeros((len(data.positions), 3))
        coloured = np.zeros(len(data.faces), bool)
        v = f = 0
        for p, (c, nf) in zip(positions, cols):
            if c is not None:
                per_vertex[v:v + len(p)] = c
                coloured[f:f + nf] = True
            v, f = v + len(p), f + nf
        uv, ft, image = vertex_colour_texture(per_vertex, data.faces[coloured])
        ref = TextureRef("vertex-colours", self.path, 0, image=image)
        variant: dict[int, int] = {}
        for row in np.unique(data.face_material[coloured]).tolist():
            base = data.materials[data.material_names[row]]
            name = f"{base.name} (vertex colours)"
            data.materials[name] = replace(base, name=name, base_color=(1.0, 1.0, 1.0), base_color_map=ref)
            variant[row] = len(data.material_names)
            data.material_names.append(name)
            data.material_lines.append(0)
        lut = np.arange(len(data.material_names), dtype=np.int32)
        lut[list(variant)] = list(variant.values())
        data.face_material[coloured] = lut[data.face_material[coloured]]
        data.face_texcoords[coloured] = ft + len(data.texcoords)
        data.texcoords = np.concatenate([data.texcoords, uv]).astype(np.float32)


def _triangles(idx: np.ndarray, mode: int) -> np.ndarray:
    """(F, 3) int32 triangles of an index list in mode 4 (list), 5 (strip) or 6 (fan)."""
    n = len(idx)
    if mode == 4:
        return idx[:n - n % 3].reshape(-1, 3).astype(np.int32)
    if n < 3:
        return np.zeros((0, 3), np.int32)
    i = np.arange(n - 2)
    if mode == 5:       # glTF: triangle i is (i, i+1, i+2) for even i and (i+1, i, i+2) for odd i
        odd = (i % 2) == 1
        tri = np.stack([np.where(odd, idx[i + 1], idx[i]), np.where(odd, idx[i], idx[i + 1]), idx[i + 2]], axis=1)
    else:               # fan: (i+1, i+2, 0)
        tri = np.stack([idx[i + 1], idx[i + 2], np.full(n - 2, idx[0])], axis=1)
    tri = tri[(tri[:, 0] != tri[:, 1]) & (tri[:, 1] != tri[:, 2]) & (tri[:, 0] != tri[:, 2])]
    return tri.astype(np.int32)
