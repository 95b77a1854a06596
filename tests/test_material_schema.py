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
    from types import SimpleNamespace
    from warp_spt.core.lights import light_table
    from warp_spt.scene.sky import Sky
    bw.bound = SimpleNamespace(lights=light_table(dev, Sky.black()))
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


# A second material kind: one module (here built in the probe) and one name in MATERIAL_KINDS.
KIND_MODULE = textwrap.dedent('''
    from types import SimpleNamespace
    import warp as wp
    from warp_spt.core.device_scene import Materials, Textures
    from warp_spt.core.materials.common import BsdfSample
    from warp_spt.core.surface import Surface

    def make(features, color):
        @wp.func
        def sample(m: Materials, t: Textures, sf: Surface, d: wp.vec3, u_lobe: float, u_dir: wp.vec2,
                   u_fresnel: float) -> BsdfSample:
            out = BsdfSample()
            out.weight = wp.vec3(1.0, 2.0, 3.0)
            out.alive = 1
            return out

        @wp.func
        def eval(m: Materials, t: Textures, sf: Surface, wi: wp.vec3) -> wp.vec3:
            return wp.vec3(0.0, 0.0, 0.0)

        @wp.func
        def pdf(m: Materials, sf: Surface, wi: wp.vec3) -> float:
            return 7.0

        @wp.func
        def has_density(m: Materials, sf: Surface) -> bool:
            return False

        return SimpleNamespace(sample=sample, eval=eval, pdf=pdf, has_density=has_density)
''')

KIND_PROBE = textwrap.dedent('''
    import importlib.util, sys
    import numpy as np
    path, module_src, folder = sys.argv[1:4]
    src = open(path).read().replace('MATERIAL_KINDS: tuple[str, ...] = ("seed",)',
                                    'MATERIAL_KINDS: tuple[str, ...] = ("seed", "probe")')
    spec = importlib.util.spec_from_loader("warp_spt.scene.material_schema", loader=None)
    schema = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = schema
    exec(compile(src, path, "exec"), schema.__dict__)
    import warp as wp
    import warp_spt.core.device_scene  # noqa: F401  (the kind module imports it)
    kspec = importlib.util.spec_from_file_location("warp_spt.core.materials.probe", module_src)
    kind = importlib.util.module_from_spec(kspec)
    sys.modules[kind.__name__] = kind         # what importlib finds for the registered name
    kspec.loader.exec_module(kind)            # from a file: Warp reads its functions' source

    from warp_spt.core.device_scene import DeviceScene, Materials, Textures
    from warp_spt.core.materials import make_materials
    from warp_spt.core.surface import INV_PI, Surface
    from warp_spt.io.loader import load_scene

    scene = load_scene([folder + "/a.obj"], [folder + "/a.mtl"])
    scene.materials.kind[1] = 1
    dev = DeviceScene(scene)
    assert dev.features.material_kinds == ("seed", "probe"), dev.features
    mat = make_materials(dev.features)

    @wp.kernel(enable_backward=False, module="unique")
    def probe(m: Materials, t: Textures, dens: wp.array(dtype=int), pdf: wp.array(dtype=float),
              weight: wp.array(dtype=wp.vec3)):
        i = wp.tid()
        sf = Surface()
        sf.ng = wp.vec3(0.0, 0.0, 1.0)
        sf.ns = sf.ng
        sf.front = 1
        sf.mat = i
        dens[i] = wp.where(mat.has_density(m, sf), 1, 0)
        pdf[i] = mat.pdf(m, sf, wp.vec3(0.0, 0.0, 1.0))
        weight[i] = mat.sample(m, t, sf, wp.vec3(0.0, 0.0, -1.0), 0.99, wp.vec2(0.5, 0.5), 0.5).weight

    dens, pdf, weight = wp.zeros(2, dtype=int), wp.zeros(2, dtype=float), wp.zeros(2, dtype=wp.vec3)
    wp.launch(probe, dim=2, inputs=[dev.materials, dev.textures(), dens, pdf, weight])
    assert dens.numpy().tolist() == [1, 0], dens
    np.testing.assert_allclose(pdf.numpy(), [0.75 * INV_PI, 7.0], rtol=1e-6)   # the checker: Roughness 0.75
    np.testing.assert_array_equal(weight.numpy()[1], [1.0, 2.0, 3.0])
    print("ok")
''')


def test_a_second_material_kind_is_dispatched(tmp_path):
    """A kind registered by name gets its rows (``kind`` column) through make_materials' dispatch."""
    (tmp_path / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nusemtl red\nf 1 2 3\n")
    (tmp_path / "a.mtl").write_text("newmtl red\nKd 1 0 0\n")
    src = str(ROOT / "warp_spt" / "scene" / "material_schema.py")
    (tmp_path / "probe_kind.py").write_text(KIND_MODULE)
    (tmp_path / "probe.py").write_text(KIND_PROBE)       # Warp compiles functions from source files only
    out = subprocess.run([sys.executable, str(tmp_path / "probe.py"), src, str(tmp_path / "probe_kind.py"),
                          str(tmp_path)], capture_output=True,
                         text=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=600)
    assert out.returncode == 0 and out.stdout.strip().endswith("ok"), out.stderr[-3000:]


def test_kinds_are_registered():
    from warp_spt.core.materials import KINDS

    assert tuple(KINDS) == schema.MATERIAL_KINDS and schema.COLUMN["kind"].high == len(KINDS) - 1
    for module in KINDS.values():
        assert callable(module.make)
