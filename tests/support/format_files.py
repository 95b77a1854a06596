"""Small PLY and glTF files for the reader tests, written byte by byte here (no library), with the
positions they must load as computed by hand beside them.

``python tests/support/format_files.py OUTDIR`` writes every file into OUTDIR (to look at them or render them).
"""

from __future__ import annotations

import base64
import json
import struct
import sys
from pathlib import Path

import numpy as np

# ---------------------------------------------------------------------------------------------- PLY

# A unit square in z = 0 (4 vertices, coloured) and an apex above it; the square as one quad face and
# the four sides as one triangle strip with a restart.
PLY_POSITIONS = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [0.5, 0.5, 1]], np.float64)
PLY_COLOURS = np.array([[255, 0, 0], [0, 255, 0], [0, 0, 255], [255, 255, 255], [0, 0, 0]], np.uint8)
PLY_QUAD = [0, 3, 2, 1]                       # facing -z
PLY_STRIP = [0, 1, 4, -1, 1, 2, 4, 3, 0]      # strip 1: (0,1,4); strip 2: (1,2,4), (4,2,3)->swapped, (4,3,0)
# By hand: the quad fans to (0,3,2), (0,2,1); strip 1 gives (0,1,4); strip 2 gives (1,2,4), then the odd
# triangle (2,4,3) with its first two swapped -> (4,2,3), then (4,3,0).
PLY_TRIANGLES = np.array([[0, 3, 2], [0, 2, 1], [0, 1, 4], [1, 2, 4], [4, 2, 3], [4, 3, 0]], np.int32)


def ply_bytes(fmt: str = "ascii", *, colours: bool = True, junk: bool = True) -> bytes:
    """The pyramid above as PLY ``fmt`` ("ascii", "binary_little_endian", "binary_big_endian"), with
    an unknown element (``junk``, a scalar and a list per row) that the reader must skip."""
    head = ["ply", f"format {fmt} 1.0", "comment made by tests/support/format_files.py", "element vertex 5",
            "property float x", "property float y", "property double z"]
    if colours:
        head += ["property uchar red", "property uchar green", "property uchar blue"]
    if junk:
        head += ["element junk 2", "property short a", "property list uchar float b"]
    head += ["element face 1", "property list uchar int vertex_indices",
             "element tristrips 1", "property list int int vertex_indices", "end_header"]
    out = ("\n".join(head) + "\n").encode()
    if fmt == "ascii":
        rows = []
        for p, c in zip(PLY_POSITIONS, PLY_COLOURS):
            rows.append(" ".join(f"{x:g}" for x in p) + ("" if not colours else " " + " ".join(map(str, c))))
        if junk:
            rows += ["7 2 0.5 1.5", "-3 0"]
        rows.append("4 " + " ".join(map(str, PLY_QUAD)))
        rows.append(f"{len(PLY_STRIP)} " + " ".join(map(str, PLY_STRIP)))
        return out + ("\n".join(rows) + "\n").encode()
    e = "<" if fmt == "binary_little_endian" else ">"
    for p, c in zip(PLY_POSITIONS, PLY_COLOURS):
        out += struct.pack(e + "ffd", *p) + (struct.pack("BBB", *c) if colours else b"")
    if junk:
        out += struct.pack(e + "hB2f", 7, 2, 0.5, 1.5) + struct.pack(e + "hB", -3, 0)
    out += struct.pack(e + "B4i", 4, *PLY_QUAD)
    out += struct.pack(e + f"i{len(PLY_STRIP)}i", len(PLY_STRIP), *PLY_STRIP)
    return out


