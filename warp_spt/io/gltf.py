"""glTF 2.0 reader (``.gltf`` with external or data-URI buffers, and ``.glb``) into an :class:`ObjData`.

The default scene's node tree is walked from its roots; every mesh a node names is placed in world
space (its node's TRS or matrix times its parents'), its primitives' triangles appended to one
object (strips and fans converted; points and lines refused). A node whose world transform mirrors
(negative determinant) has its triangles' winding reversed, as glTF asks. Normals go through the
inverse transpose. Positions stay in glTF's metres and Y up: the command line's up-axis rule for
models that are not in the seed's dialect applies (Y up).

Accessors: any component type, ``normalized`` integers, ``byteStride``, sparse accessors (with or
without a base buffer view); KHR_mesh_quantization's integer positions, normals and texture
coordinates are read through the same path. Texture coordinates are turned to the renderer's
convention (v = 0 at the image's bottom row: v' = 1 - v), after KHR_texture_transform of the base
colour texture.

Materials become the ``pbr`` kind (base colour, packed metallic-roughness, normal map, emission,
alpha, KHR_materials_ior/transmission/volume/specular/anisotropy/emissive_strength); every field is
also kept in :class:`GltfMaterial` records on :class:`GltfExtras`.
Cameras (perspective) and KHR_lights_punctual lights are kept as :class:`GltfCamera` and
:class:`GltfLight` records; the loader turns the lights into the renderer's (``GltfLight.to_scene``).

Every index, count, offset, stride and length is checked against its buffer view and buffer before
anything is read or allocated; node cycles and nodes with two parents are refused, the node depth
is bounded (MAX_NODE_DEPTH) and so are data URIs (MAX_DATA_URI_BYTES). Errors are
:class:`SceneError` naming the file (line 0) and the JSON path: ``scene.gltf: /accessors/3: count
1000000000 exceeds the buffer view``.
"""

from __future__ import annotations

import base64
import binascii
import json
import math
import os
import struct
import urllib.parse
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from warp_spt.io.paths import confine
from warp_spt.io.tokens import MAX_FILE_BYTES, file_problem, read_file
from warp_spt.scene.errors import SceneError
from warp_spt.scene.model import CHECKER_NAME, Material, ObjData, TextureRef
from warp_spt.scene.validate import MAX_COORDINATE, MAX_RADIANCE

__all__ = ["load_gltf", "parse_gltf_bytes", "choose_camera", "GltfCamera", "GltfLight", "GltfMaterial", "GltfExtras"]

MAX_NODE_DEPTH = 256                   # nesting of nodes below a root
MAX_DATA_URI_BYTES = 256 << 20         # decoded size of one base64 data URI
MAX_JSON_BYTES = 64 << 20
GLB_MAGIC, GLB_JSON, GLB_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942
_COMPONENTS = {5120: "i1", 5121: "u1", 5122: "i2", 5123: "u2", 5125: "u4", 5126: "f4"}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}
_MODES = {0: "points", 1: "lines", 2: "line loops", 3: "line strips", 4: "triangles", 5: "triangle strips",
          6: "triangle fans"}
MAX_UV = 1e30          # transformed texture coordinates: float32 with room to spare (1e39 became inf)
SUPPORTED_EXTENSIONS = {"KHR_mesh_quantization", "KHR_texture_transform", "KHR_lights_punctual",
                        "KHR_materials_emissive_strength", "KHR_materials_ior", "KHR_materials_transmission",
                        "KHR_materials_volume", "KHR_materials_specular", "KHR_materials_anisotropy"}


@dataclass
class GltfCamera:
    """A perspective camera placed by its node: ``position``, view ``direction`` (the node's -Z) and
    ``up`` (its +Y) in world space; ``yfov`` in radians; ``aspect`` None when the file leaves it to
    the image."""

    name: str
    index: int                   # in /cameras
    node: int
    position: tuple[float, float, float]
    direction: tuple[float, float, float]
    up: tuple[float, float, float]
    yfov: float
    aspect: float | None
    znear: float
    kind: str = "perspective"    # another type (orthographic) is listed but cannot be looked through

    def fov_degrees(self, width: int, height: int) -> float:
        """The full horizontal angle for an image of ``width`` x ``height`` (the renderer's ``fov``)."""
        aspect = width / height
        return math.degrees(2.0 * math.atan(math.tan(self.yfov / 2.0) * aspect))


@dataclass
class GltfLight:
    """A KHR_lights_punctual light placed by its node, as written (:meth:`to_scene`: the light the
    renderer draws)."""

    name: str
    kind: str                    # "point", "spot" or "directional"
    color: tuple[float, float, float]
    intensity: float
    position: tuple[float, float, float]
    direction: tuple[float, float, float]     # the node's -Z
    range: float | None = None
    inner_cone: float = 0.0
    outer_cone: float = math.pi / 4

    def to_scene(self):
        """The renderer's light (``warp_spt.scene.lights``): glTF's candela (point, spot) taken as
        W/sr and its lux (directional) as irradiance, one to one in the renderer's units, times the
        colour; a directional light's -Z is where its light goes, so the sun lies the other way;
        cone angles from radians to degrees. ``range`` is not used: light falls off as 1 / r^2."""
        from warp_spt.scene.lights import PointLight, SpotLight, SunLight

        power = tuple(float(c) * float(self.intensity) for c in self.color)
        name = self.name or self.kind
        if self.kind == "directional":
            return SunLight(direction=tuple(-float(c) for c in self.direction), color=power, name=name)
        if self.kind == "spot":
            outer = math.degrees(self.outer_cone)
            return SpotLight(position=self.position, direction=self.direction, intensity=power,
                             inner_deg=min(math.degrees(self.inner_cone), outer), outer_deg=outer, name=name)
        return PointLight(position=self.position, intensity=power, name=name)


@dataclass
class GltfMaterial:
    """A glTF material as written (metallic-roughness model), for the ``pbr`` kind."""

    name: str
    base_color: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    base_color_texture: int | None = None     # index into /textures
    metallic: float = 1.0
    roughness: float = 1.0
    metallic_roughness_texture: int | None = None
    normal_texture: int | None = None
    normal_scale: float = 1.0
    emissive: tuple[float, float, float] = (0.0, 0.0, 0.0)
    emissive_texture: int | None = None
    alpha_mode: str = "OPAQUE"
    alpha_cutoff: float = 0.5
    double_sided: bool = False
    extensions: dict = field(default_factory=dict)


@dataclass
class GltfExtras:
    """What a glTF holds beyond triangles: cameras, lights and materials (``ObjData.extras``)."""

    cameras: list[GltfCamera] = field(default_factory=list)
    lights: list[GltfLight] = field(default_factory=list)
    materials: list[GltfMaterial] = field(default_factory=list)
    # every placement of a mesh: (node, mesh index, 4x4 world matrix)
    instances: list[tuple[int, int, np.ndarray]] = field(default_factory=list)
    # the meshes kept in their own object space and instanced (see parse_gltf_bytes): per glTF mesh,
    # its triangles (an ObjData sharing the file's material names) and its (I, 4, 4) world matrices
    placed: list[tuple[ObjData, np.ndarray]] = field(default_factory=list)
    # the first animation's time range in seconds (None: the file has no animation)
    time_range: tuple[float, float] | None = None
    # placements of meshes scaled to nothing (a common way to hide an object), not drawn
    hidden: int = 0


