"""glTF 2.0 reader (io/gltf.py): containers, accessors, the node tree, materials, cameras, errors."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from tests.support import format_files
from tests.support.format_files import (
    CUBE_POSITIONS,
    CUBE_TRIANGLES,
    TEXTURE_2X2,
    GltfBuilder,
    gltf_box,
    gltf_camera_and_light,
    gltf_sparse,
    gltf_textured_box,
    gltf_two_instances,
    two_instances_expected,
)
from warp_spt.io.gltf import MAX_NODE_DEPTH, parse_gltf_bytes, world_triangles
from warp_spt.scene.errors import SceneError
from warp_spt.scene.lights import PointLight, SunLight
from warp_spt.scene.material_schema import KIND_PBR


def _load(g: GltfBuilder, container: str = "gltf"):
    data = g.glb() if container == "glb" else g.gltf()[0]
    return parse_gltf_bytes(data, f"scene.{container}")


@pytest.mark.parametrize("container", ["gltf", "glb"])
def test_the_box_is_translated_by_its_node(container):
    d = _load(gltf_box(), container)
    assert np.array_equal(d.positions, CUBE_POSITIONS + [1, 2, 3])
    assert np.array_equal(d.faces, CUBE_TRIANGLES)


def test_an_external_bin_file_is_read_relative_to_the_gltf(tmp_path):
    from warp_spt.io.gltf import load_gltf

    js, bn = gltf_box().gltf("data/box bits.bin")
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "box bits.bin").write_bytes(bn)
    (tmp_path / "box.gltf").write_bytes(js.replace(b"box bits", b"box%20bits"))      # a percent-encoded URI
    assert np.array_equal(load_gltf(tmp_path / "box.gltf").positions, CUBE_POSITIONS + [1, 2, 3])
    (tmp_path / "data" / "box bits.bin").unlink()
    with pytest.raises(SceneError, match=r"box.gltf: /buffers/0/uri: 'data/box%20bits.bin' cannot be read"):
        load_gltf(tmp_path / "box.gltf")


def test_two_instances_with_parent_child_and_matrix_transforms():
    d = _load(gltf_two_instances())
    positions, faces = world_triangles(d)
    assert np.allclose(positions, two_instances_expected(), atol=1e-12)
    assert [(node, mesh) for node, mesh, _ in d.extras.instances] == [(0, 0), (2, 0)]
    assert np.array_equal(faces, np.concatenate([CUBE_TRIANGLES, CUBE_TRIANGLES + 8]))
    # the shared mesh is kept once, in its own space, with both nodes' world matrices
    assert len(d.faces) == 0 and len(d.extras.placed) == 1
    sub, transforms = d.extras.placed[0]
    assert np.array_equal(sub.positions, CUBE_POSITIONS) and transforms.shape == (2, 4, 4)


def test_a_mirroring_node_reverses_the_winding_and_normals_use_the_inverse_transpose():
    g = GltfBuilder()
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float64)
    normals = np.array([[1, 1, 1]] * 3, np.float32) / np.sqrt(3)
    g.mesh(tri, NORMAL=(normals, "VEC3", 5126))
    g.node(mesh=0, scale=[-1, 2, 1])
    d = _load(g)
    assert np.array_equal(d.positions, [[0, 0, 0], [-1, 0, 0], [0, 2, 0]])
    assert np.array_equal(d.faces, [[2, 1, 0]])
    p = d.positions[d.faces[0]]
    geometric = np.cross(p[1] - p[0], p[2] - p[0])
    assert geometric[2] > 0                       # the triangle still faces +z, as before the mirror
    # inverse transpose of diag(-1, 2, 1) is diag(-1, 1/2, 1): (1, 1, 1) -> (-1, 0.5, 1), normalised
    assert np.allclose(d.normals[0], np.array([-1, 0.5, 1]) / 1.5, atol=1e-6)


def test_interleaved_stride_normalized_quantized_positions():
    """KHR_mesh_quantization: int16 normalized positions interleaved with uint8 normalized uv."""
    g = GltfBuilder()
    q = np.array([[0, 0, 0], [32767, 0, 0], [0, -32767, 16384]], np.int16)
    uv = np.array([[0, 0], [255, 0], [0, 255]], np.uint8)
    rows = np.zeros(3, np.dtype([("p", "<i2", (3,)), ("pad", "u1", 2), ("uv", "u1", (2,)), ("pad2", "u1", 2)]))
    rows["p"], rows["uv"] = q, uv
    view = g.view(rows.tobytes(), stride=12)
    g.doc["accessors"] += [{"bufferView": view, "componentType": 5122, "normalized": True, "count": 3, "type": "VEC3"},
                           {"bufferView": view, "byteOffset": 8, "componentType": 5121, "normalized": True,
                            "count": 3, "type": "VEC2"}]
    g.doc["meshes"].append({"primitives": [{"attributes": {"POSITION": 0, "TEXCOORD_0": 1}}]})
    g.doc["extensionsRequired"] = g.doc["extensionsUsed"] = ["KHR_mesh_quantization"]
    g.node(mesh=0)
    d = _load(g)
    assert np.allclose(d.positions, [[0, 0, 0], [1, 0, 0], [0, -1, 16384 / 32767]], atol=0)
    assert np.allclose(d.texcoords, [[0, 1], [1, 1], [0, 0]])          # v flipped: glTF's v runs down


@pytest.mark.parametrize("mode, expected", [
    (5, [[0, 1, 2], [2, 1, 3], [2, 3, 4]]),            # strip: odd triangles (i+1, i, i+2)
    (6, [[1, 2, 0], [2, 3, 0], [3, 4, 0]]),            # fan: (i+1, i+2, 0)
])
def test_strips_and_fans_are_converted(mode, expected):
    g = GltfBuilder()
    pos = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.5], [0, 2, 0.25]], np.float64)
    g.mesh(pos, np.arange(5), mode=mode)
    g.node(mesh=0)
    assert np.array_equal(_load(g).faces, expected)


@pytest.mark.parametrize("mode, name", [(0, "points"), (1, "lines"), (3, "line strips")])
def test_points_and_lines_are_skipped_with_one_warning(mode, name):
    """The file's triangles are drawn, as importers draw them; its point or line primitive is not."""
    g = gltf_box()
    lines = dict(g.doc["meshes"][0]["primitives"][0], mode=mode)
    g.doc["meshes"][0]["primitives"].append(lines)
    g.node(mesh=0)                      # two placements of the mesh: still one warning
    d = _load(g)
    assert len(world_triangles(d)[1]) == 2 * len(CUBE_TRIANGLES)
    assert d.warnings == [f"scene.gltf: /meshes/0/primitives/1/mode: {name} are skipped: warp_spt draws triangles "
                          "(strips and fans are converted)"]


