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

ROOT = Path(__file__).resolve().parents[2]


def test_every_column_reaches_every_derived_place(tmp_path):
    from warp_spt.upload.device_scene import DeviceScene, Materials
    from warp_spt.device.material_table import with_gradients
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

    from warp_spt.upload.device_scene import DeviceScene
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
    from warp_spt.emitters import light_table
    from warp_spt.scene.sky import Sky
    bw.bound = SimpleNamespace(lights=light_table(dev, Sky.black()))
    bw.wants_texels = bw.wants_proc = bw.wants_env = bw.wants_media = bw.wants_geometry = False
    m = bw._tile_inputs(0, 1)[0]
    assert m.sheen.grad is not None and m.sheen.ptr == dev.materials.sheen.ptr          # the gradient alias
    assert m.refractable.grad is None                  # not differentiable: no alias
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


# A glossy probe kind: one module (written here to a file) and one name in MATERIAL_KINDS. Its lobe is
# glossy with a density (a constant BRDF rho/pi, sampled uniformly over the hemisphere), so it goes
# through the whole contract: light sampling and MIS from its flags, eval, pdf, sample, albedo.
KIND_MODULE = textwrap.dedent('''
    from types import SimpleNamespace
    import numpy as np
    import warp as wp
    from warp_spt.device.lobes import LOBE_GLOSSY, LOBE_REFLECTION
    from warp_spt.bsdfs.common import BsdfSample, to_local, to_world, with_flags
    from warp_spt.device.structs import Materials, Textures
    from warp_spt.accel.surface import INV_PI, INV_TWO_PI, Surface

    LOBE = LOBE_GLOSSY | LOBE_REFLECTION

    def declare(table, rows):
        return LOBE, frozenset({"frame"})

    def make(features, base):
        @wp.func
        def shade(m: Materials, t: Textures, sf: Surface) -> Surface:
            return sf

        @wp.func
        def sample(m: Materials, t: Textures, sf: Surface, u_lobe: float, u_dir: wp.vec2,
                   u_fresnel: float) -> BsdfSample:
            z = u_dir[0]
            r = wp.sqrt(wp.max(0.0, 1.0 - z * z))
            phi = 6.2831855 * u_dir[1]
            out = BsdfSample()
            out.dir = to_world(sf, wp.vec3(r * wp.cos(phi), r * wp.sin(phi), z))
            out.pdf = INV_TWO_PI
            out.weight = m.diffuse[sf.mat] * (2.0 * z)          # (rho / pi) cos / (1 / 2 pi)
            out.alive = wp.where(wp.dot(out.dir, sf.ng) > 0.0, 1, 0)
            return with_flags(out, LOBE)

        @wp.func
        def eval(m: Materials, t: Textures, sf: Surface, wi: wp.vec3) -> wp.vec3:
            c = to_local(sf, wi)[2]
            if c <= 0.0:
                return wp.vec3(0.0, 0.0, 0.0)
            return m.diffuse[sf.mat] * (c * INV_PI)

        @wp.func
        def pdf(m: Materials, t: Textures, sf: Surface, wi: wp.vec3) -> float:
            return wp.where(wp.dot(wi, sf.ns) > 0.0, INV_TWO_PI, 0.0)

        @wp.func
        def albedo(m: Materials, t: Textures, sf: Surface) -> wp.vec3:
            return m.diffuse[sf.mat]

        @wp.func
        def lobes(m: Materials, t: Textures, sf: Surface) -> int:
            return LOBE

        return SimpleNamespace(shade=shade, sample=sample, eval=eval, pdf=pdf, albedo=albedo, lobes=lobes)
''')