def world_triangles(d: ObjData) -> tuple[np.ndarray, np.ndarray]:
    """(positions (V, 3) float64, triangles (F, 3) int32): a read file's triangles all in world space,
    its flattened ones first, then every placement of each instanced mesh (``GltfExtras.placed``; a
    mirroring placement reverses the winding, as flattening does)."""
    positions, faces, n = [d.positions], [d.faces], len(d.positions)
    for sub, transforms in getattr(d.extras, "placed", ()):
        for x in transforms:
            positions.append(sub.positions @ x[:3, :3].T + x[:3, 3])
            faces.append((sub.faces[:, ::-1] if np.linalg.det(x[:3, :3]) < 0 else sub.faces) + n)
            n += len(sub.positions)
    return np.concatenate(positions), np.concatenate(faces).astype(np.int32)


def load_gltf(path: str | os.PathLike[str], time: float | None = None) -> ObjData:
    """Read a ``.gltf`` or ``.glb`` file into world-space triangles; see the module docs. ``time``
    (seconds) poses the nodes by the file's first animation (:func:`sample_channel`); None: the
    nodes' own transforms."""
    path = str(path)
    return parse_gltf_bytes(read_file(path, "glTF", binary=True), path, time)


def parse_gltf_bytes(data: bytes, path: str = "<input>", time: float | None = None) -> ObjData:
    """Parse glTF JSON or GLB bytes; ``path`` names the file in errors and anchors relative URIs."""
    return _Reader(data, path, time).run()


def _err(path: str, pointer: str, message: str) -> SceneError:
    return SceneError(path, 0, f"{pointer}: {message}" if pointer else message)