def test_sparse_accessors_with_and_without_a_base_view():
    d = _load(gltf_sparse())
    assert np.array_equal(d.positions[:3], [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    assert np.array_equal(d.faces, [[0, 1, 2]]) and d.dropped_degenerate == 1
    # the second primitive's positions: zeros with vertex 2 set to (0, 0, 2)
    assert np.array_equal(d.positions[3:], [[0, 0, 0], [0, 0, 0], [0, 0, 2]])


def test_the_textured_box_has_its_data_uri_image_and_transformed_uv():
    from warp_spt.io.loader import load_scene

    d = _load(gltf_textured_box())
    m = d.materials["scene.gltf: checker"]
    assert isinstance(m.base_color_map.image, bytes) and m.kind == KIND_PBR and m.metallic == 0.0
    # uv = (x + 0.5, y + 0.5) offset by (0.25, 0), then v -> 1 - v
    want = np.stack([CUBE_POSITIONS[:, 0] + 0.75, 1 - (CUBE_POSITIONS[:, 1] + 0.5)], axis=1)
    assert np.allclose(d.texcoords, want)
    scene = load_scene([d])
    assert np.array_equal(scene.textures[0], TEXTURE_2X2.astype(np.float32) / 255)


def test_cameras_and_lights_are_placed_by_their_nodes():
    d = _load(gltf_camera_and_light())
    front, side = d.extras.cameras
    assert (front.name, front.position, front.direction, front.up) == ("front", (0, 0, 5), (0, 0, -1), (0, 1, 0))
    assert side.name == "side" and side.aspect == 1.5 and side.position == (5, 0, 0)
    # 90 degrees about +y turns -z into -x
    assert np.allclose(side.direction, (-1, 0, 0), atol=1e-12) and np.allclose(side.up, (0, 1, 0))
    # horizontal fov for a square image equals yfov; for 2:1 it is 2 atan(2 tan(yfov / 2))
    assert math.isclose(front.fov_degrees(100, 100), math.degrees(0.8))
    assert math.isclose(front.fov_degrees(200, 100), math.degrees(2 * math.atan(2 * math.tan(0.4))))
    (light,) = d.extras.lights
    assert (light.kind, light.color, light.intensity, light.position) == ("point", (1, 0.5, 0.25), 20, (0, 3, 0))
    assert d.warnings == []
    # the renderer's light: candela taken as W/sr, times the colour (docs/lights.md)
    assert light.to_scene() == PointLight(position=(0, 3, 0), intensity=(20, 10, 5), name=light.name or "point")


def test_gltf_spot_and_directional_lights_map_onto_the_renderers():
    from warp_spt.io.gltf import GltfLight

    sun = GltfLight("s", "directional", (1, 1, 1), 3.0, (0, 0, 0), (0.0, -1.0, 0.0)).to_scene()
    assert sun == SunLight(direction=(0, 1, 0), color=(3, 3, 3), name="s")     # towards the sun: against -Z
    spot = GltfLight("", "spot", (1, 1, 1), 2.0, (1, 2, 3), (0, 0, -1), inner_cone=0.2, outer_cone=0.5).to_scene()
    assert spot.name == "spot" and spot.direction == (0, 0, -1) and spot.position == (1, 2, 3)
    assert math.isclose(spot.inner_deg, math.degrees(0.2)) and math.isclose(spot.outer_deg, math.degrees(0.5))


def _mutated(make, change):
    g = make()
    change(g.doc)
    return g


BAD = [
    (lambda d: d["accessors"][0].update(count=10 ** 9), "/accessors/0/count: count 1000000000 exceeds the buffer view"),
    (lambda d: d["accessors"][0].update(componentType=5124), "/accessors/0/componentType: unknown componentType"),
    (lambda d: d["accessors"][0].update(type="VEC2"), "/accessors/0/type: expected type VEC3, got 'VEC2'"),
    (lambda d: d["accessors"][0].update(count="8"), "/accessors/0/count: expected an integer, got \"8\""),
    (lambda d: d["accessors"][0].update(byteOffset=4), "/accessors/0/count: count 8 exceeds the buffer view"),
    (lambda d: d["bufferViews"][0].update(byteLength=10 ** 6), "/bufferViews/0: bytes 0..1000000 exceed the buffer"),
    (lambda d: d["bufferViews"][0].update(byteStride=6), "/bufferViews/0/byteStride: byteStride 6 must be"),
    (lambda d: d["bufferViews"][1].update(buffer=3), "/bufferViews/1/buffer: buffers index 3 is out of range"),
    (lambda d: d["accessors"][1].update(componentType=5126), "/accessors/1: indices must be unsigned integers"),
    (lambda d: d["meshes"][0]["primitives"][0]["attributes"].pop("POSITION"),
     "/meshes/0/primitives/0/attributes: missing required property 'POSITION'"),
    (lambda d: d["nodes"][0].update(children=[0]), "/nodes/0/children/0: node 0 is reached twice"),
    (lambda d: d["nodes"][0].update(rotation=[0, 0, 0, 0]), "/nodes/0/rotation: a rotation quaternion must not be"),
    (lambda d: d["nodes"][0].update(translation=[1, 2]), "/nodes/0/translation: expected 3 finite numbers"),
    (lambda d: d["nodes"][0].update(mesh=True), "/nodes/0/mesh: expected an integer, got true"),
    (lambda d: d.update(extensionsRequired=["KHR_draco_mesh_compression"]),
     "/extensionsRequired: the file requires KHR_draco_mesh_compression"),
    (lambda d: d["asset"].update(version="1.0"), "/asset/version: glTF 1.0: only glTF 2.0 is read"),
    (lambda d: d.update(scene=4), "/scene: scene index 4 is out of range"),
    (lambda d: d["scenes"][0].update(nodes=[7]), "/scenes/0/nodes/0: expected a node index in 0..0, got 7"),
]


@pytest.mark.parametrize("change, message", BAD, ids=[m.split(":")[0] + f"-{k}" for k, (_, m) in enumerate(BAD)])
def test_bad_documents_name_the_json_path(change, message):
    g = _mutated(gltf_box, change)
    with pytest.raises(SceneError) as err:
        _load(g)
    assert str(err.value).startswith(f"scene.gltf: {message}"), str(err.value)


def test_index_out_of_range_and_depth_and_two_parents():
    g = gltf_box()
    g.doc["accessors"][1]["count"] = 3
    idx_view = g.doc["accessors"][1]["bufferView"]
    data = bytearray(g.bin)
    off = g.doc["bufferViews"][idx_view]["byteOffset"]
    data[off:off + 2] = np.uint16(9).tobytes()
    g.bin = bytes(data)
    with pytest.raises(SceneError, match=r"^scene.gltf: /accessors/1: index 9 is out of range: POSITION has 8"):
        _load(g)
    deep = GltfBuilder()
    deep.mesh(CUBE_POSITIONS, CUBE_TRIANGLES)
    deep.node(children=[1])
    for k in range(1, MAX_NODE_DEPTH + 3):
        deep.node(root=False, children=[k + 1])
    deep.node(root=False, mesh=0)
    with pytest.raises(SceneError, match=f"nodes nest more than {MAX_NODE_DEPTH} deep"):
        _load(deep)
    two = gltf_box()
    two.node(children=[0])
    with pytest.raises(SceneError, match="node 0 is reached twice"):
        _load(two)


def test_glb_container_errors():
    good = gltf_box().glb()
    for data, message in [
        (good[:-4], "the GLB header says"),
        (good[:4] + b"\x01\x00\x00\x00" + good[8:], "GLB version 1: only glTF 2.0 is read"),
        (good[:12] + b"\xff\xff\xff\x7f" + good[16:], "GLB chunk 0 at byte 12: length 2147483647 runs past"),
        (good[:16] + b"BIN\x00" + good[20:], "the first GLB chunk must be the JSON chunk"),
    ]:
        with pytest.raises(SceneError, match=message):
            parse_gltf_bytes(data, "scene.glb")


def test_json_nesting_and_data_uri_base64_are_checked():
    with pytest.raises(SceneError, match="^deep.gltf: the JSON nests deeper than Python's recursion limit"):
        parse_gltf_bytes(b'{"asset": {"version": "2.0"}, "x": ' + b"[" * 100000 + b"]" * 100000 + b"}", "deep.gltf")
    js = json.loads(gltf_box().gltf()[0])
    js["buffers"][0]["uri"] = js["buffers"][0]["uri"][:-3] + "!!!"
    with pytest.raises(SceneError, match=r"/buffers/0/uri: bad base64 data"):
        parse_gltf_bytes(json.dumps(js).encode(), "scene.gltf")
    js["buffers"][0]["uri"] = "https://example.com/box.bin"
    with pytest.raises(SceneError, match=r"/buffers/0/uri: only relative file URIs and data URIs are read"):
        parse_gltf_bytes(json.dumps(js).encode(), "scene.gltf")


def test_through_the_loader_and_the_cli(tmp_path, capsys):
    from warp_spt.cli.main import main
    from warp_spt.io.loader import load_scene

    (tmp_path / "box.glb").write_bytes(gltf_box().glb())
    (tmp_path / "box.obj").write_bytes(gltf_box().glb())          # by content
    scene = load_scene([tmp_path / "box.glb", tmp_path / "box.obj"])
    assert scene.num_triangles == 24 and not scene.seed_dialect    # Y up by the command line's rule
    bad = _mutated(gltf_box, lambda d: d["accessors"][0].update(count=10 ** 9))
    (tmp_path / "bad.gltf").write_bytes(bad.gltf()[0])
    assert main(["-obj", str(tmp_path / "bad.gltf"), "-res", "8", "8", "-out", str(tmp_path / "o.png")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"warp-spt: error: {tmp_path / 'bad.gltf'}: /accessors/0/count: count 1000000000 exceeds")


def test_choose_camera_by_name_or_index_keeps_the_vertical_fov():
    from warp_spt.io.gltf import choose_camera

    cams = _load(gltf_camera_and_light()).extras.cameras
    side = choose_camera(cams, "side", 300, 200)
    assert side == choose_camera(cams, "1", 300, 200) == choose_camera(cams, 1, 300, 200)
    assert np.allclose(side.position, (5, 0, 0)) and np.allclose(side.direction, (-1, 0, 0)) and side.aperture == 0
    # vertical half-angle 0.25 rad: the image plane at focus f is f tan(0.25) high (half), 1.5 times as wide
    assert math.isclose(math.tan(math.radians(side.fov) / 2), 1.5 * math.tan(0.25))
    with pytest.raises(ValueError, match="no camera 'back'; the files have 2 cameras: 0: 'front', 1: 'side'"):
        choose_camera(cams, "back", 10, 10)
    with pytest.raises(ValueError, match="no camera '2'"):
        choose_camera(cams, 2, 10, 10)
    with pytest.raises(ValueError, match="the model files define no cameras"):
        choose_camera([], 0, 10, 10)


def test_the_cli_camera_flag(tmp_path, capsys):
    from warp_spt.cli.main import main
    from warp_spt.cli.options import UsageError, parse_args

    (tmp_path / "c.gltf").write_bytes(gltf_camera_and_light().gltf()[0])
    with pytest.raises(UsageError, match="--camera uses a camera of the model files"):
        parse_args(["-obj", str(tmp_path / "c.gltf"), "--camera", "side", "--frame"])
    assert main(["-obj", str(tmp_path / "c.gltf"), "--camera", "back", "-res", "8", "8",
                 "-out", str(tmp_path / "o.png")]) == 1
    assert capsys.readouterr().err.endswith("error: --camera back: no camera 'back'; the files have 2 cameras: 0: 'front', "
                                            "1: 'side'\n")


def test_animation_static_files_and_the_api_read_gltf_and_ply(tmp_path):
    import warp_spt
    from tests.support.format_files import ply_bytes
    from warp_spt.animation import ObjSequence

    (tmp_path / "box.glb").write_bytes(gltf_box().glb())
    (tmp_path / "p.ply").write_bytes(ply_bytes("binary_little_endian"))
    seq = ObjSequence([str(tmp_path / "box.glb"), str(tmp_path / "p.ply")])
    assert seq.scene(0).num_triangles == 12 + 6 and seq.scene(1) is seq.scene(0) and seq.loads == 2
    assert np.array_equal(warp_spt.load_gltf(tmp_path / "box.glb").faces, CUBE_TRIANGLES)
    assert len(warp_spt.load_ply(tmp_path / "p.ply").faces) == 6


def test_vertex_colours_times_the_base_colour_factor_are_baked():
    from warp_spt.device.textures import sample_texture_np

    g = GltfBuilder()
    tri = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float64)
    rgba = np.array([[255, 0, 0, 255], [0, 255, 0, 0], [0, 0, 255, 128]], np.uint8)
    g.mesh(tri, COLOR_0=(rgba, "VEC4", 5121))
    g.doc["accessors"][-1]["normalized"] = True
    g.doc["meshes"][0]["primitives"][0]["material"] = 0
    g.doc["materials"] = [{"name": "half red", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 1, 1, 1]}}]
    g.mesh(tri + [2, 0, 0])                         # a second mesh without colours keeps its material
    g.doc["meshes"][1]["primitives"][0]["material"] = 0
    g.node(mesh=0)
    g.node(mesh=1)
    d = _load(g)
    assert d.material_names == ["Inner_CheckerTexture", "scene.gltf: half red", "scene.gltf: half red (vertex colours)"]
    assert np.array_equal(d.face_material, [2, 1])
    image = d.materials["scene.gltf: half red (vertex colours)"].base_color_map.image
    corners = d.texcoords[d.face_texcoords[0]]
    assert np.allclose(sample_texture_np(image, corners), [[0.5, 0, 0], [0, 1, 0], [0, 0, 1]])
    assert np.all(d.face_texcoords[1] == -1)


