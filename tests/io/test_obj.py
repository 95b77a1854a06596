"""OBJ reader: every statement form, every error with its line, the seed's demo files, round trips.

Each check runs on both scanners (the vectorised one and the line reader): expectations are
hand-computed from the text, and the two scanners are also compared with each other.
"""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.io.obj import load_obj, parse_obj_bytes, write_obj
from warp_spt.scene.errors import SceneError
from warp_spt.scene.model import CHECKER_NAME

SCANNERS = [pytest.param(True, id="fast"), pytest.param(False, id="lines")]
SQUARE = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"


def parse(text: str | bytes, fast: bool, path: str = "t.obj"):
    data = text.encode("utf-8") if isinstance(text, str) else text
    return parse_obj_bytes(data, path, fast=fast)


@pytest.fixture(params=SCANNERS)
def fast(request) -> bool:
    return request.param


# ---------------------------------------------------------------- statements


def test_vertices_and_seed_face_form(fast):
    d = parse("v 1 2 3\nv 4 5 6\nv 7 8 10\nvt 0.5 0.25 0\nvt 1 0 0\nvt 0 1 0\nf 1/1 2/2 3/3\n", fast)
    np.testing.assert_array_equal(d.positions, [[1, 2, 3], [4, 5, 6], [7, 8, 10]])
    np.testing.assert_array_equal(d.texcoords, [[0.5, 0.25], [1, 0], [0, 1]])
    np.testing.assert_array_equal(d.faces, [[0, 1, 2]])
    np.testing.assert_array_equal(d.face_texcoords, [[0, 1, 2]])
    np.testing.assert_array_equal(d.face_normals, [[-1, -1, -1]])
    assert d.faces.dtype == np.int32 and d.positions.dtype == np.float64   # rounded only at upload
    assert d.material_names == [CHECKER_NAME] and d.face_material.tolist() == [0]


@pytest.mark.parametrize("face, vt, vn", [
    ("f 1/3/2 2/2/1 3/1/3", [2, 1, 0], [1, 0, 2]),
    ("f 1//2 2//1 3//3", [-1, -1, -1], [1, 0, 2]),
    ("f 1 2 3", [-1, -1, -1], [-1, -1, -1]),
    ("f 1/3 2/2 3/1", [2, 1, 0], [-1, -1, -1]),
    ("f 1/3/2 2//1 3", [2, -1, -1], [1, 0, -1]),
])
def test_corner_forms(fast, face, vt, vn):
    head = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\nvn 0 1 0\nvn 1 0 0\n"
    d = parse(head + face + "\n", fast)
    np.testing.assert_array_equal(d.faces, [[0, 1, 2]])
    np.testing.assert_array_equal(d.face_texcoords, [vt])
    np.testing.assert_array_equal(d.face_normals, [vn])
    np.testing.assert_array_equal(d.normals, [[0, 0, 1], [0, 1, 0], [1, 0, 0]])


def test_polygons_are_fans(fast):
    text = SQUARE + "v 0.5 1.5 0\nf 1 2 3 4\nf 1 2 3 5 4\n"
    d = parse(text, fast)
    np.testing.assert_array_equal(d.faces, [[0, 1, 2], [0, 2, 3], [0, 1, 2], [0, 2, 4], [0, 4, 3]])


def test_negative_indices_are_relative(fast):
    text = "v 9 9 9\n" + SQUARE + "vt 0 0\nvt 1 1\nf -4/-2 -3/-1 -2/-2\nv 5 5 5\nf -1 -2 -3\n"
    d = parse(text, fast)
    np.testing.assert_array_equal(d.faces, [[1, 2, 3], [5, 4, 3]])
    np.testing.assert_array_equal(d.face_texcoords, [[0, 1, 0], [-1, -1, -1]])


def test_texcoord_widths(fast):
    d = parse("vt 0.25\nvt 0.5 0.75\nvt 0.1 0.2 0.3\n", fast)
    np.testing.assert_allclose(d.texcoords, [[0.25, 0], [0.5, 0.75], [0.1, 0.2]])


def test_vertex_colour_and_w_are_ignored(fast):
    d = parse("v 1 2 3 1\nv 4 5 6 0.1 0.2 0.3\n", fast)
    np.testing.assert_array_equal(d.positions, [[1, 2, 3], [4, 5, 6]])