class _Reader:
    def __init__(self, data: bytes, path: str, time: float | None = None) -> None:
        if time is not None and not math.isfinite(time):
            raise ValueError(f"time must be finite, got {time!r}")
        self.time = time
        self.path = path
        self.folder = Path(path).parent
        self.input_bytes = len(data)
        self.bin: bytes | None = None
        if data[:4] == b"glTF":
            text = self._glb(data)
        else:
            text = data
        self.doc = self._json(text)
        self.buffers: dict[int, bytes] = {}
        self.warnings: list[str] = []

    # ------------------------------------------------------------------------------------ containers

    def _glb(self, data: bytes) -> bytes:
        if len(data) < 20:
            raise _err(self.path, "", f"a GLB file needs a 12-byte header and a JSON chunk; it has {len(data)} bytes")
        magic, version, length = struct.unpack_from("<III", data, 0)
        if version != 2:
            raise _err(self.path, "", f"GLB version {version}: only glTF 2.0 is read")
        if length != len(data):
            raise _err(self.path, "", f"the GLB header says {length} bytes, the file has {len(data)}")
        pos, chunks = 12, []
        while pos < length:
            if pos + 8 > length:
                raise _err(self.path, "", f"a GLB chunk header at byte {pos} runs past the end of the file")
            size, kind = struct.unpack_from("<II", data, pos)
            if size > length - pos - 8:
                raise _err(self.path, "", f"GLB chunk {len(chunks)} at byte {pos}: length {size} runs past the end "
                           f"of the file ({length - pos - 8} bytes left)")
            chunks.append((kind, data[pos + 8:pos + 8 + size]))
            pos += 8 + size
        if not chunks or chunks[0][0] != GLB_JSON:
            raise _err(self.path, "", "the first GLB chunk must be the JSON chunk")
        if len(chunks) > 1 and chunks[1][0] == GLB_BIN:
            self.bin = chunks[1][1]
        return chunks[0][1]

    def _json(self, text: bytes) -> dict:
        if len(text) > MAX_JSON_BYTES:
            raise _err(self.path, "", f"the JSON is {len(text)} bytes, more than the {MAX_JSON_BYTES >> 20} MiB limit")
        try:
            doc = json.loads(text.decode("utf-8-sig"))
        except RecursionError:      # Python's decoder recurses once per level of nesting
            raise _err(self.path, "", "the JSON nests deeper than Python's recursion limit") from None
        except (UnicodeDecodeError, ValueError) as err:
            raise _err(self.path, "", f"not valid glTF JSON: {err}") from None
        if not isinstance(doc, dict):
            raise _err(self.path, "", f"expected a JSON object at the top, got {type(doc).__name__}")
        asset = self.obj(doc, "asset", "", required=True)
        version = self.get(asset, "version", str, "/asset", required=True)
        if not version.startswith("2."):
            raise _err(self.path, "/asset/version", f"glTF {version}: only glTF 2.0 is read")
        missing = set(self.get(doc, "extensionsRequired", list, "", []) or []) - SUPPORTED_EXTENSIONS
        if missing:
            raise _err(self.path, "/extensionsRequired", f"the file requires {', '.join(sorted(map(str, missing)))}, "
                       f"which warp_spt does not read (it reads {', '.join(sorted(SUPPORTED_EXTENSIONS))})")
        return doc

    # ------------------------------------------------------------------------------------- JSON typing

    def get(self, obj: dict, key: str, kind, pointer: str, default=None, *, required: bool = False):
        """``obj[key]`` of JSON type ``kind`` (int excludes bool; float takes int), else a SceneError."""
        if key not in obj:
            if required:
                raise _err(self.path, pointer, f"missing required property {key!r}")
            return default
        value = obj[key]
        ok = (isinstance(value, int) and not isinstance(value, bool)) if kind is int else \
            (isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)) \
            if kind is float else isinstance(value, kind)
        if not ok:
            want = {int: "an integer", float: "a finite number", str: "a string", list: "an array",
                    dict: "an object", bool: "true or false"}[kind]
            raise _err(self.path, f"{pointer}/{key}", f"expected {want}, got {json.dumps(value)[:60]}")
        return float(value) if kind is float else value

    def obj(self, parent: dict, key: str, pointer: str, *, required: bool = False) -> dict:
        return self.get(parent, key, dict, pointer, {}, required=required)

    def index(self, obj: dict, key: str, pointer: str, collection: str, *, required: bool = False) -> int | None:
        """A reference into ``/collection``, checked to exist."""
        k = self.get(obj, key, int, pointer, None, required=required)
        if k is None:
            return None
        items = self.get(self.doc, collection, list, "", [])
        if not 0 <= k < len(items):
            raise _err(self.path, f"{pointer}/{key}", f"{collection} index {k} is out of range: the file has "
                       f"{len(items)} {collection}")
        return k

    def item(self, collection: str, k: int) -> dict:
        value = self.doc[collection][k]
        if not isinstance(value, dict):
            raise _err(self.path, f"/{collection}/{k}", f"expected an object, got {json.dumps(value)[:60]}")
        return value

    def numbers(self, obj: dict, key: str, pointer: str, n: int, default):
        value = self.get(obj, key, list, pointer, None)
        if value is None:
            return default
        if len(value) != n or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                      and math.isfinite(v) for v in value):
            raise _err(self.path, f"{pointer}/{key}", f"expected {n} finite numbers, got {json.dumps(value)[:80]}")
        return [float(v) for v in value]

    # ------------------------------------------------------------------------------- buffers and data

    def buffer(self, k: int) -> bytes:
        if k in self.buffers:
            return self.buffers[k]
        ptr = f"/buffers/{k}"
        b = self.item("buffers", k)
        length = self.get(b, "byteLength", int, ptr, required=True)
        uri = self.get(b, "uri", str, ptr)
        if uri is None:
            if k != 0 or self.bin is None:
                raise _err(self.path, ptr, "no 'uri' and no GLB binary chunk to stand for it")
            data = self.bin
        else:
            data = self.uri(uri, f"{ptr}/uri")
        if length < 1 or length > len(data):
            raise _err(self.path, f"{ptr}/byteLength", f"byteLength {length} does not fit the {len(data)} bytes "
                       "of its data")
        self.buffers[k] = data[:length] if length < len(data) else data
        return self.buffers[k]

    def uri(self, uri: str, pointer: str) -> bytes:
        """The bytes of a data URI (base64, bounded) or of a file relative to the glTF's folder."""
        if uri.startswith("data:"):
            head, _, payload = uri.partition(",")
            if not head.endswith(";base64"):
                raise _err(self.path, pointer, "a data URI must be base64 (';base64,')")
            if len(payload) * 3 // 4 > MAX_DATA_URI_BYTES:
                raise _err(self.path, pointer, f"the data URI holds about {len(payload) * 3 // 4} bytes, more "
                           f"than the {MAX_DATA_URI_BYTES >> 20} MiB limit; use a .bin file or a .glb")
            try:
                return base64.b64decode(payload, validate=True)
            except (binascii.Error, ValueError) as err:
                raise _err(self.path, pointer, f"bad base64 data: {err}") from None
        target = self._local_file(uri, pointer)
        return read_file(str(target), "glTF buffer", binary=True)

    def _local_file(self, uri: str, pointer: str) -> Path:
        scheme = urllib.parse.urlsplit(uri).scheme
        if scheme and len(scheme) > 1:       # one letter: a Windows drive
            raise _err(self.path, pointer, f"only relative file URIs and data URIs are read, got {uri[:80]!r}")
        targets, refused = confine(urllib.parse.unquote(uri), self.folder, "the file")
        if refused:
            raise _err(self.path, pointer, refused)
        target = targets[0]
        problem = file_problem(target)
        if problem is not None:
            raise _err(self.path, pointer, f"{uri!r} cannot be read ({target}: {problem})")
        return target

    def view(self, k: int) -> tuple[bytes, int, int, int | None]:
        """(buffer, offset, length, stride) of buffer view ``k``, checked against its buffer."""
        ptr = f"/bufferViews/{k}"
        v = self.item("bufferViews", k)
        buf = self.buffer(self.index(v, "buffer", ptr, "buffers", required=True))
        offset = self.get(v, "byteOffset", int, ptr, 0)
        length = self.get(v, "byteLength", int, ptr, required=True)
        stride = self.get(v, "byteStride", int, ptr)
        if offset < 0 or length < 1 or offset + length > len(buf):
            raise _err(self.path, ptr, f"bytes {offset}..{offset + length} exceed the buffer's {len(buf)} bytes")
        if stride is not None and not (4 <= stride <= 252 and stride % 4 == 0):
            raise _err(self.path, f"{ptr}/byteStride", f"byteStride {stride} must be a multiple of 4 in 4..252")
        return buf, offset, length, stride

    def accessor(self, k: int, *, widths: tuple[str, ...] = ("SCALAR", "VEC2", "VEC3", "VEC4")) -> np.ndarray:
        """Accessor ``k`` as an (count, components) float64 array (normalized integers scaled), or
        (count,) int64 for an integer SCALAR that is not normalized."""
        ptr = f"/accessors/{k}"
        a = self.item("accessors", k)
        comp = self.get(a, "componentType", int, ptr, required=True)
        if comp not in _COMPONENTS:
            raise _err(self.path, f"{ptr}/componentType", f"unknown componentType {comp} (expected one of "
                       f"{sorted(_COMPONENTS)})")
        kind = _COMPONENTS[comp]
        type_ = self.get(a, "type", str, ptr, required=True)
        if type_ not in widths:
            raise _err(self.path, f"{ptr}/type", f"expected type {' or '.join(widths)}, got {type_!r}")
        n = _WIDTH[type_]
        count = self.get(a, "count", int, ptr, required=True)
        normalized = self.get(a, "normalized", bool, ptr, False)
        if normalized and kind in ("f4", "u4"):
            raise _err(self.path, f"{ptr}/normalized", f"componentType {comp} cannot be normalized")
        if count < 1:
            raise _err(self.path, f"{ptr}/count", f"count {count} must be at least 1")
        item = np.dtype(kind).itemsize
        elem = n * item
        view_k = self.index(a, "bufferView", ptr, "bufferViews")
        if view_k is None:
            # zeros (sparse values may follow): bounded by what the file holds, so a forged count
            # cannot make the reader allocate for it
            held = self.input_bytes + sum(len(b) for b in self.buffers.values())
            if count * elem > 8 * held + (1 << 20):
                raise _err(self.path, f"{ptr}/count", f"count {count} of zeros ({count * elem} bytes) is far more "
                           f"than the file's {held} bytes of data")
            values = np.zeros((count, n), kind)
        else:
            buf, voff, vlen, stride = self.view(view_k)
            off = self.get(a, "byteOffset", int, ptr, 0)
            stride = stride or elem
            if off < 0 or off % item:
                raise _err(self.path, f"{ptr}/byteOffset", f"byteOffset {off} must be a multiple of {item} and >= 0")
            if stride < elem:
                raise _err(self.path, ptr, f"byteStride {stride} is less than the element's {elem} bytes")
            if off + stride * (count - 1) + elem > vlen:
                raise _err(self.path, f"{ptr}/count", f"count {count} exceeds the buffer view: {count} elements of "
                           f"{elem} bytes, stride {stride}, from byte {off} need {off + stride * (count - 1) + elem} "
                           f"bytes, the view has {vlen}")
            values = np.ndarray((count, n), dtype="<" + kind, buffer=buf, offset=voff + off, strides=(stride, item))
        sparse = self.get(a, "sparse", dict, ptr)
        if sparse is not None:
            values = self._sparse(values.copy(), sparse, f"{ptr}/sparse", kind, n)
        if normalized:
            scale = float(np.iinfo(kind).max)
            return np.maximum(values.astype(np.float64) / scale, -1.0)
        if kind == "f4":
            out = values.astype(np.float64)
            if not np.isfinite(out).all():
                raise _err(self.path, ptr, "holds a value that is not finite (NaN or infinity)")
            return out
        if n == 1:
            return values[:, 0].astype(np.int64)
        return values.astype(np.float64)

    def _sparse(self, values: np.ndarray, sparse: dict, ptr: str, kind: str, n: int) -> np.ndarray:
        count = self.get(sparse, "count", int, ptr, required=True)
        if not 1 <= count <= len(values):
            raise _err(self.path, f"{ptr}/count", f"sparse count {count} must lie in 1..{len(values)} (the accessor's count)")
        ind = self.obj(sparse, "indices", ptr, required=True)
        comp = self.get(ind, "componentType", int, f"{ptr}/indices", required=True)
        if comp not in (5121, 5123, 5125):
            raise _err(self.path, f"{ptr}/indices/componentType", f"sparse indices must be 5121, 5123 or 5125, got {comp}")
        idx = self._slice(ind, f"{ptr}/indices", _COMPONENTS[comp], 1, count)[:, 0].astype(np.int64)
        if np.any(idx >= len(values)) or np.any(np.diff(idx) <= 0):
            raise _err(self.path, f"{ptr}/indices", f"sparse indices must increase strictly and stay below "
                       f"{len(values)}")
        vals = self._slice(self.obj(sparse, "values", ptr, required=True), f"{ptr}/values", kind, n, count)
        values[idx] = vals
        return values

    def _slice(self, ref: dict, ptr: str, kind: str, n: int, count: int) -> np.ndarray:
        """``count`` tightly packed elements from ``ref``'s bufferView and byteOffset (sparse parts)."""
        view_k = self.index(ref, "bufferView", ptr, "bufferViews", required=True)
        buf, voff, vlen, _stride = self.view(view_k)
        off = self.get(ref, "byteOffset", int, ptr, 0)
        need = count * n * np.dtype(kind).itemsize
        if off < 0 or off + need > vlen:
            raise _err(self.path, ptr, f"{count} elements of {n} x {kind} from byte {off} need {off + need} bytes, "
                       f"the buffer view has {vlen}")
        return np.frombuffer(buf, dtype="<" + kind, count=count * n, offset=voff + off).reshape(count, n)

    # ----------------------------------------------------------------------------------------- scene

    def run(self) -> ObjData:
        nodes = self.get(self.doc, "nodes", list, "", [])
        roots = self._roots(len(nodes))
        channels, time_range = self._animation(len(nodes))
        parts: list[tuple] = []           # (positions, triangles, uv or None, normals or None, material row)
        extras = GltfExtras(time_range=time_range)
        material_rows: dict[int | None, int] = {}
        names = [CHECKER_NAME]
        materials: dict[str, Material] = {}
        seen: set[int] = set()
        worlds: dict[int, np.ndarray] = {}
        order: list[int] = []
        stack = [(k, np.eye(4), 0, f"/scenes/{self._scene_index()}/nodes", False) for k in reversed(roots)]
        moving: dict[int, bool] = {}      # the node or an ancestor has a TRS channel
        while stack:
            k, parent, depth, via, parent_moves = stack.pop()
            ptr = f"/nodes/{k}"
            if k in seen:
                raise _err(self.path, via, f"node {k} is reached twice: the nodes form a cycle or a node has two "
                           "parents")
            seen.add(k)
            if depth > MAX_NODE_DEPTH:
                raise _err(self.path, ptr, f"nodes nest more than {MAX_NODE_DEPTH} deep")
            node = self.item("nodes", k)
            world = parent @ self._local(node, ptr, channels.get(k))
            worlds[k] = world
            moving[k] = parent_moves or (self.time is not None and any(
                c in channels.get(k, {}) for c in ("translation", "rotation", "scale")))
            order.append(k)
            cam = self.index(node, "camera", ptr, "cameras")
            if cam is not None:
                extras.cameras.append(self._camera(cam, k, world))
            light = self.get(self.obj(node, "extensions", ptr), "KHR_lights_punctual", dict, f"{ptr}/extensions")
            if light is not None:
                extras.lights.append(self._light(light, f"{ptr}/extensions/KHR_lights_punctual", world))
            children = self.get(node, "children", list, ptr, [])
            for c, child in reversed(list(enumerate(children))):
                if not isinstance(child, int) or isinstance(child, bool) or not 0 <= child < len(nodes):
                    raise _err(self.path, f"{ptr}/children/{c}", f"expected a node index in 0..{len(nodes) - 1}, got "
                               f"{json.dumps(child)[:40]}")
                stack.append((child, world, depth + 1, f"{ptr}/children/{c}", moving[k]))
        # meshes after the walk: a skin needs its joints' world matrices, wherever they are in the tree
        users: dict[int, int] = {}
        for k in order:
            mesh = self.index(self.item("nodes", k), "mesh", f"/nodes/{k}", "meshes")
            if mesh is not None:
                users[mesh] = users.get(mesh, 0) + 1
        placed: dict[int, tuple[list, list]] = {}        # mesh -> (object-space parts, world matrices)
        for k in order:
            node, ptr = self.item("nodes", k), f"/nodes/{k}"
            mesh = self.index(node, "mesh", ptr, "meshes")
            if mesh is None:
                continue
            world = worlds[k]
            extras.instances.append((k, mesh, world))
            skin = self._skin(node, ptr, worlds)
            weights = self._morph_weights(node, ptr, mesh, channels.get(k, {}).get("weights"))
            if (users[mesh] > 1 or moving[k]) and skin is None and weights is None:
                if mesh not in placed:
                    placed[mesh] = (self._object_parts(mesh, material_rows, names, materials), [])
                if placed[mesh][0] is not None:
                    # a node scaled to nothing (a common way to hide one) draws nothing, as its
                    # flattened triangles of zero area would not be drawn
                    if abs(np.linalg.det(world[:3, :3])) > 1e-30:
                        placed[mesh][1].append(world)
                    else:
                        extras.hidden += 1
                    continue
            for prim_k, prim in enumerate(self._primitives(mesh)):
                pptr = f"/meshes/{mesh}/primitives/{prim_k}"
                mat = self.index(prim, "material", pptr, "materials")
                if mat not in material_rows:
                    name, material = self._checked_material(mat, names)
                    material_rows[mat] = len(names)
                    names.append(name)
                    materials[name] = material
                parts.append((*self._primitive(prim, pptr, world, mat, skin, weights), material_rows[mat]))
        extras.materials = [self._material_record(m) for m in range(len(self.get(self.doc, "materials", list, "", [])))]
        for mesh, (mesh_parts, xf) in placed.items():
            if mesh_parts is None or not xf:
                continue
            sub = self._object(mesh_parts, names, materials, GltfExtras())
            sub.path = f"{self.path}#mesh{mesh}"
            transforms = np.stack(xf)
            self._check_placed(sub, transforms, f"/meshes/{mesh}")
            if len(sub.faces):
                extras.placed.append((sub, transforms))
        return self._object(parts, names, materials, extras)

    def _object_parts(self, mesh: int, material_rows: dict, names: list, materials: dict) -> list | None:
        """Mesh ``mesh``'s primitives in its own object space, to be instanced; None where it cannot be
        (vertex colours: they are baked into a texture of the whole file's triangles)."""
        out = []
        for prim_k, prim in enumerate(self._primitives(mesh)):
            pptr = f"/meshes/{mesh}/primitives/{prim_k}"
            mat = self.index(prim, "material", pptr, "materials")
            part = self._primitive(prim, pptr, np.eye(4), mat)
            if part[4] is not None:
                return None
            if mat not in material_rows:
                name, material = self._checked_material(mat, names)
                material_rows[mat] = len(names)
                names.append(name)
                materials[name] = material
            out.append((*part, material_rows[mat]))
        return out

    def _check_placed(self, sub: ObjData, transforms: np.ndarray, ptr: str) -> None:
        """Every placement of an instanced mesh within the coordinate range, as flattened vertices are."""
        if not len(sub.positions):
            return
        lo, hi = sub.positions.min(0), sub.positions.max(0)
        corners = np.array([[(hi if (i >> a) & 1 else lo)[a] for a in range(3)] for i in range(8)])
        world = np.einsum("nij,kj->nki", transforms[:, :3, :3], corners) + transforms[:, None, :3, 3]
        if not np.abs(world).max() <= MAX_COORDINATE:
            raise _err(self.path, ptr, f"an instance's vertex lies near {np.abs(world).max():g}, beyond the "
                       f"supported range of +-{MAX_COORDINATE:g}")

    def _animation(self, n_nodes: int) -> tuple[dict[int, dict], tuple[float, float] | None]:
        """The first animation's channels as {node: {path: sampler(time)}} and its time range.
        Morph target weights are not animated (a warning); other animations are not played."""
        animations = self.get(self.doc, "animations", list, "", [])
        if not animations:
            return {}, None
        if len(animations) > 1:
            self.warnings.append(f"{self.path}: {len(animations)} animations; the first is played")
        ptr = "/animations/0"
        anim = self.item("animations", 0)
        samplers = self.get(anim, "samplers", list, ptr, required=True)
        out: dict[int, dict] = {}
        lo, hi = math.inf, -math.inf
        for c, channel in enumerate(self.get(anim, "channels", list, ptr, required=True)):
            cptr = f"{ptr}/channels/{c}"
            if not isinstance(channel, dict):
                raise _err(self.path, cptr, "expected an object")
            target = self.obj(channel, "target", cptr, required=True)
            path = self.get(target, "path", str, f"{cptr}/target", required=True)
            node = self.get(target, "node", int, f"{cptr}/target")
            if node is None:
                continue                    # an extension's target: nothing to animate here
            if not 0 <= node < n_nodes:
                raise _err(self.path, f"{cptr}/target/node", f"node index {node} is out of range: the file has "
                           f"{n_nodes} nodes")
            if path not in ("translation", "rotation", "scale", "weights"):
                raise _err(self.path, f"{cptr}/target/path", f"expected translation, rotation, scale or weights, "
                           f"got {path!r}")
            k = self.get(channel, "sampler", int, cptr, required=True)
            if not 0 <= k < len(samplers) or not isinstance(samplers[k], dict):
                raise _err(self.path, f"{cptr}/sampler", f"sampler index {k} is out of range: the animation has "
                           f"{len(samplers)} samplers")
            targets = self._targets_of_node(node) if path == "weights" else 0
            if path == "weights" and targets == 0:
                raise _err(self.path, f"{cptr}/target", f"node {node} has no mesh with morph targets to weigh")
            times, values, interpolation = self._sampler(samplers[k], f"{ptr}/samplers/{k}", path, targets)
            lo, hi = min(lo, float(times[0])), max(hi, float(times[-1]))
            out.setdefault(node, {})[path] = _channel(times, values, interpolation, path == "rotation")
        return out, ((lo, hi) if lo <= hi else None)

    def _targets_of_node(self, node: int) -> int:
        mesh = self.index(self.item("nodes", node), "mesh", f"/nodes/{node}", "meshes")
        if mesh is None:
            return 0
        prims = self._primitives(mesh)
        targets = self.get(prims[0], "targets", list, f"/meshes/{mesh}/primitives/0", []) if prims else []
        return len(targets)

    def _sampler(self, sampler: dict, ptr: str, path: str, targets: int = 0):
        interpolation = self.get(sampler, "interpolation", str, ptr, "LINEAR")
        if interpolation not in ("LINEAR", "STEP", "CUBICSPLINE"):
            raise _err(self.path, f"{ptr}/interpolation", f"expected LINEAR, STEP or CUBICSPLINE, got {interpolation!r}")
        k_in = self.index(sampler, "input", ptr, "accessors", required=True)
        times = self.accessor(k_in, widths=("SCALAR",)).reshape(-1)
        if self.item("accessors", k_in).get("componentType") != 5126:
            raise _err(self.path, f"/accessors/{k_in}", "animation times must be float (5126) scalars")
        if np.any(np.diff(times) <= 0) or times[0] < 0:
            raise _err(self.path, f"/accessors/{k_in}", "animation times must be >= 0 and increase strictly")
        k_out = self.index(sampler, "output", ptr, "accessors", required=True)
        values = self.accessor(k_out, widths=("VEC4",) if path == "rotation" else ("SCALAR",) if path == "weights"
                               else ("VEC3",))
        per_key = 3 if interpolation == "CUBICSPLINE" else 1
        if path == "weights":           # one value per target and key: rows of the targets' weights
            values = np.asarray(values, np.float64).reshape(-1)
            if len(values) != per_key * len(times) * targets:
                raise _err(self.path, f"/accessors/{k_out}", f"{len(values)} weights for {len(times)} key times "
                           f"and {targets} morph targets; {interpolation} needs {per_key * len(times) * targets}")
            return times, values.reshape(per_key * len(times), targets), interpolation
        if len(values) != per_key * len(times):
            raise _err(self.path, f"/accessors/{k_out}", f"{len(values)} output values for {len(times)} key times; "
                       f"{interpolation} needs {per_key * len(times)}")
        return times, values, interpolation

    def _scene_index(self) -> int:
        scenes = self.get(self.doc, "scenes", list, "", [])
        k = self.get(self.doc, "scene", int, "", 0 if scenes else None)
        if k is not None and not 0 <= k < max(len(scenes), 1):
            raise _err(self.path, "/scene", f"scene index {k} is out of range: the file has {len(scenes)} scenes")
        return k or 0

    def _roots(self, n_nodes: int) -> list[int]:
        scenes = self.get(self.doc, "scenes", list, "", [])
        if not scenes:          # no scene: every node that is nobody's child
            children = set()
            for k in range(n_nodes):
                children.update(c for c in self.get(self.item("nodes", k), "children", list, f"/nodes/{k}", [])
                                if isinstance(c, int))
            return [k for k in range(n_nodes) if k not in children]
        s = self._scene_index()
        roots = self.get(self.item("scenes", s), "nodes", list, f"/scenes/{s}", [])
        for r, k in enumerate(roots):
            if not isinstance(k, int) or isinstance(k, bool) or not 0 <= k < n_nodes:
                raise _err(self.path, f"/scenes/{s}/nodes/{r}", f"expected a node index in 0..{n_nodes - 1}, got "
                           f"{json.dumps(k)[:40]}")
        return roots

    def _local(self, node: dict, ptr: str, animated: dict | None = None) -> np.ndarray:
        matrix = self.numbers(node, "matrix", ptr, 16, None)
        if matrix is not None and animated:
            raise _err(self.path, f"{ptr}/matrix", "a node with a matrix cannot be animated (glTF: use TRS)")
        if matrix is not None:
            m = np.array(matrix, np.float64).reshape(4, 4).T          # column-major
            if not np.allclose(m[3], [0, 0, 0, 1]):
                raise _err(self.path, f"{ptr}/matrix", "the last row must be 0, 0, 0, 1 (an affine transform)")
            return m
        t = self.numbers(node, "translation", ptr, 3, [0.0, 0.0, 0.0])
        q = self.numbers(node, "rotation", ptr, 4, [0.0, 0.0, 0.0, 1.0])
        s = self.numbers(node, "scale", ptr, 3, [1.0, 1.0, 1.0])
        if animated and self.time is not None:
            t = animated["translation"](self.time) if "translation" in animated else t
            q = animated["rotation"](self.time) if "rotation" in animated else q
            s = animated["scale"](self.time) if "scale" in animated else s
        norm = math.sqrt(sum(v * v for v in q))
        if not norm > 0:
            raise _err(self.path, f"{ptr}/rotation", "a rotation quaternion must not be zero")
        m = np.eye(4)
        m[:3, :3] = quaternion_matrix(np.array(q) / norm) * np.array(s)
        m[:3, 3] = t
        if not np.isfinite(m).all():        # animated values far out of range
            raise _err(self.path, ptr, "the node's transform is not finite")
        return m

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
        if mode < 4:
            raise _err(self.path, f"{ptr}/mode", f"{_MODES[mode]} cannot be rendered: warp_spt draws triangles "
                       "(strips and fans are converted)")
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

    # ---------------------------------------------------------------------------- textures/materials

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

    def _base_texture(self, mat: int | None) -> dict | None:
        if mat is None:
            return None
        pbr = self.obj(self.item("materials", mat), "pbrMetallicRoughness", f"/materials/{mat}")
        return self.get(pbr, "baseColorTexture", dict, f"/materials/{mat}/pbrMetallicRoughness")

    def _uv_set(self, mat: int | None) -> int:
        info = self._base_texture(mat)
        if info is None:
            return 0
        ptr = f"/materials/{mat}/pbrMetallicRoughness/baseColorTexture"
        tt = self.get(self.obj(info, "extensions", ptr), "KHR_texture_transform", dict, f"{ptr}/extensions")
        k = self.get(tt, "texCoord", int, f"{ptr}/extensions/KHR_texture_transform") if tt else None
        k = self.get(info, "texCoord", int, ptr, 0) if k is None else k
        if not 0 <= k < 16:
            raise _err(self.path, f"{ptr}/texCoord", f"texCoord {k} must lie in 0..15")
        return k

    def _uv_transform(self, uv: np.ndarray, mat: int | None) -> np.ndarray:
        """KHR_texture_transform of the base colour texture: offset + rotation(-r) * scale * uv, in
        glTF's uv space (v down), as the extension defines it."""
        info = self._base_texture(mat)
        if info is None:
            return uv
        ptr = f"/materials/{mat}/pbrMetallicRoughness/baseColorTexture/extensions/KHR_texture_transform"
        tt = self.get(self.obj(info, "extensions", ptr.rsplit("/", 2)[0]), "KHR_texture_transform", dict,
                      ptr.rsplit("/", 1)[0])
        if not tt:
            return uv
        offset = self.numbers(tt, "offset", ptr, 2, [0.0, 0.0])
        rotation = self.get(tt, "rotation", float, ptr, 0.0)
        scale = self.numbers(tt, "scale", ptr, 2, [1.0, 1.0])
        c, s = math.cos(rotation), math.sin(rotation)
        su, sv = uv[:, 0] * scale[0], uv[:, 1] * scale[1]
        out = np.stack([c * su + s * sv + offset[0], -s * su + c * sv + offset[1]], axis=1)
        if not np.abs(out).max(initial=0.0) <= MAX_UV:       # stored as float32 (also NaN)
            raise _err(self.path, ptr, f"offset {offset} and scale {scale} take texture coordinates beyond "
                       f"+-{MAX_UV:g}")
        return out

    def _image(self, tex: int, ptr: str) -> TextureRef:
        t = self.item("textures", tex)
        tptr = f"/textures/{tex}"
        source = self.index(t, "source", tptr, "images")
        if source is None:
            raise _err(self.path, tptr, "a texture without a 'source' image (or only an extension's) is not read")
        img = self.item("images", source)
        iptr = f"/images/{source}"
        uri = self.get(img, "uri", str, iptr)
        name = f"images/{source}"
        if uri is not None and not uri.startswith("data:"):
            self._local_file(uri, f"{iptr}/uri")             # exists and is local; the loader reads it
            return TextureRef(urllib.parse.unquote(uri), self.path, 0)
        if uri is not None:
            return TextureRef(name, self.path, 0, image=self.uri(uri, f"{iptr}/uri"))
        view = self.index(img, "bufferView", iptr, "bufferViews")
        if view is None:
            raise _err(self.path, iptr, "an image needs a 'uri' or a 'bufferView'")
        buf, off, length, _ = self.view(view)
        return TextureRef(name, self.path, 0, image=buf[off:off + length])

    def _checked_material(self, mat: int | None, names: list[str]) -> tuple[str, Material]:
        """:meth:`_material`, its values within the material schema's ranges (SceneError naming the
        file, the material's pointer and name, and the field)."""
        from warp_spt.scene.model import MaterialValueError

        try:
            return self._material(mat, names)
        except MaterialValueError as err:   # its name is "FILE: NAME"; the file is named already
            raise _err(self.path, f"/materials/{mat}" if mat is not None else "",
                       f"material {err.name.split(': ', 1)[-1]!r}: {err.problem}") from None

    def _material(self, mat: int | None, names: list[str]) -> tuple[str, Material]:
        """A unique name and a material of the ``pbr`` kind: glTF's metallic-roughness model and the
        KHR_materials_* that the kind has columns for. The packed metallic-roughness texture is named by
        both maps (the kind reads its B and G channels); the base colour texture's alpha is the opacity
        map of a MASK or BLEND material. Colour maps are decoded from sRGB by the loader (by slot)."""
        if mat is None:          # glTF's default material: white, metallic 1, roughness 1
            name = f"{Path(self.path).name}: default material"
            return name, self._pbr_material(name, dict(base_color=(1.0, 1.0, 1.0), metallic=1.0, roughness=1.0))
        rec = self._material_record(mat)
        # named after the file: materials of the same name in two files of a scene stay apart
        name = f"{Path(self.path).name}: {rec.name or f'material {mat}'}"
        while name in names or name == CHECKER_NAME:
            name = f"{name} ({mat})"
        mptr = f"/materials/{mat}"
        eptr = f"{mptr}/extensions"
        ext = lambda key: self.obj(rec.extensions, key, eptr)      # noqa: E731
        image = lambda k, where: None if k is None else self._image(k, f"{mptr}/{where}")  # noqa: E731
        tex = image(rec.base_color_texture, "pbrMetallicRoughness/baseColorTexture")
        strength = self.get(ext("KHR_materials_emissive_strength"), "emissiveStrength", float,
                            f"{eptr}/KHR_materials_emissive_strength", 1.0)
        orm = image(rec.metallic_roughness_texture, "pbrMetallicRoughness/metallicRoughnessTexture")
        fields = dict(base_color=tuple(min(max(c, 0.0), 1.0) for c in rec.base_color[:3]), base_color_map=tex,
                      metallic=min(max(rec.metallic, 0.0), 1.0), roughness=min(max(rec.roughness, 0.0), 1.0),
                      metallic_map=orm, roughness_map=orm,
                      normal=min(max(rec.normal_scale, 0.0), 10.0), normal_map=image(rec.normal_texture, "normalTexture"),
                      emission=tuple(min(max(c * strength, 0.0), MAX_RADIANCE) for c in rec.emissive),
                      emission_map=image(rec.emissive_texture, "emissiveTexture"))
        if rec.alpha_mode == "MASK":
            fields["alpha_cutoff"] = rec.alpha_cutoff
        if rec.alpha_mode != "OPAQUE":
            fields["opacity"] = min(max(rec.base_color[3], 0.0), 1.0)
            fields["opacity_map"] = tex
        ior = ext("KHR_materials_ior")
        if ior:
            fields["ior"] = self.get(ior, "ior", float, f"{eptr}/KHR_materials_ior", 1.5)
        transmission = ext("KHR_materials_transmission")
        if transmission:
            fields["transmission"] = self.get(transmission, "transmissionFactor", float,
                                              f"{eptr}/KHR_materials_transmission", 0.0)
            # without KHR_materials_volume a transmissive glTF surface is thin-walled
            volume = ext("KHR_materials_volume")
            fields["thin"] = not volume or self.get(volume, "thicknessFactor", float,
                                                    f"{eptr}/KHR_materials_volume", 0.0) == 0.0
        specular = ext("KHR_materials_specular")
        if specular:
            sptr = f"{eptr}/KHR_materials_specular"
            fields["specular"] = self.get(specular, "specularFactor", float, sptr, 1.0)
            fields["specular_color"] = tuple(self.numbers(specular, "specularColorFactor", sptr, 3, [1.0, 1.0, 1.0]))
        anisotropy = ext("KHR_materials_anisotropy")
        if anisotropy:
            aptr = f"{eptr}/KHR_materials_anisotropy"
            fields["anisotropy"] = self.get(anisotropy, "anisotropyStrength", float, aptr, 0.0)
            fields["anisotropy_rotation"] = self.get(anisotropy, "anisotropyRotation", float, aptr, 0.0)
        return name, self._pbr_material(name, fields)

    def _pbr_material(self, name: str, fields: dict) -> Material:
        material = Material.pbr(name, **fields)
        material.source, material.seed_dialect = self.path, False
        return material

    def _material_record(self, mat: int) -> GltfMaterial:
        m = self.item("materials", mat)
        ptr = f"/materials/{mat}"
        pbr = self.obj(m, "pbrMetallicRoughness", ptr)
        pptr = f"{ptr}/pbrMetallicRoughness"

        def texture(obj: dict, key: str, p: str) -> int | None:
            info = self.get(obj, key, dict, p)
            return None if info is None else self.index(info, "index", f"{p}/{key}", "textures", required=True)

        normal = self.get(m, "normalTexture", dict, ptr) or {}
        alpha = self.get(m, "alphaMode", str, ptr, "OPAQUE")
        if alpha not in ("OPAQUE", "MASK", "BLEND"):
            raise _err(self.path, f"{ptr}/alphaMode", f"expected OPAQUE, MASK or BLEND, got {alpha!r}")
        return GltfMaterial(
            name=self.get(m, "name", str, ptr, ""),
            base_color=tuple(self.numbers(pbr, "baseColorFactor", pptr, 4, [1.0, 1.0, 1.0, 1.0])),
            base_color_texture=texture(pbr, "baseColorTexture", pptr),
            metallic=self.get(pbr, "metallicFactor", float, pptr, 1.0),
            roughness=self.get(pbr, "roughnessFactor", float, pptr, 1.0),
            metallic_roughness_texture=texture(pbr, "metallicRoughnessTexture", pptr),
            normal_texture=texture(m, "normalTexture", ptr),
            normal_scale=self.get(normal, "scale", float, f"{ptr}/normalTexture", 1.0),
            emissive=tuple(self.numbers(m, "emissiveFactor", ptr, 3, [0.0, 0.0, 0.0])),
            emissive_texture=texture(m, "emissiveTexture", ptr),
            alpha_mode=alpha,
            alpha_cutoff=self.get(m, "alphaCutoff", float, ptr, 0.5),
            double_sided=self.get(m, "doubleSided", bool, ptr, False),
            extensions=self.obj(m, "extensions", ptr),
        )

    # ------------------------------------------------------------------------------- cameras, lights

    def _camera(self, k: int, node: int, world: np.ndarray) -> GltfCamera:
        c = self.item("cameras", k)
        ptr = f"/cameras/{k}"
        kind = self.get(c, "type", str, ptr, required=True)
        name = self.get(c, "name", str, ptr, "")
        if kind != "perspective":
            self.warnings.append(f"{self.path}: {ptr}: {kind} cameras are not read (only perspective ones)")
            kind_ok = False
        else:
            kind_ok = True
        p = self.obj(c, "perspective", ptr, required=kind_ok) if kind_ok else {}
        yfov = self.get(p, "yfov", float, f"{ptr}/perspective", 0.8, required=kind_ok)
        if not 0 < yfov < math.pi:
            raise _err(self.path, f"{ptr}/perspective/yfov", f"yfov {yfov:g} must lie in (0, pi) radians")
        aspect = self.get(p, "aspectRatio", float, f"{ptr}/perspective")
        if aspect is not None and not aspect > 0:
            raise _err(self.path, f"{ptr}/perspective/aspectRatio", f"aspectRatio {aspect:g} must be positive")
        direction, up = _unit(world[:3, :3] @ [0, 0, -1]), _unit(world[:3, :3] @ [0, 1, 0])
        if direction is None or up is None:
            raise _err(self.path, f"/nodes/{node}", "the camera's node transform is singular")
        return GltfCamera(name=name, index=k, node=node, position=tuple(float(c) for c in world[:3, 3]), direction=direction, up=up,
                          yfov=yfov, aspect=aspect, znear=self.get(p, "znear", float, f"{ptr}/perspective", 0.0),
                          kind=kind)

    def _light(self, ref: dict, ptr: str, world: np.ndarray) -> GltfLight:
        k = self.get(ref, "light", int, ptr, required=True)
        lights = self.get(self.obj(self.obj(self.doc, "extensions", ""), "KHR_lights_punctual", "/extensions"),
                          "lights", list, "/extensions/KHR_lights_punctual", [])
        if not 0 <= k < len(lights) or not isinstance(lights[k], dict):
            raise _err(self.path, f"{ptr}/light", f"light index {k} is out of range: the file has {len(lights)} lights")
        lptr = f"/extensions/KHR_lights_punctual/lights/{k}"
        light = lights[k]
        kind = self.get(light, "type", str, lptr, required=True)
        if kind not in ("point", "spot", "directional"):
            raise _err(self.path, f"{lptr}/type", f"expected point, spot or directional, got {kind!r}")
        spot = self.obj(light, "spot", lptr)
        out = GltfLight(
            name=self.get(light, "name", str, lptr, ""), kind=kind,
            color=tuple(self.numbers(light, "color", lptr, 3, [1.0, 1.0, 1.0])),
            intensity=self.get(light, "intensity", float, lptr, 1.0),
            position=tuple(float(c) for c in world[:3, 3]), direction=_unit(world[:3, :3] @ [0, 0, -1]) or (0.0, 0.0, -1.0),
            range=self.get(light, "range", float, lptr),
            inner_cone=self.get(spot, "innerConeAngle", float, f"{lptr}/spot", 0.0),
            outer_cone=self.get(spot, "outerConeAngle", float, f"{lptr}/spot", math.pi / 4))
        # the extension's ranges, each naming its member; then the renderer's light's own bounds
        if not all(0.0 <= c <= 1.0 for c in out.color):
            raise _err(self.path, f"{lptr}/color", f"each component must lie in [0, 1] (linear RGB), got {list(out.color)}")
        if not out.intensity >= 0.0:
            raise _err(self.path, f"{lptr}/intensity", f"must be at least 0, got {out.intensity:g}")
        if out.range is not None and not out.range > 0.0:
            raise _err(self.path, f"{lptr}/range", f"must be above 0, got {out.range:g}")
        if kind == "spot" and not 0.0 <= out.inner_cone < out.outer_cone <= math.pi / 2:
            raise _err(self.path, f"{lptr}/spot", f"expected 0 <= innerConeAngle < outerConeAngle <= pi/2 (radians), "
                       f"got {out.inner_cone:g} and {out.outer_cone:g}")
        try:
            out.to_scene()
        except ValueError as err:
            raise _err(self.path, lptr, str(err)) from None
        return out

    # ----------------------------------------------------------------------------------- the object

    def _object(self, parts: list[tuple], names: list[str], materials: dict[str, Material], extras: GltfExtras
                ) -> ObjData:
        from warp_spt.scene.validate import nonzero_area

        positions, faces, ftex, fnrm, fmat, uvs, nrms, cols = [], [], [], [], [], [], [], []
        nv = nt = nn = 0
        dropped = 0
        for p, tri, uv, n, c, row in parts:
            if len(tri) == 0:
                continue
            keep = nonzero_area(p, tri)
            dropped += int(len(keep) - np.count_nonzero(keep))
            tri = tri[keep]
            positions.append(p)
            faces.append(tri + nv)
            ftex.append(tri + nt if uv is not None else np.full_like(tri, -1))
            fnrm.append(tri + nn if n is not None else np.full_like(tri, -1))
            fmat.append(np.full(len(tri), row, np.int32))
            cols.append((c, len(tri)))
            if uv is not None:
                uvs.append(uv)
                nt += len(uv)
            if n is not None:
                nrms.append(n)
                nn += len(n)
            nv += len(p)
        cat = lambda xs, shape, dtype: np.concatenate(xs).astype(dtype) if xs else np.zeros(shape, dtype)  # noqa: E731
        data = ObjData(
            path=self.path, positions=cat(positions, (0, 3), np.float64),
            texcoords=cat(uvs, (0, 2), np.float32), normals=cat(nrms, (0, 3), np.float32),
            faces=cat(faces, (0, 3), np.int32), face_texcoords=cat(ftex, (0, 3), np.int32),
            face_normals=cat(fnrm, (0, 3), np.int32), face_material=cat(fmat, (0,), np.int32),
            spheres=np.zeros((0, 4)), sphere_material=np.zeros(0, np.int32),
            material_names=names, material_lines=[0] * len(names), dropped_degenerate=dropped,
            materials=materials, extras=extras, warnings=list(self.warnings),
        )
        if any(c is not None for c, _ in cols):
            from warp_spt.io.ply import colour_texture_fits, colour_texture_note

            coloured = sum(nf for c, nf in cols if c is not None)
            if colour_texture_fits(coloured):
                self._bake_colours(data, positions, cols)
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


