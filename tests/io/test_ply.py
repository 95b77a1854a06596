"""PLY reader (io/ply.py): the three encodings, strips, skipped elements, vertex colours, errors."""

from __future__ import annotations

import numpy as np
import pytest

from tests.support.format_files import (
    PLY_COLOURS,
    PLY_POSITIONS,
    PLY_TRIANGLES,
    binary_ply_mesh,
    ply_bytes,
)
from warp_spt.io.ply import VERTEX_COLOUR_MATERIAL, parse_ply_bytes, vertex_colour_texture
from warp_spt.scene.errors import SceneError

FORMATS = ("ascii", "binary_little_endian", "binary_big_endian")


@pytest.mark.parametrize("fmt", FORMATS)
@pytest.mark.parametrize("colours, junk", [(True, True), (False, False)])
def test_the_pyramid_reads_as_written_by_hand(fmt, colours, junk):
    d = parse_ply_bytes(ply_bytes(fmt, colours=colours, junk=junk), "p.ply")
    assert np.array_equal(d.positions, PLY_POSITIONS)
    assert np.array_equal(d.faces, PLY_TRIANGLES)          # quad fanned, strips restarted, odd ones swapped
    assert d.dropped_degenerate == 0
    assert (f"p.ply: {VERTEX_COLOUR_MATERIAL}" in d.materials) == colours
    assert np.all(d.face_material == (1 if colours else 0))


def test_strip_triangles_all_face_the_same_way():
    """Every side of the pyramid faces outward: the strip's alternate swap keeps one winding."""
    d = parse_ply_bytes(ply_bytes(), "p.ply")
    p = d.positions
    centre = p.mean(0)
    for f in d.faces:
        n = np.cross(p[f[1]] - p[f[0]], p[f[2]] - p[f[0]])
        assert np.dot(n, p[f].mean(0) - centre) > 0, f


def test_vertex_colours_are_the_corners_and_bilinear_is_linear_inside():
    from warp_spt.device.textures import sample_texture_np

    d = parse_ply_bytes(ply_bytes(), "p.ply")
    image = d.materials[f"p.ply: {VERTEX_COLOUR_MATERIAL}"].diffuse_map.image
    want = PLY_COLOURS.astype(np.float32) / 255
    uv = d.texcoords[d.face_texcoords]                       # (F, 3, 2)
    for f, corners in zip(d.faces, uv):
        for vertex, c in zip(f, corners):
            assert np.allclose(sample_texture_np(image, c[None]), want[vertex], atol=1e-6)
            assert np.allclose(sample_texture_np(image, c[None], bilinear=True), want[vertex], atol=1e-6)
        # barycentric points: bilinear filtering gives the linear blend of the three colours
        rng = np.random.default_rng(1)
        b = rng.dirichlet(np.ones(3), 20)
        got = sample_texture_np(image, b @ corners, bilinear=True)
        lin = b @ want[f]
        inside = np.all(lin + (b[:, 1:2] * 0) <= 1.0, axis=1)     # the fourth texel is clipped only beyond 1
        fourth = want[f[1]] + want[f[2]] - want[f[0]]
        if np.all((fourth >= 0) & (fourth <= 1)):
            assert np.allclose(got[inside], lin[inside], atol=1e-5)


def test_vertex_colour_texture_fits_many_triangles():
    f = 1001
    faces = np.arange(3 * f).reshape(f, 3) % 7
    uv, ft, image = vertex_colour_texture(np.random.default_rng(0).random((7, 3)), faces)
    assert ft.shape == (f, 3) and uv.shape == (3 * f, 2) and image.shape[0] * image.shape[1] >= 4 * f
    assert image.shape[0] * image.shape[1] <= 4 * (f + 2 * np.sqrt(f) + 1)