def test_names_groups_comments_and_whitespace(fast):
    text = ("# header\r\no Ünïcode 立方体\r\ng part one\r\ns off\r\n\r\nv\t0  0   0 # trailing\r\n"
            "v 1 0 0\r\n   v 0 1 0\r\nl 1 2\r\nusemtl Mat#1\r\nf 1 2\t 3  # tri\r\n")
    d = parse(text, fast)
    np.testing.assert_array_equal(d.positions, [[0, 0, 0], [1, 0, 0], [0, 1, 0]])
    np.testing.assert_array_equal(d.faces, [[0, 1, 2]])
    assert d.material_names == [CHECKER_NAME, "Mat#1"] and d.face_material.tolist() == [1]


def test_materials_follow_usemtl(fast):
    text = ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nusemtl 红色\nf 1 2 3\nb 0 0 0 1\nusemtl blue\nf 1 2 3\n"
            f"usemtl 红色\nf 1 2 3\nusemtl {CHECKER_NAME}\nf 1 2 3\nb 1 1 1 2\n")
    d = parse(text, fast)
    assert d.material_names == [CHECKER_NAME, "红色", "blue"]
    assert d.material_lines == [0, 5, 8]
    assert d.face_material.tolist() == [0, 1, 2, 1, 0]
    assert d.sphere_material.tolist() == [1, 0]
    np.testing.assert_array_equal(d.spheres, [[0, 0, 0, 1], [1, 1, 1, 2]])


def test_degenerate_triangles_dropped_and_counted(fast):
    text = SQUARE + "v 2 0 0\nf 1 2 3\nf 1 1 2\nf 1 2 5\nf 1 3 4\n"
    d = parse(text, fast)
    np.testing.assert_array_equal(d.faces, [[0, 1, 2], [0, 2, 3]])
    assert d.dropped_degenerate == 2


def test_empty_file_is_a_valid_obj(fast):
    d = parse("", fast)
    assert d.faces.shape == (0, 3) and d.spheres.shape == (0, 4) and d.positions.shape == (0, 3)
    assert parse("# nothing\n\n", fast).faces.shape == (0, 3)


def test_mtllib_paths(tmp_path, fast):
    (tmp_path / "my lib.mtl").write_text("")
    text = "mtllib my lib.mtl\nmtllib a.mtl sub\\b.mtl\n"
    d = parse(text, fast, path=str(tmp_path / "x.obj"))
    assert d.mtllibs == [str(tmp_path / "my lib.mtl"), str(tmp_path / "a.mtl"), str(tmp_path / "sub/b.mtl")]


# ---------------------------------------------------------------- errors

ERRORS = [
    ("v 1 2\n", 1, "expected 3, 4 or 6 numbers after 'v', got 2"),
    ("v 0 0 0\nv 1 x 0\n", 2, "expected a number after 'v', got 'x'"),
    ("v 0 0 nan\n", 1, "expected a number after 'v', got 'nan'"),
    ("v 0 0 1e39\n", 1, "expected a finite number after 'v', got '1e39'"),
    ("v 1 2 3 4 5\n", 1, "got 5"),
    ("vt\n", 1, "expected 1 to 3 numbers after 'vt', got 0"),
    ("vn 0 0\n", 1, "expected 3 numbers after 'vn', got 2"),
    ("vn 0 0 inf\n", 1, "expected a number after 'vn', got 'inf'"),
    (SQUARE + "f 1 2\n", 5, "expected at least 3 vertices after 'f', got 2"),
    (SQUARE + "f 1 2 0\n", 5, "vertex index 0 is invalid"),
    (SQUARE + "f 1 2 5\n", 5, "vertex index 5 is out of range: the file has 4 'v' lines"),
    (SQUARE + "f 1 2 -5\n", 5, "relative vertex index -5 is out of range: 4 'v' lines precede it"),
    (SQUARE + "vt 0 0\nf 1/2 2/1 3/1\n", 6, "texture coordinate index 2 is out of range"),
    (SQUARE + "f 1//1 2//1 3//1\n", 5, "normal index 1 is out of range: the file has 0 'vn' lines"),
    (SQUARE + "f 1/1/1/1 2 3\n", 5, "expected a face corner"),
    (SQUARE + "f 1/ 2 3\n", 5, "expected a face corner"),
    (SQUARE + "f /1 2 3\n", 5, "expected an integer vertex index, got ''"),
    (SQUARE + "f 1.5 2 3\n", 5, "expected an integer vertex index, got '1.5'"),
    (SQUARE + "f 1 - 3\n", 5, "expected an integer vertex index, got '-'"),
    (SQUARE + "f 1 2 99999999999999999999999\n", 5, "out of range"),
    ("b 0 0 0 0\n", 1, "expected a sphere radius > 0, got '0'"),
    ("b 0 0 0 -1\n", 1, "expected a sphere radius > 0"),
    ("b 0 0 0\n", 1, "expected 4 numbers (x y z r) after 'b', got 3"),
    ("b 0 0 0 1 2\n", 1, "got 5"),
    ("usemtl\n", 1, "expected a material name after 'usemtl'"),
    ("v 0 0 0\r\nv 0 0 0\r\n\r\nv 0 0 0 # c\r\nv 0 0 y\r\n", 5, "got 'y'"),
]