def _channel(times: np.ndarray, values: np.ndarray, interpolation: str, rotation: bool):
    """A function of time giving the channel's value: clamped outside the key times."""
    return lambda t: sample_channel(times, values, interpolation, t, rotation)


def sample_channel(times: np.ndarray, values: np.ndarray, interpolation: str, t: float,
                   rotation: bool = False) -> list[float]:
    """glTF's keyframe interpolation at time ``t`` (seconds; clamped to the key times): STEP holds the
    previous key, LINEAR blends (rotations: spherical, along the shorter arc), CUBICSPLINE is the
    Hermite spline of the (in-tangent, value, out-tangent) triples with tangents scaled by the key
    interval; rotations are normalised."""
    cubic = interpolation == "CUBICSPLINE"
    keys = values.reshape(len(times), 3, -1)[:, 1] if cubic else values
    if t <= times[0] or len(times) == 1:
        out = keys[0]
    elif t >= times[-1]:
        out = keys[-1]
    else:
        k = int(np.searchsorted(times, t, side="right")) - 1
        t0, t1 = float(times[k]), float(times[k + 1])
        dt = t1 - t0
        u = (t - t0) / dt
        if interpolation == "STEP":
            out = keys[k]
        elif cubic:
            v = values.reshape(len(times), 3, -1)
            u2, u3 = u * u, u * u * u
            out = ((2 * u3 - 3 * u2 + 1) * v[k, 1] + (u3 - 2 * u2 + u) * dt * v[k, 2]
                   + (-2 * u3 + 3 * u2) * v[k + 1, 1] + (u3 - u2) * dt * v[k + 1, 0])
        elif rotation:
            out = slerp(keys[k], keys[k + 1], u)
        else:
            out = (1 - u) * keys[k] + u * keys[k + 1]
    out = np.asarray(out, np.float64)
    if rotation:
        norm = np.linalg.norm(out)
        out = out / norm if norm > 0 else np.array([0.0, 0.0, 0.0, 1.0])
    return [float(c) for c in out]


