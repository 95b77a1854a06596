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