def test_base_colour_textures_are_decoded_from_srgb(tmp_path):
    import base64
    import io

    from PIL import Image

    from warp_spt.io.loader import load_scene

    buf = io.BytesIO()
    Image.fromarray(np.full((1, 1, 3), 128, np.uint8)).save(buf, format="PNG")
    g = gltf_textured_box()
    g.doc["images"] = [{"uri": "data:image/png;base64," + base64.b64encode(buf.getvalue()).decode()}]
    scene = load_scene([_load(g)])
    # IEC 61966-2-1: ((c + 0.055) / 1.055) ** 2.4 for c = 128 / 255 above 0.04045
    assert np.allclose(scene.textures[0], ((128 / 255 + 0.055) / 1.055) ** 2.4, rtol=1e-6)


def test_an_accessor_of_zeros_cannot_allocate_from_a_forged_count():
    g = gltf_sparse()
    g.doc["accessors"][1]["count"] = 10 ** 8            # no bufferView: zeros, then the sparse values
    with pytest.raises(SceneError, match=r"/accessors/1/count: count 100000000 of zeros \(1200000000 bytes\) is far"):
        _load(g)


def test_sample_channel_by_hand():
    from warp_spt.io.gltf import sample_channel, slerp

    times = np.array([0.0, 1.0, 3.0])
    v = np.array([[0.0, 0, 0], [2, 0, 0], [2, 4, 0]])
    assert sample_channel(times, v, "LINEAR", 0.25) == [0.5, 0, 0]
    assert sample_channel(times, v, "LINEAR", 2.0) == [2, 2, 0]             # halfway through [1, 3]
    assert sample_channel(times, v, "STEP", 2.9) == [2, 0, 0]
    assert sample_channel(times, v, "LINEAR", -1) == [0, 0, 0] and sample_channel(times, v, "LINEAR", 9) == [2, 4, 0]
    # Hermite on [1, 3] at u = 1/2 with value tangents (in a, out b) scaled by dt = 2:
    # h00 = 1/2, h10 = 1/8, h01 = 1/2, h11 = -1/8: 0.5 v1 + 0.125 * 2 b1 + 0.5 v2 - 0.125 * 2 a2
    a = np.array([[0.0, 0, 0], [0, 0, 0], [0, 0, 8]])
    b = np.array([[0.0, 0, 0], [4, 0, 0], [0, 0, 0]])
    cubic = np.stack([a, v, b], axis=1).reshape(-1, 3)
    assert np.allclose(sample_channel(times, cubic, "CUBICSPLINE", 2.0), [2 + 1, 2, -2])
    s = math.sqrt(0.5)
    q = slerp(np.array([0, 0, 0, 1.0]), np.array([0, 0, s, s]), 0.5)       # 0 -> 90 degrees about z
    assert np.allclose(q, [0, 0, math.sin(math.pi / 8), math.cos(math.pi / 8)])
    # the shorter arc: -q is the same rotation as q
    assert np.allclose(slerp(np.array([0, 0, 0, 1.0]), -np.array([0, 0, s, s]), 0.5), q)