def binary_ply_mesh(positions: np.ndarray, faces: np.ndarray, big_endian: bool = False) -> bytes:
    """A binary PLY of float32 positions and triangle faces (the benchmark's large models)."""
    e = ">" if big_endian else "<"
    head = (f"ply\nformat binary_{'big' if big_endian else 'little'}_endian 1.0\nelement vertex {len(positions)}\n"
            "property float x\nproperty float y\nproperty float z\n"
            f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n").encode()
    face_rows = np.zeros(len(faces), np.dtype([("n", "u1"), ("i", e + "i4", (3,))]))
    face_rows["n"] = 3
    face_rows["i"] = faces
    return head + positions.astype(e + "f4").tobytes() + face_rows.tobytes()


# --------------------------------------------------------------------------------------------- glTF

def _pad4(b: bytes, fill: bytes = b"\x00") -> bytes:
    return b + fill * (-len(b) % 4)


class GltfBuilder:
    """A glTF document and its one binary buffer, built up accessor by accessor."""

    def __init__(self) -> None:
        self.doc: dict = {"asset": {"version": "2.0", "generator": "tests/support/format_files.py"},
                          "buffers": [], "bufferViews": [], "accessors": [], "meshes": [], "nodes": [],
                          "scenes": [{"nodes": []}], "scene": 0}
        self.bin = b""

    def view(self, data: bytes, stride: int | None = None, target: int | None = None) -> int:
        self.bin = _pad4(self.bin)
        v = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data)}
        if stride:
            v["byteStride"] = stride
        if target:
            v["target"] = target
        self.bin += data
        self.doc["bufferViews"].append(v)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, array: np.ndarray, type_: str, component: int, **extra) -> int:
        kinds = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
        view = self.view(np.ascontiguousarray(array, dtype=kinds[component]).tobytes())
        acc = {"bufferView": view, "componentType": component, "count": int(len(array)), "type": type_, **extra}
        if type_ == "VEC3" and component == 5126:
            acc["min"] = np.min(array, 0).tolist()
            acc["max"] = np.max(array, 0).tolist()
        self.doc["accessors"].append(acc)
        return len(self.doc["accessors"]) - 1

    def mesh(self, positions: np.ndarray, indices: np.ndarray | None = None, mode: int | None = None,
             **attributes) -> int:
        prim = {"attributes": {"POSITION": self.accessor(positions.astype(np.float32), "VEC3", 5126)}}
        for name, (array, type_, comp) in attributes.items():
            prim["attributes"][name] = self.accessor(array, type_, comp)
        if indices is not None:
            prim["indices"] = self.accessor(indices.astype(np.uint16).reshape(-1), "SCALAR", 5123)
        if mode is not None:
            prim["mode"] = mode
        self.doc["meshes"].append({"primitives": [prim]})
        return len(self.doc["meshes"]) - 1

    def node(self, root: bool = True, **fields) -> int:
        self.doc["nodes"].append(fields)
        k = len(self.doc["nodes"]) - 1
        if root:
            self.doc["scenes"][0]["nodes"].append(k)
        return k

    def gltf(self, bin_name: str | None = None) -> tuple[bytes, bytes | None]:
        """(the .gltf JSON, the .bin file or None): the buffer as a data URI when bin_name is None."""
        doc = json.loads(json.dumps(self.doc))
        if bin_name is None:
            uri = "data:application/octet-stream;base64," + base64.b64encode(self.bin).decode()
            doc["buffers"] = [{"byteLength": len(self.bin), "uri": uri}]
            return json.dumps(doc).encode(), None
        doc["buffers"] = [{"byteLength": len(self.bin), "uri": bin_name}]
        return json.dumps(doc).encode(), self.bin

    def glb(self) -> bytes:
        doc = json.loads(json.dumps(self.doc))
        doc["buffers"] = [{"byteLength": len(self.bin)}]
        js = _pad4(json.dumps(doc).encode(), b" ")
        bn = _pad4(self.bin)
        body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(bn), 0x004E4942) + bn
        return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


# A unit cube's 8 corners and 12 triangles (outward)
CUBE_POSITIONS = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)], np.float64)
CUBE_TRIANGLES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                           [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.int32)
# A 2x2 texture: red, green / blue, white (top row first)
TEXTURE_2X2 = np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]], np.uint8)


def png_2x2(pixels=None) -> bytes:
    """A 2x2 PNG of ``pixels`` (default TEXTURE_2X2)."""
    import io

    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(TEXTURE_2X2 if pixels is None else pixels).save(buf, format="PNG")
    return buf.getvalue()


# A flat tangent-space normal map (0, 0, 1) -> (128, 128, 255): what a normal texture must look like
NORMAL_2X2 = np.full((2, 2, 3), (128, 128, 255), dtype=np.uint8)


def gltf_box() -> GltfBuilder:
    """One cube, one node translated by (1, 2, 3)."""
    g = GltfBuilder()
    g.mesh(CUBE_POSITIONS, CUBE_TRIANGLES)
    g.node(mesh=0, translation=[1, 2, 3])
    return g


def gltf_two_instances() -> GltfBuilder:
    """One cube used by two nodes: a child scaled by 2 under a parent rotated 90 degrees about z and
    translated by (10, 0, 0); and a node with a column-major matrix translating by (0, 0, -5)."""
    g = GltfBuilder()
    g.mesh(CUBE_POSITIONS, CUBE_TRIANGLES)
    child = g.node(root=False, mesh=0, scale=[2, 2, 2])
    s = np.sqrt(0.5)
    g.node(children=[child], rotation=[0, 0, s, s], translation=[10, 0, 0])
    g.node(mesh=0, matrix=[1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, -5, 1])
    return g


