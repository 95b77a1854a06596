"""Property-based fuzzing: mutated OBJ and MTL text never lets anything but SceneError escape.

For OBJ text the two scanners are also compared: on any input both read the same arrays, or both
raise a SceneError for the same line with the same message.
"""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warp_spt.io.mtl import parse_mtl_bytes
from warp_spt.io.obj import parse_obj_bytes
from warp_spt.scene.errors import SceneError

OBJ_SEED = (b"# c\nmtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 1.5e-3\nvt 0 0\nvt 1 0 0\nvn 0 0 1\n"
            b"o name\nusemtl red\nf 1/1/1 2/2/1 3/1/1\nf -4//1 -3//1 -2//1 -1//1\nf 1 2 4\ng g\ns 1\n"
            b"usemtl \xe7\xba\xa2\nf 1/2 2/1 3/2\nb 0 0 0 1\nb 1 2 3 0.5\n")
MTL_SEED = (b"newmtl red\nKd 1 0 0\nmap_Kd -s 1 1 1 t.png\nKs 0.5 0.5 0.5\nNi 1.5\nd 0.5\nillum 7\n"
            b"newmtl b\nKl 1 1 1\nRoughness 0.3\nFuzz 0.1\nKn 1.6\nRefractable\nKt 1 1 1\nmap_Kt x.png\n")

PIECES = [b" ", b"\t", b"\n", b"\r\n", b"/", b"//", b"-", b"+", b".", b"e", b"0", b"1", b"9", b"-1", b"#", b"nan",
          b"inf", b"1e40", b"f", b"v", b"vt", b"vn", b"b", b"usemtl", b"newmtl", b"Kd", b"\x00", b"\xff", b"\xe7",
          b"99999999999999999999", b"f 1 2 3\n", b"v 1 2 3\n", b"x"]


@st.composite
def mutated(draw, seed: bytes, pieces: list[bytes] = PIECES) -> bytes:
    """The seed text with a few insertions, deletions and replacements (of ``pieces`` or random bytes)."""
    data = bytearray(seed)
    for _ in range(draw(st.integers(1, 6))):
        at = draw(st.integers(0, len(data)))
        kind = draw(st.sampled_from(["insert", "delete", "replace"]))
        piece = draw(st.sampled_from(pieces) | st.binary(min_size=1, max_size=3))
        if kind == "insert":
            data[at:at] = piece
        elif kind == "delete":
            data[at:at + draw(st.integers(1, 8))] = b""
        else:
            data[at:at + len(piece)] = piece
    return bytes(data)


def outcome(data: bytes, fast: bool):
    try:
        d = parse_obj_bytes(data, "f.obj", fast=fast)
    except SceneError as err:
        return ("error", err.line, err.message)
    return ("ok", d)


SETTINGS = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(mutated(OBJ_SEED))
def test_mutated_obj_gives_data_or_scene_error_and_scanners_agree(data):
    a, b = outcome(data, True), outcome(data, False)
    assert a[0] == b[0]
    if a[0] == "error":
        assert a[1:] == b[1:]
        return
    da, db = a[1], b[1]
    for key in ("positions", "texcoords", "normals", "faces", "face_texcoords", "face_normals", "face_material",
                "spheres", "sphere_material"):
        np.testing.assert_array_equal(getattr(da, key), getattr(db, key), err_msg=key)
    assert da.material_names == db.material_names
    # the contract of ObjData holds whenever parsing succeeds
    assert np.isfinite(da.positions).all() and (da.spheres[:, 3] > 0).all()
    assert da.faces.size == 0 or (0 <= da.faces.min() and da.faces.max() < len(da.positions))
    assert (da.face_texcoords < len(da.texcoords)).all() and (da.face_normals < len(da.normals)).all()


@SETTINGS
@given(mutated(MTL_SEED))
def test_mutated_mtl_gives_materials_or_scene_error(data):
    try:
        lib = parse_mtl_bytes(data, "f.mtl")
    except SceneError:
        return
    for m in lib.values():
        assert 0 <= m.roughness <= 1 and m.fuzz >= 0 and m.ior > 0
        assert all(np.isfinite(c) and c >= 0 for c in (*m.diffuse, *m.reflect, *m.refract, *m.emission))


@settings(max_examples=60, deadline=None)
@given(st.binary(max_size=200))
def test_arbitrary_bytes(data):
    assert outcome(data, True)[0] == outcome(data, False)[0]
    try:
        parse_mtl_bytes(data, "f.mtl")
    except SceneError:
        pass