def test_normals_and_uv_are_per_corner():
    text = (b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
            b"property float nx\nproperty float ny\nproperty float nz\nproperty float s\nproperty float t\n"
            b"element face 1\nproperty list uchar uint vertex_index\nend_header\n"
            b"0 0 0 0 0 1 0 0\n1 0 0 0 0 1 1 0\n0 1 0 0 0 1 0 1\n3 0 1 2\n")
    d = parse_ply_bytes(text, "n.ply")
    assert np.array_equal(d.face_normals, [[0, 1, 2]]) and np.array_equal(d.normals[:, 2], [1, 1, 1])
    assert np.array_equal(d.texcoords[d.face_texcoords[0]], [[0, 0], [1, 0], [0, 1]])


def test_a_mixed_polygon_binary_file_takes_the_walk_and_agrees_with_ascii():
    # a triangle then a pentagon: the fast path (every row like the first) cannot read it
    pos = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [-1, 0.5, 0], [2, 2, 0]], np.float32)
    polys = [[0, 1, 5], [0, 1, 2, 3, 4]]
    head = ("ply\nformat {} 1.0\nelement vertex 6\nproperty float x\nproperty float y\nproperty float z\n"
            "element face 2\nproperty list uchar int vertex_indices\nend_header\n")
    binary = head.format("binary_little_endian").encode() + pos.astype("<f4").tobytes() + b"".join(
        bytes([len(p)]) + np.asarray(p, "<i4").tobytes() for p in polys)
    text = head.format("ascii").encode() + b"".join(
        (" ".join(f"{x:g}" for x in p) + "\n").encode() for p in pos) + b"".join(
        (f"{len(p)} " + " ".join(map(str, p)) + "\n").encode() for p in polys)
    a, b = parse_ply_bytes(binary, "m.ply"), parse_ply_bytes(text, "m.ply")
    assert np.array_equal(a.faces, [[0, 1, 5], [0, 1, 2], [0, 2, 3], [0, 3, 4]])
    assert np.array_equal(a.faces, b.faces) and np.array_equal(a.positions, b.positions)


def test_a_large_binary_mesh_round_trips():
    rng = np.random.default_rng(2)
    pos = rng.random((500, 3)).astype(np.float32)
    faces = rng.integers(0, 500, (2000, 3)).astype(np.int32)
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 0] != faces[:, 2])]
    for big in (False, True):
        d = parse_ply_bytes(binary_ply_mesh(pos, faces, big), "big.ply")
        assert np.array_equal(d.positions, pos.astype(np.float64)) and np.array_equal(d.faces, faces)


BAD = [
    (lambda b: b.replace(b"element vertex 5", b"element vertex 500000000"), "500000000 rows of 19 bytes need"),
    (lambda b: b.replace(b"element face 1", b"element face 9999999"), "9999999 rows need at least"),
    (lambda b: b.replace(b"property float x", b"property floot x"), ":5: expected 'property TYPE NAME'"),
    (lambda b: b.replace(b"little_endian", b"middle_endian"), ":2: expected 'format ascii|"),
    (lambda b: b[:-3], "ends at byte"),
    (lambda b: b.replace(b"end_header", b"end_hxader"), "no 'end_header' line"),
    (lambda b: b.replace(b"ply\n", b"plx\n", 1), "expected 'ply' on the first line"),
    (lambda b: b.replace(b"property float x\n", b""), "no scalar property 'x'"),
    (lambda b: b.replace(b"element vertex", b"elephant vertex"), "unknown header keyword 'elephant'"),
]


@pytest.mark.parametrize("mutate, message", BAD)
def test_bad_binary_files_are_one_clear_error(mutate, message):
    with pytest.raises(SceneError, match=message.replace("|", r"\|").replace("(", r"\(")) as err:
        parse_ply_bytes(mutate(ply_bytes("binary_little_endian")), "bad.ply")
    assert str(err.value).startswith("bad.ply")