def two_instances_expected() -> np.ndarray:
    """World positions of both nodes' cubes, by hand: rotation by 90 degrees about z maps
    (x, y, z) -> (-y, x, z); the first instance is 10 + R(2 p), the second p - (0, 0, 5)."""
    p = CUBE_POSITIONS
    first = np.stack([-2 * p[:, 1] + 10, 2 * p[:, 0], 2 * p[:, 2]], axis=1)
    second = p + [0, 0, -5]
    return np.concatenate([first, second])


def gltf_textured_box() -> GltfBuilder:
    """The cube with uv per vertex, a data-URI PNG as base colour, KHR_texture_transform (offset)."""
    g = GltfBuilder()
    uv = np.stack([CUBE_POSITIONS[:, 0] + 0.5, CUBE_POSITIONS[:, 1] + 0.5], axis=1).astype(np.float32)
    g.mesh(CUBE_POSITIONS, CUBE_TRIANGLES, TEXCOORD_0=(uv, "VEC2", 5126))
    g.doc["meshes"][0]["primitives"][0]["material"] = 0
    g.doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(png_2x2()).decode()}]
    g.doc["textures"] = [{"source": 0}]
    g.doc["materials"] = [{"name": "checker", "pbrMetallicRoughness": {
        "baseColorFactor": [1, 1, 1, 1], "metallicFactor": 0.0,
        "baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0.25, 0.0]}}}},
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 2.0}, "KHR_materials_ior": {"ior": 1.4},
                       "KHR_materials_specular": {"specularFactor": 0.5}}}]
    g.doc["extensionsUsed"] = ["KHR_texture_transform"]
    g.node(mesh=0)
    return g


def gltf_sparse() -> GltfBuilder:
    """A triangle whose positions come from a zero-filled base and a sparse accessor that sets
    vertices 1 and 2, and a second triangle with no bufferView at all (zeros) plus sparse values."""
    g = GltfBuilder()
    base = np.zeros((3, 3), np.float32)
    g.mesh(base)                                          # accessor 0: POSITION, zeros
    idx_view = g.view(np.array([1, 2], np.uint16).tobytes())
    val_view = g.view(np.array([[1, 0, 0], [0, 1, 0]], np.float32).tobytes())
    g.doc["accessors"][0]["sparse"] = {"count": 2, "indices": {"bufferView": idx_view, "componentType": 5123},
                                       "values": {"bufferView": val_view}}
    g.doc["accessors"][0]["max"] = [1, 1, 0]
    val2 = g.view(np.array([[0, 0, 2]], np.float32).tobytes())
    idx2 = g.view(np.array([2], np.uint8).tobytes())
    g.doc["accessors"].append({"componentType": 5126, "count": 3, "type": "VEC3", "sparse": {
        "count": 1, "indices": {"bufferView": idx2, "componentType": 5121}, "values": {"bufferView": val2}}})
    g.doc["meshes"][0]["primitives"].append({"attributes": {"POSITION": 1}})
    g.doc["accessors"][1]["min"], g.doc["accessors"][1]["max"] = [0, 0, 0], [0, 0, 2]
    g.node(mesh=0)
    return g
# The sparse file's second primitive is (0,0,0), (0,0,0), (0,0,2): zero area, dropped


