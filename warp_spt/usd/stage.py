"""The stage walk: every prim drawn at one time code, in metres and Y up.

Prims whose purpose is ``guide`` or ``proxy`` are skipped (the render purpose is drawn over the
proxy), as are invisible ones. Transforms come from UsdGeom's xform cache (so ``resetXformStack``
holds). A mesh under a native instance (an instanceable prim's prototype) or a PointInstancer's
prototype is read once in the prototype's space and placed once per instance (``ModelExtras.placed``:
the TLAS's instances, no copies); other meshes are flattened into world space. The stage's
``upAxis`` Z is turned to Y up and its ``metersPerUnit`` applied, by one matrix at the root.
Whatever is not read is one warning naming the prim path."""

from __future__ import annotations

import math

import numpy as np

from warp_spt.scene.errors import SceneError
from warp_spt.scene.model import CHECKER_NAME, ObjData
from warp_spt.scene.parts import ModelExtras, Part, gather
from warp_spt.usd import lights_cameras as lc
from warp_spt.usd import shapes
from warp_spt.usd.assets import locate, package_bytes
from warp_spt.usd.materials import Materials
from warp_spt.usd.meshes import corner_values, triangulate

MAX_INSTANCE_COLOURS = 64     # a PointInstancer's colours drawn apart (each one more mesh in the TLAS)
# the prim types that are read; any other typed prim that is not a grouping warns once
_GROUPS = {"Xform", "Scope", "", "Material", "Shader", "NodeGraph", "GeomSubset", "Skeleton", "SkelRoot"}


def _uniform_scale(m: np.ndarray) -> float | None:
    """s where ``m`` is s times a rotation (a sphere stays a sphere), else None."""
    s = abs(np.linalg.det(m)) ** (1.0 / 3.0)
    if not s > 0 or not np.allclose(m.T @ m, np.eye(3) * s * s, rtol=0.0, atol=1e-9 * s * s):
        return None
    return float(s)


def _matrix(m) -> np.ndarray:
    """A Gf.Matrix4d (row vectors, p' = p M) as a column-vector 4x4 matrix."""
    return np.array(m, np.float64).reshape(4, 4).T