@pytest.mark.parametrize("interpolation", ["LINEAR", "STEP", "CUBICSPLINE"])
def test_animated_nodes_are_posed_at_the_time_asked(interpolation):
    g = format_files.gltf_animated(interpolation)
    data = g.gltf()[0]
    assert np.array_equal(parse_gltf_bytes(data, "a.gltf").positions, CUBE_POSITIONS)     # no time: the bind pose
    d = parse_gltf_bytes(data, "a.gltf", time=0.5)
    assert d.extras.time_range == (0.0, 2.0)
    # a rigidly moving node's mesh stays in its own space (its BVH is kept from frame to frame)
    assert len(d.faces) == 0 and np.array_equal(d.extras.placed[0][0].positions, CUBE_POSITIONS)
    # rotation at t = 0.5: a quarter of the way from 0 to 90 degrees about z (slerp: 22.5 degrees)
    a = math.radians(22.5)
    r = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    if interpolation == "LINEAR":
        t = np.array([1.0, 0, 0])
    elif interpolation == "STEP":
        t = np.array([0.0, 0, 0])     # held at the key of t = 0 (the rotation's sampler is LINEAR in all)
    else:     # Hermite on [0, 1] at u = 1/2, dt = 1: 0.5 v0 + 0.125 b0 + 0.5 v1 - 0.125 a1 = (1 + 0.125, 0, 0)
        t = np.array([1.125, 0, 0])
    assert np.allclose(world_triangles(d)[0], CUBE_POSITIONS @ r.T + t, atol=1e-6)