@pytest.mark.parametrize("text, line, message", ERRORS)
def test_errors_name_file_line_and_expectation(fast, text, line, message):
    with pytest.raises(SceneError) as info:
        parse(text, fast, path="dir/bad.obj")
    err = info.value
    assert (err.path, err.line) == ("dir/bad.obj", line)
    assert message in err.message
    assert str(err).startswith(f"dir/bad.obj:{line}: ")


def test_missing_file_is_a_scene_error(tmp_path):
    with pytest.raises(SceneError, match="cannot read OBJ file"):
        load_obj(tmp_path / "absent.obj")


def test_error_after_many_good_lines_reports_its_line():
    good = "".join(f"v {i} {i} 0\n" for i in range(500))
    text = good + "f 1 2 3\n" * 200 + "f 1 2 501\n"
    with pytest.raises(SceneError) as info:
        parse(text, True)
    assert info.value.line == 701


# ---------------------------------------------------------------- seed demo files


def test_seed_cornell_box(seed_demo):
    d = load_obj(seed_demo / "cornell_export.obj")
    assert (len(d.positions), len(d.texcoords), len(d.faces), len(d.spheres)) == (36, 4, 42, 0)
    counts = {n: int(np.sum(d.face_material == k)) for k, n in enumerate(d.material_names)}
    assert counts == {CHECKER_NAME: 0, "light": 2, "white": 12, "Floor": 2, "BackWall": 2, "green": 2,
                      "red": 2, "Box2": 10, "Box1": 10}
    assert d.dropped_degenerate == 0
    light = d.positions[d.faces[d.face_material == d.material_names.index("light")]]
    np.testing.assert_allclose(light[..., 2], 32.865, atol=1e-3)
    assert d.mtllibs == [str(seed_demo / "cornell_export.mtl")]


def test_seed_balls(seed_demo):
    d = load_obj(seed_demo / "baller.obj")
    assert len(d.faces) == 0
    np.testing.assert_allclose(d.spheres, [[12.5409, 15.4094, 8.5959, 6.7822], [-5.1149, -5.4793, 6.6618, 4.2782],
                                           [6.7154, -0.303, 17.1339, 3.815]], rtol=1e-6)
    assert [d.material_names[k] for k in d.sphere_material] == ["Ball1", "Ball2", "Ball2"]


def test_seed_utf8_cube(seed_demo):
    d = load_obj(seed_demo / "testUVW.obj")
    assert (len(d.positions), len(d.texcoords), len(d.faces)) == (8, 4, 12)
    assert d.material_names == [CHECKER_NAME, "Texture4"] and set(d.face_material.tolist()) == {1}


# ---------------------------------------------------------------- scanners agree, round trips


def random_mesh(rng: np.random.Generator, nv: int = 40, nf: int = 60) -> dict:
    pos = (rng.normal(size=(nv, 3)) * 10.0 ** rng.integers(-3, 4, size=(nv, 1))).astype(np.float32)
    faces = np.stack([rng.choice(nv, 3, replace=False) for _ in range(nf)])
    tex = rng.random((7, 2)).astype(np.float32)
    nrm = rng.normal(size=(5, 3)).astype(np.float32)
    ft = np.where(rng.random((nf, 1)) < 0.6, rng.integers(0, 7, (nf, 3)), -1)
    fn = np.where(rng.random((nf, 1)) < 0.5, rng.integers(0, 5, (nf, 3)), -1)
    spheres = np.concatenate([rng.normal(size=(3, 3)), rng.random((3, 1)) + 0.1], axis=1).astype(np.float32)
    return dict(positions=pos, faces=faces, texcoords=tex, face_texcoords=ft, normals=nrm, face_normals=fn,
                material_names=[CHECKER_NAME, "a", "b b", "ü"], face_material=rng.integers(0, 4, nf),
                spheres=spheres, sphere_material=rng.integers(0, 4, 3))