def slerp(a: np.ndarray, b: np.ndarray, u: float) -> np.ndarray:
    """Spherical interpolation of unit quaternions along the shorter arc."""
    na, nb = np.linalg.norm(a), np.linalg.norm(b)
    if not (na > 0 and nb > 0):         # a zero key: no rotation to blend from or to
        return np.asarray(a if na > 0 else b if nb > 0 else [0.0, 0.0, 0.0, 1.0], np.float64)
    a = np.asarray(a, np.float64) / na
    b = np.asarray(b, np.float64) / nb
    dot = float(np.dot(a, b))
    if dot < 0:
        b, dot = -b, -dot
    if dot > 0.9995:                     # nearly equal: the chord is the arc
        out = a + u * (b - a)
        return out / np.linalg.norm(out)
    theta = math.acos(dot)
    return (math.sin((1 - u) * theta) * a + math.sin(u * theta) * b) / math.sin(theta)


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


def quaternion_matrix(q: np.ndarray) -> np.ndarray:
    """The rotation matrix of a unit quaternion (x, y, z, w)."""
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def _unit(v: np.ndarray) -> tuple[float, float, float] | None:
    n = float(np.linalg.norm(v))
    return tuple(float(c) for c in np.asarray(v) / n) if n > 0 and math.isfinite(n) else None