def test_an_animated_gltf_through_frames(tmp_path):
    from warp_spt.animation import ObjSequence
    from warp_spt.cli.main import main

    (tmp_path / "a.glb").write_bytes(format_files.gltf_animated().glb())
    seq = ObjSequence([str(tmp_path / "a.glb")], fps=4)
    for k in (0, 2, 9):                              # t = 0, 0.5 and 2.25 (past the end: the last pose)
        want = world_triangles(parse_gltf_bytes(format_files.gltf_animated().glb(), "a.glb", time=k / 4))[0]
        got = next(seq.scene(k).placed_meshes()).positions
        assert np.array_equal(got, want)
    assert seq.loads == 1 and seq.scene(2) is seq.scene(2) and seq.scene(2) is not seq.scene(0)
    # frame 1 rendered alone equals frame 1 of the sequence, bit for bit, through one camera (without
    # one, the sequence is framed over both frames' bounds and frame 1 alone over its own)
    common = ["-obj", str(tmp_path / "a.glb"), "--fps", "4", "-res", "8", "8", "-sr", "2", "--quiet",
              "-cam", *"1 2 12 0 0 -1 38 12 0".split(), "--up", "y"]
    assert main([*common, "--frames", "0:2", "-out", str(tmp_path / "seq_{frame}.npy")]) == 0
    assert main([*common, "--frames", "1:2", "-out", str(tmp_path / "one_{frame}.npy")]) == 0
    assert (tmp_path / "seq_1.npy").read_bytes() == (tmp_path / "one_1.npy").read_bytes()
    assert (tmp_path / "seq_0.npy").read_bytes() != (tmp_path / "seq_1.npy").read_bytes()


