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

The reader is one class assembled from a module per section of the format, each building on the
one below: ``document.py`` (containers, JSON typing), ``accessors.py`` (buffers, views, accessors),
``materials.py``, ``meshes.py`` (primitives, skins, morphs), ``animation.py``, ``cameras_lights.py``
and ``scene_graph.py`` (the node walk; the reader itself).
"""

from __future__ import annotations

import os

from warp_spt.gltf.animation import sample_channel, slerp
from warp_spt.gltf.cameras_lights import GltfCamera, GltfLight, choose_camera
from warp_spt.gltf.materials import GltfMaterial
from warp_spt.gltf.meshes import GltfExtras
from warp_spt.gltf.scene_graph import MAX_NODE_DEPTH, Reader, quaternion_matrix, world_triangles
from warp_spt.io.tokens import read_file
from warp_spt.scene.model import ObjData

__all__ = ["load_gltf", "parse_gltf_bytes", "choose_camera", "world_triangles", "sample_channel", "slerp",
           "quaternion_matrix", "MAX_NODE_DEPTH", "GltfCamera", "GltfLight", "GltfMaterial", "GltfExtras"]


def load_gltf(path: str | os.PathLike[str], time: float | None = None) -> ObjData:
    """Read a ``.gltf`` or ``.glb`` file into world-space triangles; see the module docs. ``time``
    (seconds) poses the nodes by the file's first animation (:func:`sample_channel`); None: the
    nodes' own transforms."""
    path = str(path)
    return parse_gltf_bytes(read_file(path, "glTF", binary=True), path, time)


def parse_gltf_bytes(data: bytes, path: str = "<input>", time: float | None = None) -> ObjData:
    """Parse glTF JSON or GLB bytes; ``path`` names the file in errors and anchors relative URIs."""
    obj = Reader(data, path, time).run()
    obj.format = "glTF"             # Y up by definition (scene/conventions.up_axis)
    return obj