class Reader:
    def __init__(self, stage, path: str, seconds: float | None) -> None:
        from pxr import Usd, UsdGeom

        self.stage, self.path = stage, path
        start, end = stage.GetStartTimeCode(), stage.GetEndTimeCode()
        self.tcps = stage.GetTimeCodesPerSecond() or 24.0
        self.animated = stage.HasAuthoredTimeCodeRange() and end > start
        # frame k at k / fps seconds is time code start + seconds * timeCodesPerSecond
        self.time = Usd.TimeCode(start + seconds * self.tcps) if seconds is not None and self.animated else \
            (Usd.TimeCode(start) if self.animated else Usd.TimeCode.Default())
        self.time_range = (0.0, (end - start) / self.tcps) if self.animated else None
        self.cache = UsdGeom.XformCache(self.time)
        # metersPerUnit only where authored: its fallback is centimetres, but unmarked stages are mostly in
        # metres (the units of glTF, Newton and Warp's renderer); the first view frames the scene either way
        mpu = UsdGeom.GetStageMetersPerUnit(stage) if UsdGeom.StageHasAuthoredMetersPerUnit(stage) else 1.0
        root = np.eye(4) * float(mpu or 1.0)
        root[3, 3] = 1.0
        if UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z:          # (x, y, z) -> (x, z, -y)
            root = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1]], np.float64) @ root
        self.root = root
        self.warnings: list[str] = []
        self._warned: set[tuple[str, str]] = set()
        self.names = [CHECKER_NAME]
        self.materials = Materials(path, self.warn)
        self.parts: list[Part] = []
        self.spheres: list[tuple] = []
        self.extras = ModelExtras(time_range=self.time_range)
        self.placed: dict[str, tuple[list[Part], list[np.ndarray]]] = {}
        self.instancer_row = 0          # the row of the PointInstancer's displayColor while its prototypes are read

    def warn(self, prim: str, message: str) -> None:
        if (prim, message) not in self._warned:
            self._warned.add((prim, message))
            self.warnings.append(f"{self.path}: {message}")

    def world(self, prim) -> np.ndarray:
        return self.root @ _matrix(self.cache.GetLocalToWorldTransform(prim))

    def run(self) -> ObjData:
        self._walk(self.stage.GetPseudoRoot(), None, None)
        for key, (parts, xf) in self.placed.items():
            if not xf:
                continue
            sub, _ = gather(f"{self.path}#{key}", parts, self.names, self.materials.materials, ModelExtras(), [])
            live = [x for x in xf if abs(np.linalg.det(x[:3, :3])) > 1e-30]
            self.extras.hidden += len(xf) - len(live)
            if len(sub.faces) and live:
                self.extras.placed.append((sub, np.stack(live)))
        out, _ = gather(self.path, self.parts, self.names, self.materials.materials, self.extras, self.warnings)
        if self.spheres:
            out.spheres = np.array([s[:4] for s in self.spheres], np.float64)
            out.sphere_material = np.array([s[4] for s in self.spheres], np.int32)
        return out

    def _walk(self, prim, proto_root, placements) -> None:
        """Draw ``prim``'s subtree. Under a prototype, ``proto_root`` is the prim whose space the
        prototype's meshes are read in and ``placements`` the world matrices of its instances."""
        from pxr import UsdGeom, UsdLux

        for child in prim.GetFilteredChildren(_predicate()):
            where = str(child.GetPath())
            img = UsdGeom.Imageable(child)
            if img:
                purpose = img.ComputePurpose()
                if purpose in (UsdGeom.Tokens.guide, UsdGeom.Tokens.proxy):
                    continue
                if img.ComputeVisibility(self.time) == UsdGeom.Tokens.invisible:
                    continue
            if child.IsInstance():
                proto = child.GetPrototype()
                world = self.world(child) if placements is None else None
                here = [world] if world is not None else [p @ self._relative(child, proto_root) for p in placements]
                self._walk(proto, proto, here)
                continue
            kind = child.GetTypeName()
            if child.IsA(UsdGeom.PointInstancer):
                self._point_instancer(child, proto_root, placements)
                continue
            if child.IsA(UsdGeom.Mesh):
                self._mesh(child, proto_root, placements)
            elif _is_shape(child):
                self._shape(child, proto_root, placements)
            elif child.IsA(UsdGeom.Camera):
                if placements is None:
                    self.extras.cameras.append(lc.camera(child, self.world(child), len(self.extras.cameras),
                                                         self.time, self.path))
            elif child.HasAPI(UsdLux.LightAPI):
                if placements is None:
                    self._light(child)
                else:
                    self.warn(where, f"{where}: a light inside an instance is not read")
            elif child.IsA(UsdGeom.Gprim):
                self.warn(where, f"{where}: {kind} prims are not read (meshes are)")
            elif kind not in _GROUPS and not child.IsA(UsdGeom.Xformable):
                self.warn(where, f"{where}: {kind} prims are not read")
            self._walk(child, proto_root, placements)

    def _relative(self, prim, proto_root) -> np.ndarray:
        """``prim``'s transform in ``proto_root``'s space (the prototype's root has none of its own)."""
        m = _matrix(self.cache.GetLocalToWorldTransform(prim))
        if proto_root is None:
            return self.root @ m
        return np.linalg.inv(_matrix(self.cache.GetLocalToWorldTransform(proto_root))) @ m

    def _point_instancer(self, prim, proto_root, placements) -> None:
        from pxr import UsdGeom

        where = str(prim.GetPath())
        pi = UsdGeom.PointInstancer(prim)
        xforms = pi.ComputeInstanceTransformsAtTime(self.time, self.time)
        indices = np.asarray(pi.GetProtoIndicesAttr().Get(self.time) or [], np.int64)
        targets = pi.GetPrototypesRel().GetTargets()
        if len(indices) and (indices.min() < 0 or indices.max() >= len(targets)):
            raise SceneError(self.path, 0, f"{where}: protoIndices names prototype {int(indices.max())}, but it has "
                             f"{len(targets)} prototypes")
        outer_row = self.instancer_row
        rows = self._instance_rows(prim, len(indices), outer_row)
        base = self.world(prim) if placements is None else None
        outer = [base] if base is not None else [p @ self._relative(prim, proto_root) for p in placements]
        for k, target in enumerate(targets):
            proto = self.stage.GetPrimAtPath(target)
            if not proto:
                raise SceneError(self.path, 0, f"{where}: prototype {target} does not exist")
            picked = np.flatnonzero(indices == k)
            # the prototype read once per colour its instances are drawn in (unbound prototypes take it)
            for row in np.unique(rows[picked]).tolist():
                own = _matrix(UsdGeom.Xformable(proto).GetLocalTransformation(self.time))
                mine = [outer_m @ _matrix(xforms[i]) @ own for outer_m in outer
                        for i in picked[rows[picked] == row].tolist()]
                self.instancer_row = row
                # the prototype prim's own transform is part of each instance's; its meshes in its space
                if proto.IsA(UsdGeom.Mesh):
                    self._mesh(proto, proto, mine)
                elif _is_shape(proto):
                    self._shape(proto, proto, mine)
                self._walk(proto, proto, mine)
        self.instancer_row = outer_row

    def _instance_rows(self, prim, count: int, outer_row: int) -> np.ndarray:
        """(count,) the row each instance of a PointInstancer is drawn in where its prototype has no
        material or colour of its own: the instancer's displayColor, one per instance where it has one per
        instance and at most MAX_INSTANCE_COLOURS of them (else its mean, with a warning), else the
        enclosing instancer's row."""
        values = self._display_colours(prim)
        if values is None:
            return np.full(count, outer_row, np.int32)
        if len(values) == count and count > 1:
            codes, inverse = np.unique(np.round(np.clip(values, 0.0, 1.0) * 255.0), axis=0, return_inverse=True)
            if len(codes) <= MAX_INSTANCE_COLOURS:
                rows = [self.materials.display(tuple(float(c) for c in values[inverse.ravel() == j].mean(axis=0)),
                                               self.names) for j in range(len(codes))]
                return np.asarray(rows, np.int32)[inverse.ravel()]
            where = str(prim.GetPath())
            self.warn(where, f"{where}: displayColor has {len(codes)} colours over its instances, more than "
                      f"{MAX_INSTANCE_COLOURS}: drawn in their mean colour")
            return np.full(count, self.materials.display(tuple(float(c) for c in values.mean(axis=0)), self.names),
                           np.int32)
        return np.full(count, self._display_row(prim), np.int32)

    def _mesh(self, prim, proto_root, placements) -> None:
        from pxr import UsdGeom, UsdShade

        where = str(prim.GetPath())
        mesh = UsdGeom.Mesh(prim)
        t = self.time
        points = np.asarray(mesh.GetPointsAttr().Get(t) or [], np.float64).reshape(-1, 3)
        counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(t) or [], np.int64)
        indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(t) or [], np.int64)
        holes = np.asarray(mesh.GetHoleIndicesAttr().Get(t) or [], np.int64)
        left = mesh.GetOrientationAttr().Get(t) == UsdGeom.Tokens.leftHanded
        tri, corners, face = self._triangles(points, counts, indices, holes, left, where)
        if not len(tri):
            return
        scheme = mesh.GetSubdivisionSchemeAttr()
        # only an authored scheme: its fallback is catmullClark, which exporters of polygon meshes leave unset
        if scheme.HasAuthoredValue() and scheme.Get(t) != UsdGeom.Tokens.none:
            self.warn(where, f"{where}: subdivisionScheme {scheme.Get(t)} is not applied: drawn as its control cage")
        api = UsdGeom.PrimvarsAPI(prim)
        uv = uv_index = normals = normal_index = None
        st = api.GetPrimvar("st")
        if st and st.HasValue():
            uv, uv_index = self._primvar(st, corners, face, indices, where, "primvars:st")
        pn = api.GetPrimvar("normals")
        if pn and pn.HasValue():
            normals, normal_index = self._primvar(pn, corners, face, indices, where, "primvars:normals")
        elif mesh.GetNormalsAttr().HasValue():
            normals, normal_index = corner_values(np.asarray(mesh.GetNormalsAttr().Get(t), np.float64).reshape(-1, 3),
                                                  mesh.GetNormalsInterpolation(), corners, face, indices,
                                                  self.path, f"{where}.normals")
        rows = np.full(len(counts), self._row(prim), np.int32)
        for subset in UsdGeom.Subset.GetAllGeomSubsets(mesh):
            if subset.GetFamilyNameAttr().Get() != "materialBind":
                continue
            bound = UsdShade.MaterialBindingAPI(subset.GetPrim()).ComputeBoundMaterial()[0]
            faces = np.asarray(subset.GetIndicesAttr().Get(t) or [], np.int64)
            if len(faces) and (faces.min() < 0 or faces.max() >= len(counts)):
                raise SceneError(self.path, 0, f"{subset.GetPath()}: face {int(faces.max())} is out of range: the "
                                 f"mesh has {len(counts)} faces")
            rows[faces] = self.materials.row(bound if bound else None, self.names) if bound else rows[faces]
        self._place(prim, proto_root, placements, points, tri, uv, uv_index, normals, normal_index, face, rows)

    def _triangles(self, points, counts, indices, holes, left, where):
        try:
            tri, corners, face = triangulate(points, counts, indices, holes, left, where)
        except SceneError as err:
            raise SceneError(self.path, 0, err.message if err.path is None else f"{where}: {err.message}") from None
        if len(tri) and not np.isfinite(points).all():
            raise SceneError(self.path, 0, f"{where}: the points are not finite")
        return tri, corners, face

    def _shape(self, prim, proto_root, placements) -> None:
        """An implicit shape: an exact sphere where nothing instances or stretches it, else polygons."""
        from pxr import UsdGeom

        where = str(prim.GetPath())
        row = self._row(prim)

        def size(attr, name):
            v = float(attr.Get(self.time))
            if not (math.isfinite(v) and v >= 0):
                raise SceneError(self.path, 0, f"{where}: {name} must be finite and not negative, got {v:g}")
            return v

        normals = None
        if prim.IsA(UsdGeom.Sphere):
            radius = size(UsdGeom.Sphere(prim).GetRadiusAttr(), "radius")
            world = self.world(prim) if placements is None else None
            scale = None if world is None else _uniform_scale(world[:3, :3])
            if scale is not None:
                if radius * scale > 0:
                    self.spheres.append((*(float(c) for c in world[:3, 3]), radius * scale, row))
                return
            points, counts, indices, normals = shapes.sphere(radius)
        elif prim.IsA(UsdGeom.Cube):
            points, counts, indices = shapes.cube(size(UsdGeom.Cube(prim).GetSizeAttr(), "size"))
        else:
            kind = next(k for k in (UsdGeom.Capsule, UsdGeom.Cylinder, UsdGeom.Cone) if prim.IsA(k))
            shape = kind(prim)
            make = {UsdGeom.Capsule: shapes.capsule, UsdGeom.Cylinder: shapes.cylinder, UsdGeom.Cone: shapes.cone}[kind]
            points, counts, indices = make(size(shape.GetRadiusAttr(), "radius"), size(shape.GetHeightAttr(), "height"),
                                           str(shape.GetAxisAttr().Get(self.time)))
        tri, corners, face = self._triangles(points, counts, indices, np.zeros(0, np.int64), False, where)
        normal_index = None if normals is None else tri
        self._place(prim, proto_root, placements, points, tri, None, None, normals, normal_index, face,
                    np.full(len(counts), row, np.int32))

    def _place(self, prim, proto_root, placements, points, tri, uv, uv_index, normals, normal_index, face,
               rows) -> None:
        """A prim's triangles into world space, or (under instances) once into its prototype's space."""
        where = str(prim.GetPath())
        if placements is None:
            world = self.world(prim)
            p = points @ world[:3, :3].T + world[:3, 3]
            if np.linalg.det(world[:3, :3]) < 0:            # a mirroring transform keeps the faces' side
                tri, uv_index, normal_index = (None if a is None else a[:, ::-1] for a in (tri, uv_index, normal_index))
            if normals is not None:
                normals = normals @ np.linalg.inv(world[:3, :3])      # the inverse transpose, row vectors
            self._add(self.parts, p, tri, uv, uv_index, normals, normal_index, face, rows)
            return
        key = where if self.instancer_row == 0 else f"{where} (row {self.instancer_row})"
        if key not in self.placed:
            local = self._relative(prim, proto_root) if proto_root is not None and prim != proto_root else np.eye(4)
            p = points @ local[:3, :3].T + local[:3, 3]
            if normals is not None:
                normals = normals @ np.linalg.inv(local[:3, :3])
            self.placed[key] = ([], [])
            self._add(self.placed[key][0], p, tri, uv, uv_index, normals, normal_index, face, rows)
        self.placed[key][1].extend(placements)

    def _row(self, prim) -> int:
        """The material row of a gprim: its bound material, else its displayColor (as Hydra draws an
        unbound prim), else that of the PointInstancer it is a prototype of, else the default (row 0)."""
        bound = self._bound(prim)
        if bound is not None:
            return self.materials.row(bound, self.names)
        own = self._display_row(prim)
        return self.instancer_row if own is None else own

    def _display_colours(self, prim) -> np.ndarray | None:
        """(N, 3) the values of ``prim``'s displayColor primvar, None if it has none."""
        from pxr import UsdGeom

        pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
        if not pv or not pv.HasValue():
            return None
        values = np.asarray(pv.ComputeFlattened(self.time) or [], np.float64).reshape(-1, 3)
        if not np.isfinite(values).all():
            raise SceneError(self.path, 0, f"{prim.GetPath()}.primvars:displayColor: the colours are not finite")
        return values if len(values) else None

    def _display_row(self, prim) -> int | None:
        """The row of ``prim``'s displayColor primvar (its mean where it varies), None if it has none."""
        values = self._display_colours(prim)
        if values is None:
            return None
        if len(values) > 1 and np.ptp(values, axis=0).max() > 0:
            where = str(prim.GetPath())
            self.warn(where, f"{where}: displayColor varies over the prim: drawn in its mean colour")
        return self.materials.display(tuple(float(c) for c in values.mean(axis=0)), self.names)

    @staticmethod
    def _add(out: list, p, tri, uv, uv_index, normals, normal_index, face, rows) -> None:
        if normals is not None:
            length = np.linalg.norm(normals, axis=1, keepdims=True)
            normals = np.where(length > 0, normals / np.where(length > 0, length, 1.0), 0.0)
        for row in np.unique(rows[face]).tolist():
            pick = rows[face] == row
            out.append(Part(p, tri[pick], None if uv is None else uv.astype(np.float32),
                            None if normals is None else normals.astype(np.float32), None, int(row),
                            None if uv_index is None else uv_index[pick],
                            None if normal_index is None else normal_index[pick]))

    def _primvar(self, pv, corners, face, indices, where, name):
        values = np.asarray(pv.ComputeFlattened(self.time), np.float64)
        values = values.reshape(len(values), -1)
        interp = pv.GetInterpolation()
        return corner_values(values, interp, corners, face, indices, self.path, f"{where}.{name}")

    @staticmethod
    def _bound(prim):
        from pxr import UsdShade

        m = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()[0]
        return m if m else None

    def _light(self, prim) -> None:
        from pxr import UsdLux

        where = str(prim.GetPath())
        world = self.world(prim)
        if prim.IsA(UsdLux.DistantLight):
            self.extras.lights.append(lc.distant(prim, world, self.time))
        elif prim.IsA(UsdLux.SphereLight):
            s = UsdLux.SphereLight(prim)
            r = float(s.GetRadiusAttr().Get(self.time) or 0.5)
            scale = abs(np.linalg.det(world[:3, :3])) ** (1.0 / 3.0)
            radiance = lc.radiance(s.LightAPI(), self.time)
            if s.GetTreatAsPointAttr().Get(self.time) or r * scale <= 0:
                from warp_spt.scene.lights import PointLight

                # a sphere of radiance L sends L * pi r^2 W/sr each way: the point light of the same power
                area = math.pi * (r * scale) ** 2 if r * scale > 0 else 1.0
                self.extras.lights.append(lc.UsdLight(where, PointLight(
                    position=tuple(float(c) for c in world[:3, 3]), intensity=tuple(c * area for c in radiance),
                    name=prim.GetName())))
                return
            if lc.normalized(s.LightAPI(), self.time):
                radiance = tuple(c / (4.0 * math.pi * (r * scale) ** 2) for c in radiance)
            row = self.materials.emitter(f"{where} (sphere light)", radiance, self.names)
            self.spheres.append((*(float(c) for c in world[:3, 3]), r * scale, row))
        elif prim.IsA(UsdLux.RectLight) or prim.IsA(UsdLux.DiskLight):
            if prim.IsA(UsdLux.RectLight) and UsdLux.RectLight(prim).GetTextureFileAttr().Get(self.time):
                self.warn(where, f"{where}: a rect light's texture is not read: drawn in its colour")
            pts, tri, area = lc.area_surface(prim, self.time)
            radiance = lc.radiance(UsdLux.LightAPI(prim), self.time)
            p = pts @ world[:3, :3].T + world[:3, 3]
            if lc.normalized(UsdLux.LightAPI(prim), self.time):
                radiance = tuple(c / (area * abs(np.linalg.det(world[:3, :3])) ** (2.0 / 3.0)) for c in radiance)
            row = self.materials.emitter(f"{where} (area light)", radiance, self.names)
            self.parts.append(Part(p, tri, row=row))
        elif prim.IsA(UsdLux.DomeLight):
            self._dome(prim)
        else:
            self.warn(where, f"{where}: {prim.GetTypeName()} lights are not read")

    def _dome(self, prim) -> None:
        from pxr import UsdLux

        from warp_spt.scene.sky import Sky

        where = str(prim.GetPath())
        dome = UsdLux.DomeLight(prim)
        radiance = lc.radiance(dome.LightAPI(), self.time)
        asset = dome.GetTextureFileAttr().Get(self.time)
        if asset is None or not asset.path:
            self.extras.sky = Sky.constant(*radiance)
            return
        if not asset.resolvedPath:
            self.warn(where, f"{where}: the dome light's texture {asset.path!r} is not found: a constant sky of "
                      "its colour stands for it")
            self.extras.sky = Sky.constant(*radiance)
            return
        name, packaged, refused = locate(asset.resolvedPath, self.path, "dome light texture")
        if refused:
            raise SceneError(self.path, 0, f"{where}: {refused}")
        from warp_spt.images.environment import read_environment_image
        from warp_spt.scene.environment import EnvironmentMap

        strength = max(radiance) if max(radiance) > 0 else 0.0
        if len(set(radiance)) > 1:
            self.warn(where, f"{where}: the dome light's colour tints are not read: its brightest channel scales "
                      "the map")
        note = lambda m: self.warn(where, m)           # noqa: E731
        try:
            if packaged:
                import tempfile
                from pathlib import Path

                # the map readers take a file: the packaged bytes go to a private temporary folder, gone after
                with tempfile.TemporaryDirectory(prefix="warp_spt_usdz_") as folder:
                    inner = Path(folder) / ("map" + Path(name[:-1].rsplit("[", 1)[-1]).suffix.lower())
                    inner.write_bytes(package_bytes(asset.resolvedPath))
                    try:
                        image = read_environment_image(inner, note)
                    except ValueError as err:
                        raise ValueError(str(err).replace(str(inner), name)) from None
            else:
                image = read_environment_image(name, note)
        except ValueError as err:
            raise SceneError(self.path, 0, f"{where}: the dome light's texture: {err}") from None
        self.extras.sky = Sky.environment(EnvironmentMap(image, name, "importance"), strength=strength)


def _is_shape(prim) -> bool:
    """An implicit shape that is read (``shapes.py``)."""
    from pxr import UsdGeom

    return any(prim.IsA(k) for k in (UsdGeom.Sphere, UsdGeom.Cube, UsdGeom.Capsule, UsdGeom.Cylinder, UsdGeom.Cone))


def _predicate():
    from pxr import Usd

    # defined, active, not abstract prims: the ones a renderer draws (instances are entered by hand)
    return Usd.PrimDefaultPredicate