@pytest.mark.parametrize("time", [0.0, 1.0, 2.0])
def test_a_two_bone_skinned_bar_against_a_numpy_reference(time):
    d = parse_gltf_bytes(format_files.gltf_skinned_bar().gltf()[0], "bar.gltf", time=time)
    # reference: joint worlds W0 = I, W1 = T(1, 0, 0) Rz(theta), theta = 45 degrees per second;
    # inverse binds B0 = I, B1 = T(-1, 0, 0); v' = sum_j w_j W_j B_j v
    theta = math.radians(45 * time)
    rz = np.eye(4)
    rz[:2, :2] = [[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]]
    t1, b1 = np.eye(4), np.eye(4)
    t1[0, 3], b1[0, 3] = 1, -1
    mats = [np.eye(4), t1 @ rz @ b1]
    v = np.concatenate([format_files.BAR_POSITIONS, np.ones((6, 1))], axis=1)
    want = sum(w[:, None] * (v @ m.T) for w, m in zip(format_files.BAR_WEIGHTS.T, mats))[:, :3]
    assert np.allclose(d.positions, want, atol=1e-6)
    if time == 2.0:      # the tip turned 90 degrees about joint 1: x = 2 -> (1, 1), (1 - 0.2, 1)
        assert np.allclose(d.positions[4:], [[1, 1, 0], [0.8, 1, 0]], atol=1e-6)


