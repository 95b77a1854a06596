"""Large meshes (issue 33): the files exporters write take the vectorised OBJ scanner."""

from __future__ import annotations

import numpy as np

from warp_spt.io.obj import parse_obj_bytes
from warp_spt.io.obj_bulk import scan_bulk

BLENDER = b"""# Blender 4.1.0
# www.blender.org
mtllib cube.mtl
o Cube
v 1.000000 1.000000 -1.000000
v 1.000000 -1.000000 -1.000000
v 1.000000 1.000000 1.000000
v -1.000000 1.000000 -1.000000
vn -0.0000 1.0000 -0.0000
vt 0.625000 0.500000
s 0
usemtl Material
f 1/1/1 2/1/1 3/1/1
f 1/1/1 3/1/1 4/1/1
o Other
v 2 2 2
f 1//1 2//1 5//1
"""


def heightfield_obj(n: int) -> bytes:
    """A plain n x n grid as numpy's savetxt writes it (bench_scaling.py's OBJ form)."""
    u = np.linspace(0.0, 1.0, n)
    x, y = np.meshgrid(u, u)
    p = np.stack([x, y, np.sin(3 * x) * y], axis=-1).reshape(-1, 3)
    a = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).ravel()
    f = np.concatenate([np.stack([a, a + 1, a + n + 1], 1), np.stack([a, a + n + 1, a + n], 1)]) + 1
    return ("".join(f"v {x:.6g} {y:.6g} {z:.6g}\n" for x, y, z in p) + "".join(f"f {i} {j} {k}\n" for i, j, k in f)).encode()


def test_exporter_files_take_the_vectorised_scanner():
    for text in (BLENDER, BLENDER.replace(b"\n", b"\r\n"), heightfield_obj(60)):
        assert scan_bulk(text.replace(b"\r\n", b"\n"), "x.obj") is not None


def test_the_vectorised_scanner_reads_a_heightfield_as_the_line_reader():
    text = heightfield_obj(40)
    a, b = parse_obj_bytes(text, "h.obj"), parse_obj_bytes(text, "h.obj", fast=False)
    assert len(a.faces) == 2 * 39 * 39
    for key in ("positions", "faces", "face_material"):
        np.testing.assert_array_equal(getattr(a, key), getattr(b, key), err_msg=key)


def test_the_box_shortcut_of_the_edge_check_never_passes_a_longer_edge():
    """box_bounds_edges may only say True where every edge really is within the limit (the
    per-triangle lengths, computed independently, decide), and it says True for ordinary models."""
    from warp_spt.scene.validate import box_bounds_edges, longest_edges

    rng = np.random.default_rng(3)
    for trial in range(200):
        p = rng.normal(size=(rng.integers(3, 40), 3)) * 10.0 ** rng.uniform(-3, 3)
        f = rng.integers(0, len(p), size=(30, 3)).astype(np.int32)
        longest = float(longest_edges(p, f).max())
        for limit in (longest * 0.999, longest, longest * 1.5, longest * 100.0):
            if box_bounds_edges(p, limit):
                assert longest <= limit
    unit = rng.uniform(size=(100, 3))
    assert box_bounds_edges(unit, 2.0) and not box_bounds_edges(unit, 1.0)