BAD_ASCII = [
    (b"4 0 3 2 1", b"4 0 3 2 9", "bad.ply:27: face 0: vertex index 9 is out of range: the file has 5 vertices"),
    (b"0.5 0.5 1", b"0.5 nan 1", "bad.ply:24: element 'vertex' property 'y': expected a finite number, got nan"),
    (b"0.5 0.5 1", b"0.5 x 1", "bad.ply:24: element 'vertex': expected a number, got 'x'"),
    (b"0.5 0.5 1", b"0.5 0.5", "bad.ply:24: element 'vertex': expected 6 numbers, got 5"),
    (b"4 0 3 2 1", b"4 0 3 2", "bad.ply:27: element 'face': list 'vertex_indices' of length 4 does not fit"),
    (b"4 0 3 2 1", b"2 0 3", "bad.ply:27: face 0 has 2 corners; a face needs at least 3"),
    (b"-3 0\n", b"-3 0\n4 0 3 2 1\n", None),                # one row more than declared: ignored
    (b"0.5 0.5 1 0 0 0", b"0.5 0.5 1 0 0 0 0", "bad.ply:24: element 'vertex': expected 6 numbers, got 7"),
    (b"9 0 1 4 -1", b"9 0 1 4 -2", "bad.ply:28: tristrips row 0: vertex index -2 is out of range"),
    (b"list uchar int vertex_indices", b"list uchar float vertex_indices",
     "bad.ply:15: element 'face': list 'vertex_indices' has a float type"),
]


@pytest.mark.parametrize("old, new, message", BAD_ASCII)
def test_bad_ascii_files_name_the_line(old, new, message):
    data = ply_bytes("ascii")
    assert old in data
    data = data.replace(old, new, 1)
    if message is None:
        parse_ply_bytes(data, "bad.ply")
        return
    with pytest.raises(SceneError) as err:
        parse_ply_bytes(data, "bad.ply")
    assert str(err.value).startswith(message), str(err.value)


def test_through_the_loader_by_suffix_and_by_content(tmp_path):
    from warp_spt.io.loader import load_scene

    (tmp_path / "pyramid.ply").write_bytes(ply_bytes("binary_big_endian"))
    (tmp_path / "misnamed.obj").write_bytes(ply_bytes("ascii", colours=False))
    a = load_scene([tmp_path / "pyramid.ply"])
    b = load_scene([tmp_path / "misnamed.obj"])
    assert a.num_triangles == b.num_triangles == len(PLY_TRIANGLES)
    assert a.materials.names == ["Inner_CheckerTexture", f"pyramid.ply: {VERTEX_COLOUR_MATERIAL}"]
    assert len(a.textures) == 1
    assert b.bare and not a.bare                # vertex colours count as the file's own material


def test_the_cli_reports_a_bad_ply_in_one_line(tmp_path, capsys):
    from warp_spt.cli.main import main

    bad = tmp_path / "scan.ply"
    bad.write_bytes(ply_bytes("binary_little_endian").replace(b"element face 1", b"element face 4000000000"))
    assert main(["-obj", str(bad), "-res", "8", "8", "-out", str(tmp_path / "o.png")]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith(f"warp-spt: error: {bad}: element 'face' (header line 14): 4000000000 rows need")


def test_the_colour_texture_bound_covers_the_texture_made():
    from warp_spt.io.ply import colour_texture_fits

    for f in (1, 2, 3, 5, 99, 1000, 12345, 10**6 + 7):
        faces = np.zeros((f, 3), np.int64)
        _, _, image = vertex_colour_texture(np.zeros((1, 3)), faces)
        assert image.shape[0] * image.shape[1] <= 4 * (f + 2 * int(np.sqrt(f)) + 1)
    assert colour_texture_fits(16_000_000) and not colour_texture_fits(2**24)


def test_two_coloured_files_keep_their_own_colours(tmp_path):
    from warp_spt.io.loader import load_scene

    (tmp_path / "a.ply").write_bytes(ply_bytes("ascii"))
    (tmp_path / "b.ply").write_bytes(ply_bytes("ascii").replace(b"0 0 0 255 0 0", b"0 0 0 0 0 0"))
    scene = load_scene([tmp_path / "a.ply", tmp_path / "b.ply"])
    assert len(scene.textures) == 2 and not np.array_equal(scene.textures[0], scene.textures[1])
    assert [m.face_material[0] for m in scene.meshes] == [1, 2]