@pytest.mark.parametrize("seed", range(6))
def test_round_trip_through_writer(tmp_path, seed):
    m = random_mesh(np.random.default_rng(seed))
    write_obj(tmp_path / "m.obj", **m)
    d = load_obj(tmp_path / "m.obj")
    np.testing.assert_array_equal(d.positions, m["positions"])
    np.testing.assert_array_equal(d.texcoords, m["texcoords"])
    np.testing.assert_array_equal(d.normals, m["normals"])
    np.testing.assert_array_equal(d.faces, m["faces"])
    np.testing.assert_array_equal(d.face_texcoords, m["face_texcoords"])
    np.testing.assert_array_equal(d.face_normals, m["face_normals"])
    names = [d.material_names[k] for k in d.face_material]
    assert names == [m["material_names"][k] for k in m["face_material"]]
    np.testing.assert_array_equal(d.spheres, m["spheres"])
    assert [d.material_names[k] for k in d.sphere_material] == [m["material_names"][k] for k in m["sphere_material"]]


@pytest.mark.parametrize("seed", range(4))
def test_scanners_agree_on_mixed_files(tmp_path, seed):
    rng = np.random.default_rng(100 + seed)
    write_obj(tmp_path / "m.obj", **random_mesh(rng))
    lines = (tmp_path / "m.obj").read_text(encoding="utf-8").splitlines()
    extra = ["# comment", "g grp", "s 1", "", "  ", "o thing", "vt 0.5", "v 1 2 3 0.5 0.5 0.5"]
    for _ in range(20):  # sprinkle statements that shift line numbers and relative references
        lines.insert(int(rng.integers(0, len(lines) + 1)), str(rng.choice(extra)))
    text = "\r\n".join(lines).replace("f 1 ", "f -1 ") + "\r\n"
    a, b = parse(text, True), parse(text, False)
    for key in ("positions", "texcoords", "normals", "faces", "face_texcoords", "face_normals", "face_material",
                "spheres", "sphere_material"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)
    assert a.material_names == b.material_names and a.material_lines == b.material_lines


def test_fast_scanner_handles_bulk_files():
    from warp_spt.io.obj_bulk import scan_bulk

    text = SQUARE * 3 + "vt 0 0\nvn 0 0 1\n" + "f 1/1/1 2/1/1 3/1/1 4/1/1\n" * 5 + "usemtl m\nb 0 0 0 1\n"
    assert scan_bulk(text.encode(), "x") is not None


def _all_fields_equal(a, b):
    for key in ("positions", "texcoords", "normals", "faces", "face_texcoords", "face_normals", "face_material",
                "spheres", "sphere_material", "v_line" if hasattr(a, "v_line") else "faces"):
        x, y = getattr(a, key), getattr(b, key)
        assert x.dtype == y.dtype and x.shape == y.shape and np.array_equal(x, y), key
    assert a.material_names == b.material_names and a.material_lines == b.material_lines
    assert a.dropped_degenerate == b.dropped_degenerate


@pytest.mark.parametrize("seed", range(6))
def test_plain_scanner_agrees_with_line_reader(seed):
    """Issue 45's plain-file scanner (obj_bulk.scan_plain: no '/', '#' or '\\' in the file) on generated
    files: negative indices, quads and n-gons, vt/vn lines, groups, usemtl, spheres, blank lines."""
    from warp_spt.io.obj_bulk import scan_plain

    rng = np.random.default_rng(300 + seed)
    lines, nv = [], 0
    for _ in range(120):
        r = rng.random()
        if r < 0.4 or nv < 3:
            lines.append("v " + " ".join(f"{x:.6g}" for x in rng.normal(size=int(rng.choice([3, 4, 6])))))
            nv += 1
        elif r < 0.75:
            k = int(rng.choice([3, 3, 4, 5, 7]))
            idx = rng.choice(nv, k, replace=k > nv) + 1
            lines.append("f " + " ".join(str(i - nv - 1 if rng.random() < 0.3 else i) for i in idx))
        else:
            lines.append(str(rng.choice(["vt 0.5 0.25", "vt 1", "vn 0 0 1", "g grp", "o thing", "s 1", "",
                                         "usemtl red", "usemtl b b", "b 0 1 2 0.5", "v 1e3  -2.5e-3\t7"])))
    text = ("\n".join(lines) + "\n").encode()
    assert scan_plain(text, "t.obj") is not None
    _all_fields_equal(parse(text, True), parse(text, False))


@pytest.mark.parametrize("text", [b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3 # c\n", b" v 0 0 0\n", b"f 1/2 2/3 3/4\n",
                                  b"v 0 0 nan\n", b"v 0 0\n", b"f 1 2\n", b"f 1 2 0\n", b"f 1 - 2\n", b"v 0 0 1e39\n"])
def test_plain_scanner_leaves_the_rest_to_the_others(text):
    """Comments, leading blanks, slashes, bad numbers or counts: scan_plain steps aside (None) and the
    error (if any) is the line reader's."""
    from warp_spt.io.obj_bulk import scan_plain

    assert scan_plain(text, "t.obj") is None
