"""A glTF file's JSON document: the GLB and JSON containers, the version and required extensions, and
the JSON typing every section reads through (each wrong value a :class:`SceneError` naming the file
and the JSON pointer)."""

from __future__ import annotations

import json
import math
import struct
from pathlib import Path

from warp_spt.scene.errors import SceneError

MAX_JSON_BYTES = 64 << 20
GLB_MAGIC, GLB_JSON, GLB_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942
SUPPORTED_EXTENSIONS = {"KHR_mesh_quantization", "KHR_texture_transform", "KHR_lights_punctual",
                        "KHR_materials_emissive_strength", "KHR_materials_ior", "KHR_materials_transmission",
                        "KHR_materials_volume", "KHR_materials_specular", "KHR_materials_anisotropy",
                        "KHR_materials_pbrSpecularGlossiness", "KHR_materials_clearcoat",
                        "KHR_materials_sheen"}
# extensions a file may use that leave its look as the renderer draws it when they are not read: metadata,
# material variants (the default is drawn), image formats beside a PNG or JPEG fallback
LOOK_NEUTRAL = {"KHR_xmp_json_ld", "KHR_materials_variants", "KHR_texture_basisu", "EXT_texture_webp",
                "EXT_texture_avif", "MSFT_texture_dds"}


def _err(path: str, pointer: str, message: str) -> SceneError:
    return SceneError(path, 0, f"{pointer}: {message}" if pointer else message)


_NUMBER_TYPES = frozenset((int, float))


class Document:
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
        self._warned: set = set()
        used = self.get(self.doc, "extensionsUsed", list, "", []) or []
        for k, name in enumerate(used):
            if isinstance(name, str) and name not in SUPPORTED_EXTENSIONS | LOOK_NEUTRAL:
                self.warn_once(name, f"/extensionsUsed/{k}: {name} is not read: the file renders without it")

    def warn_once(self, key, message: str) -> None:
        """One warning per ``key`` (an extension, an image) however many parts of the file meet it."""
        if key not in self._warned:
            self._warned.add(key)
            self.warnings.append(f"{self.path}: {message}")

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
        # JSON numbers are exactly int and float here (bool, a subclass of int, is not one); checked
        # by whole-list builtins: a 200,000-node file checks 600,000 of these lists
        if len(value) != n or not set(map(type, value)) <= _NUMBER_TYPES or \
                not all(map(math.isfinite, value)):
            raise _err(self.path, f"{pointer}/{key}", f"expected {n} finite numbers, got {json.dumps(value)[:80]}")
        return list(map(float, value))
