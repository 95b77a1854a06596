"""The material schema is the one home of the material fields (issue 20): every column reaches the host
Material and MaterialTable, validation, the device struct and its upload, the named parameters and
the gradient aliases; and a column added to the schema (one line) reaches them all with no other edit."""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from warp_spt.scene import material_schema as schema
from warp_spt.scene.errors import SceneError
from warp_spt.scene.model import Material, MaterialTable

ROOT = Path(__file__).resolve().parents[1]


def test_every_column_reaches_every_derived_place(tmp_path):
    from warp_spt.core.device_scene import DeviceScene, Materials
    from warp_spt.core.material_table import with_gradients
    from warp_spt.diff.params import MATERIAL_FIELDS, parameters, value_range
    from warp_spt.io.loader import load_scene

    obj = tmp_path / "a.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n")
    (tmp_path / "a.mtl").write_text("newmtl red\nKd 1 0 0\n")
    scene = load_scene([str(obj)], [str(tmp_path / "a.mtl")])
    dev = DeviceScene(scene)
    params = parameters(dev)
    aliases = []

    def alias(a):
        aliases.append(a.ptr)
        return a

    with_gradients(dev.materials, alias)
    assert list(Materials.vars) == [c.name for c in schema.COLUMNS]        # the device struct's field order
    for c in schema.COLUMNS:
        host = getattr(scene.materials, c.name)
        assert host.dtype == np.dtype(schema.host_dtype(c)) and host.shape == (2, *schema.row_shape(c))
        np.testing.assert_array_equal(getattr(dev.materials, c.name).numpy().reshape(host.shape), host)
        if c.type != schema.SLOTS:
            assert getattr(Material("m"), c.name) == c.default
        assert (getattr(dev.materials, c.name).ptr in aliases) == c.differentiable
        assert (c.name in MATERIAL_FIELDS) == c.differentiable == (f"red.{c.name}" in params)
        if c.differentiable:
            assert params.info(f"red.{c.name}").shape == schema.row_shape(c)
            assert value_range(params.info(f"red.{c.name}")) == (c.low, c.high)


@pytest.mark.parametrize("column", [c for c in schema.COLUMNS if c.low is not None or c.high is not None],
                         ids=lambda c: c.name)
def test_validation_checks_each_range(column):
    from warp_spt.scene.validate import _check_materials

    t = MaterialTable.from_rows([Material("Inner_CheckerTexture")])
    bad = (column.low - 1.0) if column.low is not None else column.high * 2.0
    getattr(t, column.name)[0] = bad
    with pytest.raises(SceneError, match=re.escape(f"materials.{column.name} must {schema.range_text(column)}")):
        _check_materials(t, 0)


# A new column, written into the schema's source as one line; nothing else is edited.
EXTRA = '    Column("sheen", COLOR, (0.25, 0.5, 0.75), 0.0, 1.0, "a test column", differentiable=True),\n'

PROBE = textwrap.dedent('''
    import importlib.util, sys
    import numpy as np
    path, extra, folder = sys.argv[1:4]
    src = open(path).read()
    start = src.index("COLUMNS: tuple[Column, ...] = (")
    end = src.index("\\n)\\n", start) + 1
    spec = importlib.util.spec_from_loader("warp_spt.scene.material_schema", loader=None)
    schema = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = schema
    exec(compile(src[:end] + extra + src[end:], path, "exec"), schema.__dict__)

    from warp_spt.core.device_scene import DeviceScene
    from warp_spt.diff.gradients import _Backward
    from warp_spt.diff.optim import Adam
    from warp_spt.diff.params import parameters
    from warp_spt.io.loader import load_scene
    from warp_spt.scene.errors import SceneError
    from warp_spt.scene.model import Material
    from warp_spt.scene.validate import validate_scene

    assert Material("m").sheen == (0.25, 0.5, 0.75)
    scene = load_scene([folder + "/a.obj"], [folder + "/a.mtl"])
    np.testing.assert_array_equal(scene.materials.sheen, [[0.25, 0.5, 0.75]] * 2)     # the host table
    dev = DeviceScene(scene)
    np.testing.assert_array_equal(dev.materials.sheen.numpy(), [[0.25, 0.5, 0.75]] * 2)   # the upload
    params = parameters(dev)
    assert params.info("red.sheen").shape == (3,)                                        # the parameter
    params["red.sheen"] = (0.1, 0.2, 0.3)
    np.testing.assert_allclose(dev.materials.sheen.numpy()[1], [0.1, 0.2, 0.3])
    try:
        params["red.sheen"] = (0.1, 0.2, 1.5)
        raise AssertionError("a value out of the column's range was accepted")
    except ValueError:
        pass
    opt = Adam(params, ["red.sheen"], lr=10.0)                                          # the bounds
    opt.step({"red.sheen": np.array([-1.0, -1.0, -1.0])})
    assert params["red.sheen"].max() == 1.0
    bw = _Backward.__new__(_Backward)                   # only what _tile_inputs reads
    bw.dev, bw.tex, bw.mode, bw.nbytes = dev, dev.textures(), "prb", 0
    bw.wants_texels = bw.wants_proc = False
    m = bw._tile_inputs(0, 1)[0]
    assert m.sheen.grad is not None and m.sheen.ptr == dev.materials.sheen.ptr          # the gradient alias
    assert m.ior.grad is None
    scene.materials.sheen[1, 0] = 2.0
    try:
        validate_scene(scene)
        raise AssertionError("validation missed the new column")
    except SceneError as err:
        assert "materials.sheen must lie in [0, 1]" in str(err), err
    print("ok")
''')


def test_a_new_column_is_one_line(tmp_path):
    (tmp_path / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n")
    (tmp_path / "a.mtl").write_text("newmtl red\nKd 1 0 0\n")
    src = str(ROOT / "warp_spt" / "scene" / "material_schema.py")
    out = subprocess.run([sys.executable, "-c", PROBE, src, EXTRA, str(tmp_path)], capture_output=True, text=True,
                         cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=300)
    assert out.returncode == 0 and out.stdout.strip().endswith("ok"), out.stderr[-3000:]