def test_morph_target_weights_from_the_mesh_and_the_animation():
    g = format_files.gltf_morph()
    data = g.gltf()[0]
    assert np.allclose(parse_gltf_bytes(data, "m.gltf").positions[2], [0, 1, 0.5])          # mesh weights
    assert np.allclose(parse_gltf_bytes(data, "m.gltf", time=0.25).positions[2], [0, 1, 0.25])
    g.doc["nodes"][0]["weights"] = [2.0]                                                       # node's win
    assert np.allclose(parse_gltf_bytes(g.gltf()[0], "m.gltf").positions[2], [0, 1, 2.0])
    g.doc["meshes"][0]["weights"] = [1, 2]
    g.doc["nodes"][0].pop("weights")
    with pytest.raises(SceneError, match=r"/meshes/0/primitives/0/targets: 1 morph targets for 2 weights"):
        parse_gltf_bytes(g.gltf()[0], "m.gltf")


def test_materials_map_onto_the_pbr_kind():
    import base64

    from warp_spt.io.loader import load_scene
    from warp_spt.scene.model import texture_decode

    g = gltf_textured_box()
    png = "data:image/png;base64," + base64.b64encode(format_files.png_2x2()).decode()
    flat = "data:image/png;base64," + base64.b64encode(format_files.png_2x2(format_files.NORMAL_2X2)).decode()
    g.doc["images"] += [{"uri": png}, {"uri": flat}]
    g.doc["textures"] += [{"source": 1}, {"source": 2}]
    g.doc["materials"] = [{
        "name": "full", "alphaMode": "MASK", "alphaCutoff": 0.3, "emissiveFactor": [0.5, 0.25, 0],
        "normalTexture": {"index": 2, "scale": 0.7},
        "pbrMetallicRoughness": {"baseColorFactor": [0.2, 0.4, 0.6, 0.9], "baseColorTexture": {"index": 0},
                                 "metallicFactor": 0.3, "roughnessFactor": 0.8,
                                 "metallicRoughnessTexture": {"index": 1}},
        "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4},
                       "KHR_materials_ior": {"ior": 1.33}, "KHR_materials_transmission": {"transmissionFactor": 0.5},
                       "KHR_materials_specular": {"specularFactor": 0.4, "specularColorFactor": [1, 0.5, 0.5]},
                       "KHR_materials_anisotropy": {"anisotropyStrength": 0.6, "anisotropyRotation": 1.0}}}]
    d = _load(g)
    m = d.materials["scene.gltf: full"]
    assert m.kind == KIND_PBR and m.base_color == (0.2, 0.4, 0.6) and (m.metallic, m.roughness) == (0.3, 0.8)
    assert m.metallic_map is m.roughness_map and m.metallic_map.path == "images/1"       # the packed texture
    assert (m.normal, m.normal_map.path) == (0.7, "images/2")
    assert m.emission == (2.0, 1.0, 0.0) and m.alpha_cutoff == 0.3 and m.opacity == 0.9
    assert m.opacity_map is m.base_color_map
    assert (m.ior, m.transmission, m.thin, m.specular, m.specular_color) == (1.33, 0.5, True, 0.4, (1, 0.5, 0.5))
    assert (m.anisotropy, m.anisotropy_rotation) == (0.6, 1.0)
    assert [texture_decode(m, c) for c in ("base_color", "opacity", "metallic", "normal")] == \
        ["srgb", "alpha", "linear", "normal"]                     # a normal map: linear, checked to be one
    scene = load_scene([d])
    # base colour (sRGB), its alpha, the packed metallic-roughness (read once for both maps), the normal map
    assert len(scene.textures) == 4
    d2 = _load(gltf_box())
    default = d2.materials["scene.gltf: default material"]
    assert (default.kind, default.base_color, default.metallic, default.roughness) == (KIND_PBR, (1, 1, 1), 1, 1)