def gltf_camera_and_light() -> GltfBuilder:
    """The cube at the origin, a perspective camera "front" at (0, 0, 5) looking down -z (glTF's
    default view direction), a second camera "side" at (5, 0, 0) turned 90 degrees about y to look
    down -x, and a point light."""
    g = GltfBuilder()
    g.mesh(CUBE_POSITIONS, CUBE_TRIANGLES)
    g.node(mesh=0)
    g.doc["cameras"] = [{"name": "front", "type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.01}},
                        {"name": "side", "type": "perspective",
                         "perspective": {"yfov": 0.5, "aspectRatio": 1.5, "znear": 0.1, "zfar": 100}}]
    g.node(camera=0, translation=[0, 0, 5])
    s = np.sqrt(0.5)
    g.node(camera=1, translation=[5, 0, 0], rotation=[0, s, 0, s])
    g.doc["extensionsUsed"] = ["KHR_lights_punctual"]
    g.doc["extensions"] = {"KHR_lights_punctual": {"lights": [
        {"name": "bulb", "type": "point", "color": [1, 0.5, 0.25], "intensity": 20}]}}
    g.node(translation=[0, 3, 0], extensions={"KHR_lights_punctual": {"light": 0}})
    return g


def write_all(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    for fmt in ("ascii", "binary_little_endian", "binary_big_endian"):
        (out / f"pyramid_{fmt}.ply").write_bytes(ply_bytes(fmt))
    (out / "box.glb").write_bytes(gltf_box().glb())
    js, bn = gltf_box().gltf("box.bin")
    (out / "box.gltf").write_bytes(js)
    (out / "box.bin").write_bytes(bn)
    for name, make in (("textured_box", gltf_textured_box), ("two_instances", gltf_two_instances),
                       ("sparse", gltf_sparse), ("camera_light", gltf_camera_and_light)):
        (out / f"{name}.gltf").write_bytes(make().gltf()[0])


if __name__ == "__main__":
    write_all(Path(sys.argv[1] if len(sys.argv) > 1 else "format_files"))


def gltf_animated(interpolation: str = "LINEAR") -> GltfBuilder:
    """The cube on node 0, animated over t in [0, 2]: translation keys (0,0,0), (2,0,0), (2,4,0) at t = 0,
    1, 2 and a rotation about z from 0 to 90 degrees over [0, 2]. CUBICSPLINE keys carry tangents:
    translation in-tangents 0 and out-tangents (1, 0, 0)."""
    g = GltfBuilder()
    g.mesh(CUBE_POSITIONS, CUBE_TRIANGLES)
    g.node(mesh=0)
    times = g.accessor(np.array([0.0, 1.0, 2.0], np.float32), "SCALAR", 5126)
    keys = np.array([[0, 0, 0], [2, 0, 0], [2, 4, 0]], np.float32)
    if interpolation == "CUBICSPLINE":
        zero, out_t = np.zeros(3, np.float32), np.array([1, 0, 0], np.float32)
        keys = np.stack([np.stack([zero, k, out_t]) for k in keys]).reshape(-1, 3)
    trans = g.accessor(keys, "VEC3", 5126)
    s = np.sqrt(0.5)
    rtimes = g.accessor(np.array([0.0, 2.0], np.float32), "SCALAR", 5126)
    rot = g.accessor(np.array([[0, 0, 0, 1], [0, 0, s, s]], np.float32), "VEC4", 5126)
    g.doc["animations"] = [{"samplers": [{"input": times, "output": trans, "interpolation": interpolation},
                                         {"input": rtimes, "output": rot}],
                            "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}},
                                         {"sampler": 1, "target": {"node": 0, "path": "rotation"}}]}]
    return g


# A strip along x (x = 0, 1, 2; y = 0, 0.2) skinned to two joints: joint 0 at the origin, joint 1 at
# x = 1 (its child), which turns about z from 0 to 90 degrees over t in [0, 2]. Weights: x = 0 all
# joint 0, x = 1 half and half, x = 2 all joint 1.
BAR_POSITIONS = np.array([[x, y, 0] for x in (0.0, 1.0, 2.0) for y in (0.0, 0.2)], np.float64)
BAR_WEIGHTS = np.array([[1, 0], [1, 0], [0.5, 0.5], [0.5, 0.5], [0, 1], [0, 1]], np.float64)


def gltf_skinned_bar() -> GltfBuilder:
    g = GltfBuilder()
    tri = np.array([[0, 2, 3], [0, 3, 1], [2, 4, 5], [2, 5, 3]])
    joints = np.array([[0, 1, 0, 0]] * 6, np.uint8)
    weights = np.concatenate([BAR_WEIGHTS, np.zeros((6, 2))], axis=1).astype(np.float32)
    g.mesh(BAR_POSITIONS, tri, JOINTS_0=(joints, "VEC4", 5121), WEIGHTS_0=(weights, "VEC4", 5126))
    g.node(children=[1])                                  # node 0: joint 0
    g.node(root=False, translation=[1, 0, 0])             # node 1: joint 1
    ibm = np.stack([np.eye(4), np.array([[1, 0, 0, -1], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])])
    ibm_acc = g.accessor(ibm.transpose(0, 2, 1).reshape(2, 16).astype(np.float32), "MAT4", 5126)
    g.doc["skins"] = [{"joints": [0, 1], "inverseBindMatrices": ibm_acc}]
    g.node(mesh=0, skin=0, translation=[50, 50, 50])      # node 2: ignored for a skinned mesh
    times = g.accessor(np.array([0.0, 2.0], np.float32), "SCALAR", 5126)
    s = np.sqrt(0.5)
    rot = g.accessor(np.array([[0, 0, 0, 1], [0, 0, s, s]], np.float32), "VEC4", 5126)
    g.doc["animations"] = [{"samplers": [{"input": times, "output": rot}],
                            "channels": [{"sampler": 0, "target": {"node": 1, "path": "rotation"}}]}]
    return g


def gltf_morph() -> GltfBuilder:
    """A triangle with one morph target lifting vertex 2 by (0, 0, 1); mesh weight 0.5; an animation
    of the weight from 0 to 1 over t in [0, 1]."""
    g = GltfBuilder()
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float64)
    g.mesh(tri)
    lift = g.accessor(np.array([[0, 0, 0], [0, 0, 0], [0, 0, 1]], np.float32), "VEC3", 5126)
    g.doc["meshes"][0]["primitives"][0]["targets"] = [{"POSITION": lift}]
    g.doc["meshes"][0]["weights"] = [0.5]
    g.node(mesh=0)
    times = g.accessor(np.array([0.0, 1.0], np.float32), "SCALAR", 5126)
    w = g.accessor(np.array([0.0, 1.0], np.float32), "SCALAR", 5126)
    g.doc["animations"] = [{"samplers": [{"input": times, "output": w}],
                            "channels": [{"sampler": 0, "target": {"node": 0, "path": "weights"}}]}]
    return g