def choose_camera(cameras: list[GltfCamera], choice: str | int, width: int, height: int):
    """The renderer's :class:`~warp_spt.scene.camera.Camera` for the camera named ``choice`` (or at
    index ``choice`` in file order) among ``cameras`` (``Scene.cameras``), for a ``width`` x
    ``height`` image: the file's vertical field of view is kept (the horizontal one follows from the
    image's aspect, as glTF viewers do), a pinhole, with the camera's own up direction (so its roll is
    kept). Raises ValueError naming the cameras there are."""
    from warp_spt.scene.camera import Camera

    if not cameras:
        raise ValueError("the model files define no cameras")
    names = [c.name for c in cameras]
    text = str(choice)
    if text in names:
        if names.count(text) > 1:
            raise ValueError(f"{names.count(text)} cameras are named {text!r}; give an index (0..{len(cameras) - 1})")
        cam = cameras[names.index(text)]
    elif text.lstrip("-").isdigit() and 0 <= int(text) < len(cameras):
        cam = cameras[int(text)]
    else:
        listed = ", ".join(f"{k}: {n!r}" if n else f"{k} (unnamed)" for k, n in enumerate(names))
        raise ValueError(f"no camera {text!r}; the files have {len(cameras)} camera{'s' * (len(cameras) > 1)}: "
                         f"{listed}")
    if cam.kind != "perspective":
        raise ValueError(f"camera {text!r} is {cam.kind} (/cameras/{cam.index}); only perspective cameras can be "
                         "looked through")
    camera = Camera(position=cam.position, direction=cam.direction, fov=cam.fov_degrees(width, height),
                    aperture=0.0, focus=1.0, up=cam.up)
    camera.validate()
    return camera