def test_an_animated_gltf_gives_the_frames_of_its_time_range(tmp_path):
    from PIL import Image

    from warp_spt.animation import ObjSequence
    from warp_spt.cli.main import main

    (tmp_path / "a.glb").write_bytes(format_files.gltf_animated().glb())      # keys over t in [0, 2]
    (tmp_path / "box.glb").write_bytes(gltf_box().glb())
    assert ObjSequence([str(tmp_path / "a.glb"), str(tmp_path / "box.glb")], fps=4).default_frames() == range(0, 9)
    assert ObjSequence([str(tmp_path / "box.glb")]).default_frames() is None
    assert main(["-obj", str(tmp_path / "a.glb"), "--fps", "1", "--gif", str(tmp_path / "a.gif"), "-res", "8", "8",
                 "-sr", "1", "--quiet", "--look-at", "1", "0", "0"]) == 0
    with Image.open(tmp_path / "a.gif") as gif:
        assert gif.n_frames == 3                                              # t = 0, 1, 2


def test_an_animated_camera_follows_its_node_per_frame(tmp_path):
    from warp_spt.animation import ObjSequence
    from warp_spt.io.gltf import choose_camera

    g = gltf_camera_and_light()
    times = g.accessor(np.array([0.0, 1.0], np.float32), "SCALAR", 5126)
    moves = g.accessor(np.array([[0, 0, 5], [0, 0, 9]], np.float32), "VEC3", 5126)
    g.doc["animations"] = [{"samplers": [{"input": times, "output": moves}],
                            "channels": [{"sampler": 0, "target": {"node": 1, "path": "translation"}}]}]
    (tmp_path / "c.glb").write_bytes(g.glb())
    seq = ObjSequence([str(tmp_path / "c.glb")], fps=2)
    positions = [choose_camera(seq.scene(k).cameras, "front", 10, 10).position for k in (0, 1, 2)]
    assert np.allclose(positions, [(0, 0, 5), (0, 0, 7), (0, 0, 9)])


def test_materials_of_the_same_name_in_two_files_stay_apart(tmp_path):
    from warp_spt.io.loader import load_scene

    for name, colour in (("a.gltf", [1, 0, 0, 1]), ("b.gltf", [0, 0, 1, 1])):
        g = gltf_box()
        g.doc["meshes"][0]["primitives"][0]["material"] = 0
        g.doc["materials"] = [{"name": "Material", "pbrMetallicRoughness": {"baseColorFactor": colour}}]
        (tmp_path / name).write_bytes(g.gltf()[0])
    scene = load_scene([tmp_path / "a.gltf", tmp_path / "b.gltf"])
    rows = [scene.materials.names.index(n) for n in ("a.gltf: Material", "b.gltf: Material")]
    assert [m.face_material[0] for m in scene.meshes] == rows
    assert np.array_equal(scene.materials.base_color[rows], [[1, 0, 0], [0, 0, 1]])