def test_a_long_edge_behind_a_large_box_is_still_refused():
    """Where the box proves nothing (vertices far apart), the exact lengths decide: small triangles
    far apart pass, one long triangle fails with its own length in the message."""
    from dataclasses import replace

    import pytest

    from warp_spt.io.loader import load_scene
    from warp_spt.scene.errors import SceneError
    from warp_spt.scene.limits import MAX_TRIANGLE_EDGE
    from warp_spt.scene.validate import validate_scene

    e = MAX_TRIANGLE_EDGE
    apart = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0.9 * e, 0, 0], [0.9 * e + 1, 0, 0], [0.9 * e, 1, 0]])
    text = "".join(f"v {x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in apart)
    import tempfile
    from pathlib import Path
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "apart.obj"
        path.write_text(text + "f 1 2 3\nf 4 5 6\n")
        scene = load_scene([str(path)])                      # the box is 0.9e across: no shortcut; passes
        validate_scene(scene)
        mesh = scene.meshes[0]
        validate_scene(replace(scene, meshes=[replace(mesh, positions=mesh.positions * 1.2)]))  # box > e, edges ~1
        path.write_text(text + "f 1 2 3\nf 4 5 6\nf 1 6 2\n")     # an edge of about 0.9e: within e
        scene = load_scene([str(path)])
        validate_scene(scene)
        mesh = scene.meshes[0]
        with pytest.raises(SceneError, match="edge of 1.08e\\+09 is longer"):
            validate_scene(replace(scene, meshes=[replace(mesh, positions=mesh.positions * 1.2)]))


def test_mesh_bounds_are_the_rounded_extremes_of_the_used_vertices():
    """placement_bounds (no transforms) against the definition: float32-rounded used vertices' min
    and max, with an unused far vertex that must not count."""
    from warp_spt.scene.model import MeshData

    rng = np.random.default_rng(5)
    p = rng.normal(size=(500, 3)) * 1e3 + 1e-3 * rng.normal(size=(500, 3))
    p[7] = (1e6, -1e6, 1e6)                                   # unused
    f = rng.integers(0, 500, size=(800, 3)).astype(np.int32)
    f[f == 7] = 8
    m = MeshData("m", p, f, np.zeros((800, 3, 2), np.float32), None, np.zeros(800, np.int32))
    used = np.unique(f)
    r = p[used].astype(np.float32).astype(np.float64)
    b = m.placement_bounds()
    assert np.array_equal(b[0], np.stack([r.min(0), r.max(0)]))
    b = m.placement_bounds(rounded=False)
    assert np.array_equal(b[0], np.stack([p[used].min(0), p[used].max(0)]))
    full = MeshData("m", p[used], np.arange(len(used), dtype=np.int32)[:len(used) // 3 * 3].reshape(-1, 3),
                    np.zeros((len(used) // 3, 3, 2), np.float32), None, np.zeros(len(used) // 3, np.int32))
    q = p[used][:len(used) // 3 * 3].astype(np.float32).astype(np.float64)
    assert np.array_equal(full.placement_bounds()[0], np.stack([q.min(0), q.max(0)]))


def _binary_ply(points: np.ndarray, faces: np.ndarray, index_type: str) -> bytes:
    kinds = {"char": "i1", "uchar": "u1", "short": "<i2", "ushort": "<u2", "int": "<i4", "uint": "<u4"}
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {len(faces)}\nproperty list uchar {index_type} vertex_indices\nend_header\n").encode()
    rows = np.empty(len(faces), dtype=[("n", "u1"), ("v", kinds[index_type], (3,))])
    rows["n"] = 3
    rows["v"] = faces
    return header + points.astype("<f4").tobytes() + rows.tobytes()


def test_binary_ply_indices_of_every_integer_type_read_as_written():
    """The reader keeps small signed index types as they are and widens the others: the faces are
    the ones written, whatever the type, and a mesh without uv or normals says -1 at every corner."""
    import pytest

    from warp_spt.io.ply import parse_ply_bytes
    from warp_spt.scene.errors import SceneError

    rng = np.random.default_rng(7)
    points = rng.uniform(size=(100, 3))
    faces = np.array([rng.permutation(100)[:3] for _ in range(60)])
    for kind in ("char", "uchar", "short", "ushort", "int", "uint"):
        d = parse_ply_bytes(_binary_ply(points, faces, kind), "t.ply")
        assert d.faces.dtype == np.int32 and np.array_equal(d.faces, faces), kind
        assert np.all(d.face_texcoords == -1) and np.all(d.face_normals == -1) and d.face_normals.shape == faces.shape
    bad = faces.copy()
    bad[5, 1] = 2**32 - 1                       # wraps to -1 as int32: must be reported as the value it is
    with pytest.raises(SceneError, match="face 5: vertex index 4294967295 is out of range"):
        parse_ply_bytes(_binary_ply(points, bad, "uint"), "t.ply")
    bad[5, 1] = -3
    with pytest.raises(SceneError, match="face 5: vertex index -3 is out of range"):
        parse_ply_bytes(_binary_ply(points, bad, "int"), "t.ply")
    for value in (np.nan, np.inf, -np.inf, 2e15):
        p = points.copy()
        p[17, 2] = value
        with pytest.raises(SceneError, match="vertex 17: coordinate .* is not finite or beyond"):
            parse_ply_bytes(_binary_ply(p, faces, "int"), "t.ply")


def test_the_blocked_zero_area_test_is_the_cross_product_test():
    """nonzero_area (blocks, a component at a time; OBJ and PLY) against np.cross(...) != 0 on the
    whole array, on triangles built to be degenerate in every way (repeated corners, collinear,
    tiny and huge coordinates within MAX_COORDINATE)."""
    from warp_spt.scene.validate import nonzero_area
    from warp_spt.scene.limits import MAX_COORDINATE

    rng = np.random.default_rng(11)
    n = 70_000                                    # more than one block
    p = rng.normal(size=(3000, 3)) * 10.0 ** rng.integers(-12, 14, size=(3000, 1))
    p = np.clip(p, -MAX_COORDINATE, MAX_COORDINATE)
    p[:1000] = np.round(p[:1000])                 # integer grids: exact collinear triples
    p[1000:1500, 2] = 0.0
    f = rng.integers(0, 3000, size=(n, 3))
    f[::5, 1] = f[::5, 0]                         # repeated corner
    line = rng.integers(0, 1000, size=(n // 5, 1)) + np.array([0, 1, 2]) * 0
    f[1::5] = line
    pp = p.copy()
    a, b = pp[f[2::5, 0]], pp[f[2::5, 1]]
    mid = 2 * b - a                               # b - a = mid - b exactly for integers: collinear
    pp = np.concatenate([pp, mid])
    f[2::5, 2] = 3000 + np.arange(len(mid))
    p0 = pp[f[:, 0]]
    expected = np.any(np.cross(pp[f[:, 1]] - p0, pp[f[:, 2]] - p0) != 0.0, axis=1)
    got = nonzero_area(pp, f)
    assert np.array_equal(got, expected)
    assert 0.2 * n < np.count_nonzero(~got) < 0.8 * n         # the degenerate cases are there


def test_joining_per_mesh_arrays_skips_zero_parts_but_keeps_every_bit():
    """device_scene._cat leaves all-zero parts unwritten (fresh zero pages): the result must still be
    np.concatenate's, bit for bit (a -0.0 is not a zero part)."""
    from warp_spt.upload.device_scene import _cat

    rng = np.random.default_rng(2)
    parts = [np.zeros((5, 2), np.float32), rng.normal(size=(3, 2)).astype(np.float32),
             np.array([[0.0, -0.0]], np.float32), np.zeros((0, 2), np.float32), np.zeros((4, 2), np.float32)]
    got = _cat(parts, (0, 2), np.float32)
    assert got.dtype == np.float32 and np.array_equal(got.view(np.uint32), np.concatenate(parts).view(np.uint32))
    ints = [np.zeros(4, np.int32), np.arange(3, dtype=np.int32)]
    assert np.array_equal(_cat(ints, (0,), np.int32), np.concatenate(ints))


def test_a_tree_array_grows_in_place_only_into_its_own_allocation():
    """device_scene._grown: a view of the array a tree's rows start, with more rows, only where that
    array is C-contiguous and long enough; else None (the caller copies)."""
    from warp_spt.upload.device_scene import _grown

    full = np.arange(40, dtype=np.int32).reshape(10, 4)
    head = full[:3]
    g = _grown(head, 7)
    assert g is not None and g.shape == (7, 4) and np.shares_memory(g, full) and np.array_equal(g[:3], head)
    assert _grown(head, 11) is None                       # longer than the allocation
    assert _grown(full[2:5], 4) is None                   # not its start
    assert _grown(full[:, :2], 3) is None                 # not contiguous
    assert _grown(np.zeros((3, 4), np.int32), 4) is None  # owns its memory: no room known


def test_invisible_characters_are_still_found_after_the_ascii_shortcut():
    """tokens._check_invisible skips its searches for pure ASCII text: a file with one of the
    invisible characters (each has a byte >= 0x80) is still refused at its line, by name."""
    import pytest

    from warp_spt.scene.errors import SceneError

    base = b"v 0 0 0\nv 1 0 0\nv 0 1 0\n"
    assert len(parse_obj_bytes(base + b"f 1 2 3\n", "a.obj").faces) == 1
    for junk, name in ((b"\xe2\x80\x8b", "zero-width space"), (b"\xc2\xa0", "no-break space"),
                       (b"\xef\xbb\xbf", "byte-order mark")):
        with pytest.raises(SceneError, match=name) as err:
            parse_obj_bytes(base + b"f 1 2" + junk + b" 3\n", "a.obj")
        assert err.value.line == 4