def gltf_scaled_away(big_keys: bool = False) -> GltfBuilder:
    """:func:`gltf_animated`'s cube, also scaled from 1 to 0 over t in [0, 1] (hidden from then on: the
    usual way to hide an object); with ``big_keys`` its translation instead passes through x = 1e30 at t = 1."""
    g = gltf_animated()
    times = g.accessor(np.array([0.0, 1.0], np.float32), "SCALAR", 5126)
    anim = g.doc["animations"][0]
    if big_keys:
        ttimes = g.accessor(np.array([0.0, 1.0, 2.0], np.float32), "SCALAR", 5126)
        keys = g.accessor(np.array([[0, 0, 0], [1e30, 0, 0], [0, 0, 0]], np.float32), "VEC3", 5126)
        anim["samplers"][0] = {"input": ttimes, "output": keys}
        return g
    scale = g.accessor(np.array([[1, 1, 1], [0, 0, 0]], np.float32), "VEC3", 5126)
    anim["samplers"].append({"input": times, "output": scale})
    anim["channels"].append({"sampler": len(anim["samplers"]) - 1, "target": {"node": 0, "path": "scale"}})
    return g


def gltf_instanced_grid(n: int) -> GltfBuilder:
    """``n`` nodes placing one cube (half size) on a square grid in y = 0: the instancing stress file."""
    g = GltfBuilder()
    g.mesh(CUBE_POSITIONS, CUBE_TRIANGLES)
    side = int(np.ceil(n ** 0.5))
    for k in range(n):
        g.node(mesh=0, translation=[2.0 * (k % side), 0.0, 2.0 * (k // side)], scale=[0.5, 0.5, 0.5])
    return g


class FakeBlosc:
    """Stands in for python-blosc (not installed here; ``sys.modules["blosc"]``) as it behaves: the
    uncompressed size is taken from the chunk's 16-byte header and allocated before anything is
    decoded. Only stored ("memcpyed", flag 2) chunks are decoded; other data is refused as blosc
    refuses what it cannot decode. ``asked``: the sizes it was asked to allocate (none is allocated
    beyond 64 MiB: a MemoryError)."""

    def __init__(self):
        self.asked = []

    def decompress(self, chunk):
        if len(chunk) < 16:
            raise ValueError("input too short")
        nbytes, _, cbytes = struct.unpack("<III", bytes(chunk[4:16]))
        self.asked.append(nbytes)
        if nbytes > 1 << 26:
            raise MemoryError(f"asked for {nbytes} bytes")
        if not chunk[2] & 0x02 or not cbytes == len(chunk) == 16 + nbytes:
            raise ValueError("Error while decompressing data")
        return bytes(chunk[16:])


def blosc_grid(data: bytes, declared: int | None = None) -> bytes:
    """The uncompressed one-grid NanoVDB file ``data`` with its grid stored as one blosc chunk
    (memcpyed: the bytes as they are after blosc's header), the chunk's header declaring ``declared``
    uncompressed bytes if given."""
    start = 16 + 176 + struct.unpack("<I", data[16 + 136:16 + 140])[0]
    grid = data[start:]
    chunk = struct.pack("<BBBBIII", 2, 1, 0x02, 1, len(grid) if declared is None else declared, len(grid),
                        16 + len(grid)) + grid
    head = bytearray(data[:start])
    head[14:16] = struct.pack("<H", 2)                               # codec: blosc
    head[16 + 8:16 + 16] = struct.pack("<Q", 8 + len(chunk))         # the grid's size as stored
    return bytes(head) + struct.pack("<Q", len(chunk)) + chunk
