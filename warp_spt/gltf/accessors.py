"""Buffers (GLB chunk, data URIs, files beside the glTF), buffer views and accessors (any component
type, ``normalized`` integers, ``byteStride``, sparse accessors), each checked against what holds it
before anything is read or allocated."""

from __future__ import annotations

import base64
import binascii
import urllib.parse
from pathlib import Path

import numpy as np

from warp_spt.gltf.document import Document, _err
from warp_spt.io.paths import confine
from warp_spt.io.tokens import file_problem, read_file

MAX_DATA_URI_BYTES = 256 << 20         # decoded size of one base64 data URI
_COMPONENTS = {5120: "i1", 5121: "u1", 5122: "i2", 5123: "u2", 5125: "u4", 5126: "f4"}
_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


class Accessors(Document):
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

    def _local_file(self, uri: str, pointer: str, missing_ok: bool = False) -> Path | None:
        """The file ``uri`` names, inside the glTF's folder (else a SceneError: a file elsewhere is not
        read); one that cannot be read is a SceneError too, or with ``missing_ok`` a warning and None."""
        scheme = urllib.parse.urlsplit(uri).scheme
        if scheme and len(scheme) > 1:       # one letter: a Windows drive
            raise _err(self.path, pointer, f"only relative file URIs and data URIs are read, got {uri[:80]!r}")
        targets, refused = confine(urllib.parse.unquote(uri), self.folder, "the file")
        if refused:
            raise _err(self.path, pointer, refused)
        target = targets[0]
        problem = file_problem(target)
        if problem is not None:
            if not missing_ok:
                raise _err(self.path, pointer, f"{uri!r} cannot be read ({target}: {problem})")
            self.warn_once(pointer, f"{pointer}: {uri!r} cannot be read ({target}: {problem}): a neutral texel "
                           "stands for it")
            return None
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
