"""Scene parameters addressed by name, as Mitsuba's ``traverse``: read, set and differentiate them.

``parameters(scene, camera, sky)`` lists what a user can edit and what gradients reach:

* ``"<material>.<field>"`` for each differentiable column of the material schema
  (``warp_spt.scene.material_schema``): the colours ``.diffuse``, ``.reflect``, ``.refract``,
  ``.emission`` (3,); ``.roughness`` (probability of the diffuse lobe, in [0, 1]) and ``.fuzz``
  (>= 0), ();
* ``"<material>.<slot>_map"`` for each image texture, named after the first material slot that uses
  it (slots diffuse, reflect, refract, emission): its texels (h, w, 3), row 0 the image's top row;
* ``"<material>.<slot>_map.<key>"`` for each numeric parameter of a procedural texture (named, as
  image textures are, after the first slot using that instance; ``<key>`` as declared with
  ``@warp_spt.texture``): () for a number, (3,) for an RGB triple;
* ``"sky.color"`` (3,) for a constant sky; ``"sky.zenith"`` and ``"sky.nadir"`` (3,) for the
  gradient sky (its colours straight up and straight down);
* ``"environment.strength"`` and ``"environment.rotate"`` () for an environment-map sky (its
  radiance scale, and its turn about the up axis in degrees; the rotation's derivative comes from the
  map's lookup, linear in azimuth), and ``"environment.texels"`` (H, W, 3), the map's radiance (row 0
  the zenith), differentiated with its sampling distribution held fixed (docs/lights.md);
* ``"<light>.direction"`` and ``"<light>.color"`` (3,) for a sun (towards it; its irradiance),
  ``"<light>.position"`` and ``"<light>.intensity"`` (3,) for a point or spot light, ``<light>`` its
  name (``scene.lights.unique_names``); positions and directions by the tape only;
* ``"fog.sigma_a"``, ``"fog.sigma_s"`` (3,) and ``"fog.g"`` () for the scene's medium, and
  ``"<material>.medium_sigma_a"``, ``.medium_sigma_s``, ``.medium_g`` for a material's interior
  medium (materials whose media are equal share one: setting one sets all); a density grid adds
  ``.density_scale`` / ``.medium_density_scale`` (), and its ``sigma_a``/``sigma_s`` are per unit
  density (docs/volumes.md, Gradients);
* geometry (``warp_spt.diff.geometry_params``): ``"<mesh>.positions"`` (V, 3), an object's
  ``.translation``, ``.rotation`` (a rotation vector) and ``.scale`` (3,), ``"sphere<k>.center"``
  (3,) and ``.radius`` (); by the tape, with the silhouettes seen by the camera (``diff.boundary``);
* ``"camera.position"`` and ``"camera.direction"`` (3,): by the tape, through shading and the
  silhouettes seen by the camera (see docs/gradients.md).

Values are validated before they reach a kernel (finite; a material field in its range of the
material schema, reflectance colours in [0, 1], roughness in [0, 1], fuzz >= 0; texels >= 0; a
non-zero direction). Setting a material value updates both the host Scene and
the device arrays, and recomputes the scene's Features (a roughness leaving 1 needs the mirror lobe
compiled in) and its light table (an emission change re-weights light sampling).
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np

from warp_spt.device.camera_rays import CAMERA_FIELDS
from warp_spt.diff import geometry_params as geo_params
from warp_spt.diff.geometry_params import MESH, POSE, SPHERE
from warp_spt.device.camera_rays import camera_frame as kernel_camera_frame
from warp_spt.upload.device_scene import DeviceScene
from warp_spt.device.proctex import get_texture
from warp_spt.device.textures import tile_view
from warp_spt.scene.camera import Camera
from warp_spt.device.media_table import media_of
from warp_spt.scene.errors import SceneError
from warp_spt.scene.limits import MAX_RADIANCE
from warp_spt.scene.material_schema import (
    COLOR,
    COLUMN,
    DIFFERENTIABLE,
    SLOT_COLUMNS,
    range_text,
)
from warp_spt.scene.media import MAX_SIGMA, Medium
from warp_spt.scene.lights import KIND_SUN, PUNCTUAL_TYPES, punctual_lights, unique_names
from warp_spt.scene.model import TEX_PROC_BASE, Scene
from warp_spt.scene.sky import SKY_ENVIRONMENT, Sky
from warp_spt.scene.validate import check_procedural_colours

# the environment map's light kind (emitters.environment) and its parameters, in the order of the rows
# of its parameter array (EnvLight.params): Sky fields
ENVIRONMENT = "environment"
ENVIRONMENT_FIELDS = ("strength", "rotate")
ENVIRONMENT_TEXELS = "texels"       # the map itself: not a row of that array (EnvLight.texels)

# a participating medium's parameters (kind MEDIUM; index its row of the media table), in order; the
# last only for a density grid
MEDIUM = "medium"
MEDIUM_FIELDS = ("sigma_a", "sigma_s", "g", "density_scale")

# the material schema's differentiable columns (warp_spt.scene.material_schema), in its order
MATERIAL_FIELDS = tuple(c.name for c in DIFFERENTIABLE)
COLOR_FIELDS = tuple(c.name for c in DIFFERENTIABLE if c.type == COLOR)
SCALAR_FIELDS = tuple(c.name for c in DIFFERENTIABLE if c.type != COLOR)
REPLAYABLE_FIELDS = tuple(c.name for c in DIFFERENTIABLE if not c.pathwise)   # path replay takes these
_SLOT_NAMES = {c.slot: c.name for c in SLOT_COLUMNS}


@dataclass(frozen=True)
class ParamInfo:
    """Where a named parameter lives: ``kind`` is "material", "texture", "proc" (a procedural
    texture's parameter), "sky", "punctual" (a sun, point or spot light), "medium" or "camera"; ``field`` the material field / texture key / sky or
    camera attribute; ``index`` the material row, texture index, procedural instance or row of the
    sky's colour array (``Sky.colour_fields`` order)."""

    name: str
    kind: str
    field: str
    index: int
    shape: tuple[int, ...]


class SceneParameters:
    """The editable, differentiable parameters of one DeviceScene seen by one camera under one sky.

    ``params[name]`` returns a numpy copy; ``params[name] = value`` validates and applies it.
    ``params.camera`` and ``params.sky`` are the current camera and sky (frozen dataclasses, replaced
    when set).
    """

    def __init__(self, scene: DeviceScene | Scene, camera: Camera | None = None, sky: Sky | None = None):
        if camera is not None and not isinstance(camera, Camera):
            raise TypeError(f"camera must be a warp_spt.Camera or None, got {camera!r}")
        if sky is not None and not isinstance(sky, Sky):
            raise TypeError(f"sky must be a warp_spt.Sky or None, got {sky!r}")
        # uploaded here with a mesh cache: a geometry parameter's change then keeps the BVHs of the
        # meshes it leaves as they were (DeviceScene.update_geometry)
        self.scene = scene if isinstance(scene, DeviceScene) else DeviceScene(scene, meshes={})
        self.camera = camera or Camera()
        self.sky = sky or getattr(self.scene.scene, "sky", None) or Sky.black()
        self._info = _describe(self.scene.scene, self.sky)
        geometry, self._poses = geo_params.describe(self.scene.scene, set(self._info))
        # the geometry's names come before the camera's (whose names stay last, as before)
        camera = {n: self._info.pop(n) for n in [n for n, p in self._info.items() if p.kind == "camera"]}
        for n, (kind, f, index, shape) in geometry.items():
            self._info[n] = ParamInfo(n, kind, f, index, shape)
        self._info.update(camera)
        # the meshes as loaded: a world-space mesh's pose moves these (geometry_params.with_pose)
        self._base_meshes = list(self.scene.scene.meshes)

    # --- the mapping -------------------------------------------------------------------------
    def names(self) -> list[str]:
        return list(self._info)

    def __iter__(self):
        return iter(self._info)

    def __len__(self) -> int:
        return len(self._info)

    def __contains__(self, name: object) -> bool:
        return name in self._info

    def differentiable(self) -> list[str]:
        """The names :func:`warp_spt.diff.gradients.render_gradients` differentiates (all of them)."""
        return list(self._info)

    def info(self, name: str) -> ParamInfo:
        if not isinstance(name, str) or name not in self._info:
            raise KeyError(f"no parameter {name!r}; parameters are: {', '.join(self._info)}")
        return self._info[name]

    def __getitem__(self, name: str) -> np.ndarray:
        p = self.info(name)
        s = self.scene.scene
        if p.kind == "material":
            return np.array(getattr(s.materials, p.field)[p.index], dtype=np.float32)
        if p.kind == "texture":
            return np.array(s.textures[p.index], dtype=np.float32)
        if p.kind == "proc":
            off, size = proc_slice(s, p)
            return np.array(s.procedural[p.index].params[off:off + size], dtype=np.float32).reshape(p.shape)
        if (p.kind, p.field) == (ENVIRONMENT, ENVIRONMENT_TEXELS):
            return np.array(self.sky.env.image, dtype=np.float32)
        if p.kind == "sky":          # the constant or gradient part (an environment map's plus sky)
            return np.array(getattr(self.sky.colour_sky(), p.field), dtype=np.float32)
        if p.kind == ENVIRONMENT:
            return np.array(getattr(self.sky, p.field), dtype=np.float32)
        if p.kind == "punctual":
            return np.array(getattr(self._light(p)[1], p.field), dtype=np.float32)
        if p.kind == MEDIUM:
            return np.array(getattr(self._medium(p), p.field), dtype=np.float32)
        if p.kind == MESH:
            m = s.meshes[p.index] if s.meshes[p.index].transforms is not None else self._base_meshes[p.index]
            return np.array(m.positions, dtype=np.float32)
        if p.kind == POSE:
            return np.array(getattr(self._poses[p.index], p.field), dtype=np.float32)
        if p.kind == SPHERE:
            row = np.asarray(s.spheres[p.index], dtype=np.float32)
            return row[:3].copy() if p.field == "center" else np.array(row[3], dtype=np.float32)
        return np.array(getattr(self.camera, p.field), dtype=np.float32)

    def pose(self, name: str) -> geo_params.Pose:
        """The :class:`geometry_params.Pose` an object's pose parameter belongs to."""
        p = self.info(name)
        if p.kind != POSE:
            raise KeyError(f"{name} is not an object's pose parameter")
        return self._poses[p.index]

    def _set_geometry(self, p: ParamInfo, v: np.ndarray) -> None:
        """Validate and upload a geometry parameter's new value (geometry_params)."""
        dev = self.scene
        scene = dev.scene
        if p.kind == SPHERE:
            geo_params.check_sphere(p.name, p.field, v)
            spheres = np.array(scene.spheres, dtype=np.float64).reshape(-1, 4)
            if p.field == "center":
                spheres[p.index, :3] = v
            else:
                spheres[p.index, 3] = v
            dev.update_geometry(replace(scene, spheres=spheres.astype(np.float32)))
            return
        if p.kind == POSE:
            geo_params.check_pose(p.name, p.field, v)
            pose = self._poses[p.index]
            old = getattr(pose, p.field)
            setattr(pose, p.field, np.array(v, dtype=np.float64))
            try:
                new = geo_params.with_pose(scene, self._base_meshes, self._poses, pose.mesh)
                m = new.meshes[pose.mesh]
                x = geo_params.placement(pose)
                if m.transforms is not None:
                    geo_params.check_positions(p.name, m, np.asarray(m.positions, np.float64), x[:3, :3])
                else:
                    geo_params.check_positions(p.name, m, np.asarray(m.positions, np.float64))
            except ValueError:
                setattr(pose, p.field, old)
                raise
            dev.update_geometry(new)
            return
        k = p.index
        m = scene.meshes[k]
        if m.transforms is not None:
            geo_params.check_positions(p.name, m, v)
            meshes = list(scene.meshes)
            meshes[k] = replace(m, positions=v.astype(np.float32))
            dev.update_geometry(replace(scene, meshes=meshes))
            return
        base = self._base_meshes[k]
        x = geo_params.placement(next(q for q in self._poses if q.mesh == k))
        geo_params.check_positions(p.name, base, v, x[:3, :3])
        self._base_meshes[k] = replace(base, positions=v.astype(np.float32))
        try:
            dev.update_geometry(geo_params.with_pose(scene, self._base_meshes, self._poses, k))
        except Exception:
            self._base_meshes[k] = base
            raise

    def _light(self, p: ParamInfo):
        """(place in scene.lights, the light) of a light's parameter (row 2 j or 2 j + 1: light j)."""
        places = [k for k, x in enumerate(self.scene.scene.lights) if isinstance(x, PUNCTUAL_TYPES)]
        k = places[p.index // 2]
        return k, self.scene.scene.lights[k]

    def __setitem__(self, name: str, value) -> None:
        p = self.info(name)
        try:
            v = np.asarray(value, dtype=np.float64)
        except (OverflowError, TypeError, ValueError):      # 10**400, "abc", ragged lists
            raise ValueError(f"{name}: expected numbers of shape {p.shape} (finite in float32), "
                             f"got {value!r:.80}") from None
        if v.shape != p.shape:
            raise ValueError(f"{name}: expected shape {p.shape}, got {v.shape}")
        _check_value(p, v)
        if p.kind == "proc":
            self._check_proc(p, v)
        elif p.kind == "camera":       # the camera the renderer would refuse is refused here
            replace(self.camera, **{p.field: tuple(float(x) for x in v)}).validate()
        if p.kind == "material":
            self._set_material(p, v)
        elif p.kind == "texture":
            self._set_texture(p, v)
        elif p.kind == "proc":
            self._set_proc(p, v)
        elif p.kind == "sky":
            self.sky = self.sky.with_colours(**{p.field: tuple(float(x) for x in v)})   # validated by Sky
        elif (p.kind, p.field) == (ENVIRONMENT, ENVIRONMENT_TEXELS):     # a new map: its own light table
            self.sky = replace(self.sky, env=replace(self.sky.env, image=v.astype(np.float32)))
        elif p.kind == ENVIRONMENT:
            self.sky = replace(self.sky, **{p.field: float(v)})
        elif p.kind == MEDIUM:
            self._set_medium(p, v)
        elif p.kind in geo_params.GEOMETRY_KINDS:
            self._set_geometry(p, v)
        elif p.kind == "punctual":      # validated by the light's record; its table is rebuilt
            k, light = self._light(p)
            self.scene.scene.lights[k] = replace(light, **{p.field: tuple(float(x) for x in v)})
            self._refresh()
        else:
            self.camera = replace(self.camera, **{p.field: tuple(float(x) for x in v)})

    def update(self, values: dict) -> None:
        for k, v in values.items():
            self[k] = v

    @contextmanager
    def restored(self, names):
        """A context in which the parameters ``names`` may be changed: on leaving it they hold their
        values of entering it bit for bit, at the precision they are kept (``self[name]`` is a float32
        copy; a pose, a light or a sky holds float64): the camera and sky objects themselves, the
        host Scene of the geometry with its base meshes and poses, the light and medium records and
        textures set back, the device arrays written from them again."""
        infos = [self.info(n) for n in names]
        camera, sky, dev = self.camera, self.sky, self.scene
        scene = dev.scene
        geometry = any(p.kind in geo_params.GEOMETRY_KINDS for p in infos)
        bases = list(self._base_meshes)
        poses = [(q, q.translation.copy(), q.rotation.copy(), q.scale.copy()) for q in self._poses]
        lights = list(scene.lights)
        fog, interiors = getattr(scene, "fog", None), dict(getattr(scene, "interiors", None) or {})
        rows = {p.name: getattr(scene.materials, p.field)[p.index].copy() for p in infos if p.kind == "material"}
        kept = {p.name: (p, scene.textures[p.index] if p.kind == "texture" else scene.procedural[p.index])
                for p in infos if p.kind in ("texture", "proc")}
        media = {p.name: np.array(getattr(self._medium(p), p.field), np.float64) for p in infos if p.kind == MEDIUM}
        try:
            yield self
        finally:
            if geometry:            # first: the host Scene it puts back is the one the others write to
                for q, t, r, s in poses:
                    q.translation, q.rotation, q.scale = t, r, s
                self._base_meshes[:] = bases
                dev.update_geometry(scene)
            self.camera, self.sky = camera, sky
            for n, row in rows.items():
                self[n] = row
            for n, (p, held) in kept.items():     # the device's float32 copy, then the host's own object
                if p.kind == "texture":
                    self[n] = held
                else:
                    off, size = proc_slice(scene, p)
                    self[n] = np.reshape(held.params[off:off + size], p.shape)
                (scene.textures if p.kind == "texture" else scene.procedural)[p.index] = held
            for n, v in media.items():
                self[n] = v
            if media:
                scene.fog = fog
                scene.interiors.update(interiors)
            if any(p.kind == "punctual" for p in infos):
                scene.lights[:] = lights
                self._refresh()

    # --- writing through to host and device ------------------------------------------------------
    def _set_material(self, p: ParamInfo, v: np.ndarray) -> None:
        dev = self.scene
        getattr(dev.scene.materials, p.field)[p.index] = v
        arr = getattr(dev.materials, p.field)
        host = arr.numpy()
        host[p.index] = v
        arr.assign(host)
        self._refresh()

    def _set_texture(self, p: ParamInfo, v: np.ndarray) -> None:
        dev = self.scene
        dev.scene.textures[p.index] = v.astype(np.float32)
        texels, tiles = dev.atlas_arrays()
        host = texels.numpy()
        tile_view(host, tiles.numpy()[p.index])[...] = v
        texels.assign(host)
        self._refresh()

    def _check_proc(self, p: ParamInfo, v: np.ndarray) -> None:
        """The loader's rules for a procedural texture's parameter (its declared range; a colour
        within the range of the slots it fills), checked before anything is written."""
        ref = self.scene.scene.procedural[p.index]
        problem = get_texture(ref.name).check(p.field, tuple(float(x) for x in v.reshape(-1)))
        if problem:
            raise ValueError(f"{p.name}: {problem}")
        procedural = list(self.scene.scene.procedural)
        procedural[p.index] = self._proc_with(p, v)
        try:
            check_procedural_colours(replace(self.scene.scene, procedural=procedural))
        except SceneError as err:
            raise ValueError(f"{p.name}: {err.message}") from None

    def _proc_with(self, p: ParamInfo, v: np.ndarray):
        """The procedural instance of ``p`` with ``v`` in its parameter vector (rounded as uploaded)."""
        ref = self.scene.scene.procedural[p.index]
        off, size = proc_slice(self.scene.scene, p)
        vec = list(ref.params)
        vec[off:off + size] = (float(np.float32(x)) for x in v.reshape(-1))
        return replace(ref, params=tuple(vec))

    def _set_proc(self, p: ParamInfo, v: np.ndarray) -> None:
        dev = self.scene
        off, size = proc_slice(dev.scene, p)
        dev.scene.procedural[p.index] = self._proc_with(p, v)
        host = dev.proc_params.numpy()
        host[p.index, off:off + size] = v.reshape(-1)
        dev.proc_params.assign(host)
        self._refresh()

    def _medium(self, p: ParamInfo) -> Medium:
        """The host Medium ``p`` names (the fog's, or its material's interior)."""
        scene = self.scene.scene
        if p.name == f"fog.{p.field}":
            return scene.fog
        return scene.interiors[p.name[:-len(f".medium_{p.field}")]]

    def _set_medium(self, p: ParamInfo, v: np.ndarray) -> None:
        """Validate (``Medium.check``), then write the host Medium (the fog, or every interior holding
        it) and its row of the device's media table (coefficients times the grid's scale, the majorant)."""
        scene = self.scene.scene
        old = self._medium(p)
        value = tuple(float(x) for x in v) if p.shape else float(v)
        try:
            new = replace(old, **{p.field: value}).check(p.name)
        except ValueError as err:
            raise ValueError(str(err)) from None
        if getattr(scene, "fog", None) is old:
            scene.fog = new
        for name, m in list((getattr(scene, "interiors", None) or {}).items()):
            if m is old:
                scene.interiors[name] = new
        md = self.scene.geometry.media
        scale = new.density_scale if new.density is not None else 1.0
        rows = {"sigma_a": np.asarray(new.sigma_a) * scale, "sigma_s": np.asarray(new.sigma_s) * scale,
                "majorant": np.asarray(new.sigma_t) * scale * new.majorant}
        for name, row in rows.items():
            host = getattr(md, name).numpy()
            host[p.index] = row
            getattr(md, name).assign(host)
        host = md.g.numpy()
        host[p.index] = new.g
        md.g.assign(host)
        self._refresh()

    def _refresh(self) -> None:
        """Features and light table follow the new values."""
        self.scene.refresh_features()


def parameters(scene: DeviceScene | Scene, camera: Camera | None = None, sky: Sky | None = None) -> SceneParameters:
    """The named parameters of ``scene`` (uploaded if it is a host Scene); see the module docstring."""
    return SceneParameters(scene, camera, sky)


def _describe(scene: Scene, sky: Sky) -> dict[str, ParamInfo]:
    info: dict[str, ParamInfo] = {}
    mt = scene.materials
    for row, mname in enumerate(mt.names):
        for f in MATERIAL_FIELDS:
            n = f"{mname}.{f}"
            info[n] = ParamInfo(n, "material", f, row, (3,) if f in COLOR_FIELDS else ())
    for k, img in enumerate(scene.textures):
        uses = np.argwhere(mt.tex == k)
        if len(uses):
            row, slot = (int(x) for x in uses[0])
            n = f"{mt.names[row]}.{_SLOT_NAMES[slot]}_map"
        else:
            n = f"texture{k}"
        info[n] = ParamInfo(n, "texture", "texels", k, tuple(np.shape(img)))
    for k, ref in enumerate(scene.procedural):
        uses = np.argwhere(mt.tex == TEX_PROC_BASE - k)
        if not len(uses):
            continue                        # not used by any material: nothing to differentiate
        row, slot = (int(x) for x in uses[0])
        for key, (_, size) in get_texture(ref.name).layout().items():
            n = f"{mt.names[row]}.{_SLOT_NAMES[slot]}_map.{key}"
            info[n] = ParamInfo(n, "proc", key, k, () if size == 1 else (size,))
    # the sky's colours: kind "sky", the light kind whose colour array holds them, index their row
    for row, f in enumerate(sky.colour_fields()):
        info[f"sky.{f}"] = ParamInfo(f"sky.{f}", "sky", f, row, (3,))
    # an environment map's strength and rotation: rows of its light kind's parameter array
    if sky.kind == SKY_ENVIRONMENT:
        for row, f in enumerate(ENVIRONMENT_FIELDS):
            info[f"{ENVIRONMENT}.{f}"] = ParamInfo(f"{ENVIRONMENT}.{f}", ENVIRONMENT, f, row, ())
        n = f"{ENVIRONMENT}.{ENVIRONMENT_TEXELS}"
        info[n] = ParamInfo(n, ENVIRONMENT, ENVIRONMENT_TEXELS, -1, tuple(sky.env.image.shape))
    # sun, point and spot lights: kind "punctual", index the row of its parameter array (two per light)
    lights = punctual_lights(scene.lights)
    for j, (light, lname) in enumerate(zip(lights, unique_names(lights))):
        fields = ("direction", "color") if light.kind == KIND_SUN else ("position", "intensity")
        for row, f in enumerate(fields):
            n = f"{lname}.{f}"
            if n in info:           # a material of the same name
                n = f"light:{n}"
            info[n] = ParamInfo(n, "punctual", f, 2 * j + row, (3,))
    media, outer, rows = media_of(scene)
    owners = [("fog.", outer)] if outer >= 0 else []
    owners += [(f"{mt.names[k]}.medium_", int(r)) for k, r in enumerate(rows) if r >= 0]
    for prefix, row in owners:
        for f in MEDIUM_FIELDS if media[row].density is not None else MEDIUM_FIELDS[:3]:
            n = prefix + f
            info[n] = ParamInfo(n, MEDIUM, f, row, (3,) if f.startswith("sigma") else ())
    for f in ("position", "direction"):
        info[f"camera.{f}"] = ParamInfo(f"camera.{f}", "camera", f, 0, (3,))
    return info


# The kernel's camera frame (integrators.CameraParams), whose gradients render_gradients computes
def camera_frame(camera: Camera, width: int, height: int) -> np.ndarray:
    """(6, 3) float64: the CameraParams vectors of ``camera`` in CAMERA_FIELDS order
    (``device.camera_rays.camera_frame``, the kernels' own)."""
    f = kernel_camera_frame(camera, width, height)
    return np.stack([f[k] for k in CAMERA_FIELDS])


def camera_jacobian(camera: Camera, field: str, width: int, height: int, h: float = 1e-6) -> np.ndarray:
    """(6, 3, 3): d camera_frame / d ``camera.<field>`` ("position" or "direction").

    The frame is a smooth float64 function of both (away from looking straight along ``up``, where
    Camera.axes switches to a fixed reference), so central differences with h = 1e-6 give its
    derivative to about 1e-9 relative. The position moves only the origin.
    """
    if field == "position":
        jac = np.zeros((len(CAMERA_FIELDS), 3, 3))
        jac[0] = np.eye(3)
        return jac
    v = np.asarray(getattr(camera, field), dtype=np.float64)
    cols = []
    for i in range(3):
        e = np.zeros(3)
        e[i] = h * max(1.0, float(np.linalg.norm(v)))
        hi = camera_frame(replace(camera, **{field: tuple(v + e)}), width, height)
        lo = camera_frame(replace(camera, **{field: tuple(v - e)}), width, height)
        cols.append((hi - lo) / (2.0 * e[i]))
    return np.stack(cols, axis=-1)


def proc_slice(scene: Scene, p: ParamInfo) -> tuple[int, int]:
    """(offset, size) of a procedural parameter in its instance's parameter vector."""
    return get_texture(scene.procedural[p.index].name).layout()[p.field]


def value_range(p: ParamInfo) -> tuple[float | None, float | None]:
    """(low, high) of a parameter's values, None where unbounded: a material field's range in the
    material schema; colours, texels (and a procedural texture's RGB triples) >= 0; camera vectors
    and a procedural texture's numbers any finite value."""
    if p.kind == "material":
        return COLUMN[p.field].low, COLUMN[p.field].high
    if p.kind == "texture":
        return 0.0, 1.0                         # texels, as validate_scene requires
    if (p.kind == "sky" or (p.kind == ENVIRONMENT and p.field in ("strength", ENVIRONMENT_TEXELS))
            or (p.kind == "punctual" and p.field in ("color", "intensity"))):
        return 0.0, MAX_RADIANCE
    if p.kind == "proc" and p.shape == (3,):
        return 0.0, None
    if p.kind == MEDIUM:              # Medium.check has the exact (open) bounds
        return {"g": (-0.999, 0.999), "density_scale": (0.0, MAX_SIGMA)}.get(p.field, (0.0, MAX_SIGMA))
    return None, None


def non_negative(p: ParamInfo) -> bool:
    """The parameter's values are bounded below by 0 (see :func:`value_range`)."""
    return value_range(p)[0] == 0.0


FLOAT32_MAX = float(np.finfo(np.float32).max)


def _check_value(p: ParamInfo, v: np.ndarray) -> None:
    if not np.all(np.isfinite(v)) or np.any(np.abs(v) > FLOAT32_MAX):     # 1e39 is inf on the device
        raise ValueError(f"{p.name}: values must be finite (in float32 too, at most {FLOAT32_MAX:.3g})")
    low, high = value_range(p)
    if (low is not None and np.any(v < low)) or (high is not None and np.any(v > high)):
        if p.kind == "material" and p.shape == ():
            raise ValueError(f"{p.name}: {p.field} must {range_text(COLUMN[p.field])}, got {float(v)}")
        raise ValueError(f"{p.name}: values must be >= {low:g}" if high is None
                         else f"{p.name}: values must lie in [{low:g}, {high:g}]")
    if p.field == "direction" and not np.any(v != 0):
        raise ValueError(f"{p.name}: the view direction must not be zero")