KIND_PROBE = textwrap.dedent('''
    import importlib.util, sys
    import numpy as np
    path, module_src, folder = sys.argv[1:4]
    line = 'MATERIAL_KINDS: tuple[str, ...] = ("seed", "pbr")'
    src = open(path).read()
    assert line in src, "the registry line moved"
    src = src.replace(line, 'MATERIAL_KINDS: tuple[str, ...] = ("seed", "pbr", "probe")')   # the one registry line
    spec = importlib.util.spec_from_loader("warp_spt.scene.material_schema", loader=None)
    schema = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = schema
    exec(compile(src, path, "exec"), schema.__dict__)
    import warp as wp
    import warp_spt.device.structs  # noqa: F401  (the kind module imports it)
    kspec = importlib.util.spec_from_file_location("warp_spt.bsdfs.probe", module_src)
    kind = importlib.util.module_from_spec(kspec)
    sys.modules[kind.__name__] = kind         # what importlib finds for the registered name
    kspec.loader.exec_module(kind)            # from a file: Warp reads its functions' source

    from warp_spt.upload.device_scene import DeviceScene
    from warp_spt.device.lobes import LOBE_GLOSSY
    from warp_spt.io.loader import load_scene
    from warp_spt.rendering import tiles as R
    from warp_spt.scene.camera import Camera
    from warp_spt.scene.sky import Sky

    # a sphere of the probe kind (Kd 0.5) and one of the seed's (row 1 and 2): a furnace of radiance 1
    scene = load_scene([folder + "/a.obj"], [folder + "/a.mtl"])
    probe = scene.materials.names.index("probe")
    scene.materials.kind[probe] = 2
    dev = DeviceScene(scene)
    assert dev.features.material_kinds == ("seed", "probe"), dev.features
    assert dev.features.lobes & LOBE_GLOSSY and dev.features.scatters
    cam = Camera(position=(0, -6, 0), direction=(0, 1, 0), fov=16.0, aperture=0.0, focus=6.0)
    res = R.render_scene(dev, cam, R.RenderSettings(width=16, height=16, spp=256, max_depth=3, seed=1,
                                                    sky=Sky.constant(1.0, 1.0, 1.0)))
    img = res.image
    centre = img[5:11, 5:11].reshape(-1, 3)      # every pixel inside the probe sphere's disc
    # convex: one bounce reaches the sky, so each pixel's expectation is rho x L = 0.5 exactly
    se = centre.std(0, ddof=1) / np.sqrt(len(centre))
    mean = centre.mean(0)
    assert np.all(np.abs(mean - 0.5) < 5 * np.maximum(se, 1e-3)), (mean, se)
    assert np.all(np.abs(mean - 0.5) < 0.02), mean
    print("ok")
''')


def test_a_glossy_kind_is_one_module_and_a_registry_line(tmp_path):
    """A glossy kind registered by name renders a furnace through nee (light sampling and MIS from its
    lobe flags, its eval and pdf) to rho x L, beside the seed's kind in the same scene."""
    (tmp_path / "a.obj").write_text("usemtl probe\nb 0 0 0 0.5\nusemtl red\nb 3 4 0 0.5\n")
    (tmp_path / "a.mtl").write_text("newmtl probe\nKd 0.5 0.5 0.5\nnewmtl red\nKd 1 0 0\nKr 0 0 0\n")
    src = str(ROOT / "warp_spt" / "scene" / "material_schema.py")
    (tmp_path / "probe_kind.py").write_text(KIND_MODULE)
    (tmp_path / "probe.py").write_text(KIND_PROBE)       # Warp compiles functions from source files only
    out = subprocess.run([sys.executable, str(tmp_path / "probe.py"), src, str(tmp_path / "probe_kind.py"),
                          str(tmp_path)], capture_output=True,
                         text=True, cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=600)
    assert out.returncode == 0 and out.stdout.strip().endswith("ok"), out.stderr[-3000:] + out.stdout[-2000:]


def test_kinds_are_registered():
    from warp_spt.bsdfs import KINDS

    assert tuple(KINDS) == schema.MATERIAL_KINDS and schema.COLUMN["kind"].high == len(KINDS) - 1
    for module in KINDS.values():
        assert callable(module.make) and callable(module.declare)
