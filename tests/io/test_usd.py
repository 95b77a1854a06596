"""The USD reader (warp_spt.usd) on stages the tests write with pxr: one fixture per case."""

from __future__ import annotations

import math

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade  # noqa: E402

from warp_spt.io.loader import load_scene, read_model  # noqa: E402
from warp_spt.scene.errors import SceneError  # noqa: E402


def _stage(tmp_path, name="s.usda", up="Y"):
    path = str(tmp_path / name)
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y if up == "Y" else UsdGeom.Tokens.z)
    return stage, path


def _quad(stage, where, counts=(4,), indices=(0, 1, 2, 3), points=((0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0))):
    m = UsdGeom.Mesh.Define(stage, where)
    m.CreatePointsAttr([Gf.Vec3f(*p) for p in points])
    m.CreateFaceVertexCountsAttr(list(counts))
    m.CreateFaceVertexIndicesAttr(list(indices))
    return m


def _material(stage, where, colour):
    mat = UsdShade.Material.Define(stage, where)
    sh = UsdShade.Shader.Define(stage, where + "/pbr")
    sh.CreateIdAttr("UsdPreviewSurface")
    sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*colour))
    sh.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(0.25)
    mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
    return mat


def _textured_quad(folder, file, colour_space=None, name="s.usda"):
    """A stage ``name`` in ``folder`` of one quad whose material's diffuse colour reads texture ``file``
    (``colour_space``: its sourceColorSpace, unset by default); returns the stage's path."""
    stage, path = _stage(folder, name)
    m = _quad(stage, "/q")
    mat = _material(stage, "/M/t", (1, 1, 1))
    tex = UsdShade.Shader.Define(stage, "/M/t/tex")
    tex.CreateIdAttr("UsdUVTexture")
    tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(file)
    if colour_space is not None:
        tex.CreateInput("sourceColorSpace", Sdf.ValueTypeNames.Token).Set(colour_space)
    UsdShade.Shader(stage.GetPrimAtPath("/M/t/pbr")).GetInput("diffuseColor").ConnectToSource(
        tex.ConnectableAPI(), "rgb")
    UsdShade.MaterialBindingAPI.Apply(m.GetPrim()).Bind(mat)
    stage.Save()
    return path


def test_quads_and_ngons_are_fanned_and_holes_left_out(tmp_path):
    stage, path = _stage(tmp_path)
    pts = [(math.cos(a), math.sin(a), 0) for a in np.linspace(0, 2 * math.pi, 6, endpoint=False)]
    m = _quad(stage, "/ngon", counts=(6, 3, 4), indices=(0, 1, 2, 3, 4, 5, 0, 1, 2, 0, 2, 3, 4), points=pts)
    m.CreateHoleIndicesAttr([1])
    stage.Save()
    d = read_model(path)
    assert len(d.faces) == 4 + 2                    # a hexagon's 4 triangles and a quad's 2; the hole dropped


def test_left_handed_orientation_reverses_the_winding(tmp_path):
    stage, path = _stage(tmp_path)
    _quad(stage, "/q").CreateOrientationAttr(UsdGeom.Tokens.leftHanded)
    stage.Save()
    d = read_model(path)
    p = d.positions[d.faces]
    assert np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])[:, 2].max() < 0     # facing -Z


def test_face_varying_normals_and_uvs(tmp_path):
    stage, path = _stage(tmp_path)
    m = _quad(stage, "/q")
    api = UsdGeom.PrimvarsAPI(m)
    st = api.CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.faceVarying)
    st.Set([Gf.Vec2f(0.1, 0.2), Gf.Vec2f(0.3, 0.4), Gf.Vec2f(0.5, 0.6), Gf.Vec2f(0.7, 0.8)])
    n = api.CreatePrimvar("normals", Sdf.ValueTypeNames.Normal3fArray, UsdGeom.Tokens.faceVarying)
    n.Set([Gf.Vec3f(0, 0, 1), Gf.Vec3f(0, 1, 0), Gf.Vec3f(1, 0, 0), Gf.Vec3f(0, 0, 1)])
    stage.Save()
    s = load_scene([path], warn=lambda m: None)
    mesh = s.meshes[0]
    # first triangle: corners 0, 1, 2 of the quad
    assert np.allclose(mesh.corner_uv[0], [[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]], atol=1e-6)
    assert np.allclose(mesh.corner_normal[0], [[0, 0, 1], [0, 1, 0], [1, 0, 0]], atol=1e-6)


def test_a_subset_with_two_materials(tmp_path):
    stage, path = _stage(tmp_path)
    m = _quad(stage, "/q", counts=(3, 3), indices=(0, 1, 2, 0, 2, 3))
    red, blue = _material(stage, "/M/red", (1, 0, 0)), _material(stage, "/M/blue", (0, 0, 1))
    UsdShade.MaterialBindingAPI.Apply(m.GetPrim()).Bind(red)
    sub = UsdGeom.Subset.CreateGeomSubset(m, "b", UsdGeom.Tokens.face, [1], "materialBind")
    UsdShade.MaterialBindingAPI.Apply(sub.GetPrim()).Bind(blue)
    stage.Save()
    s = load_scene([path], warn=lambda m: None)
    colours = [tuple(np.round(s.materials.base_color[r], 3)) for r in s.meshes[0].face_material]
    assert sorted(colours) == [(0.0, 0.0, 1.0), (1.0, 0.0, 0.0)]
    assert np.allclose(s.materials.roughness[s.meshes[0].face_material], 0.25)


def test_xform_hierarchy_with_a_reset(tmp_path):
    stage, path = _stage(tmp_path)
    UsdGeom.Xform.Define(stage, "/a").AddTranslateOp().Set(Gf.Vec3d(10, 0, 0))
    b = UsdGeom.Xform.Define(stage, "/a/b")
    b.AddTranslateOp().Set(Gf.Vec3d(0, 5, 0))
    _quad(stage, "/a/b/q")
    c = UsdGeom.Xform.Define(stage, "/a/c")
    c.SetResetXformStack(True)
    c.AddTranslateOp().Set(Gf.Vec3d(0, 0, 7))
    _quad(stage, "/a/c/q")
    stage.Save()
    d = read_model(path)
    lo = d.positions.min(0)
    assert np.allclose(sorted({tuple(p) for p in d.positions[d.faces[:2].ravel()]})[0], [10, 5, 0])
    assert np.isclose(d.positions[:, 2].max(), 7) and np.isclose(lo[0], 0)    # the reset drops /a's translate


def test_native_instances_and_a_point_instancer_are_placed_not_copied(tmp_path):
    stage, path = _stage(tmp_path)
    proto = UsdGeom.Xform.Define(stage, "/Proto")
    _quad(stage, "/Proto/q")
    proto.GetPrim().SetSpecifier(Sdf.SpecifierClass)
    for k in range(3):
        inst = UsdGeom.Xform.Define(stage, f"/i{k}")
        inst.GetPrim().GetReferences().AddInternalReference("/Proto")
        inst.GetPrim().SetInstanceable(True)
        inst.AddTranslateOp().Set(Gf.Vec3d(3 * k, 0, 0))
    pi = UsdGeom.PointInstancer.Define(stage, "/pi")
    _quad(stage, "/pi/protos/q2")
    pi.CreatePrototypesRel().SetTargets(["/pi/protos/q2"])
    pi.CreateProtoIndicesAttr([0, 0])
    pi.CreatePositionsAttr([Gf.Vec3f(0, 10, 0), Gf.Vec3f(0, 20, 0)])
    stage.Save()
    d = read_model(path)
    assert len(d.faces) == 0
    placed = sorted(((len(sub.faces), len(xf)) for sub, xf in d.extras.placed))
    assert placed == [(2, 2), (2, 3)]
    ys = sorted(x[1, 3] for sub, xf in d.extras.placed for x in xf)
    assert np.allclose(ys, [0, 0, 0, 10, 20])


def test_lights_of_each_kind(tmp_path):
    stage, path = _stage(tmp_path)
    _quad(stage, "/floor")
    sun = UsdLux.DistantLight.Define(stage, "/sun")
    sun.CreateIntensityAttr(3.0)
    sun.CreateAngleAttr(1.0)
    UsdLux.SphereLight.Define(stage, "/ball").CreateRadiusAttr(0.25)
    pt = UsdLux.SphereLight.Define(stage, "/pt")
    pt.CreateTreatAsPointAttr(True)
    pt.CreateIntensityAttr(2.0)
    UsdGeom.Xformable(pt).AddTranslateOp().Set(Gf.Vec3d(0, 4, 0))
    rect = UsdLux.RectLight.Define(stage, "/rect")
    rect.CreateWidthAttr(2.0)
    rect.CreateHeightAttr(0.5)
    rect.CreateExposureAttr(1.0)
    UsdLux.DiskLight.Define(stage, "/disk").CreateRadiusAttr(0.5)
    UsdLux.DomeLight.Define(stage, "/dome").CreateColorAttr(Gf.Vec3f(0.2, 0.3, 0.4))
    stage.Save()
    s = load_scene([path], warn=lambda m: None)
    kinds = {type(x).__name__: x for x in s.lights}
    assert kinds["SunLight"].direction == pytest.approx((0, 0, 1)) and kinds["SunLight"].color == (3, 3, 3)
    assert kinds["SunLight"].radius_deg == pytest.approx(0.5)
    assert kinds["PointLight"].position == pytest.approx((0, 4, 0))
    assert np.allclose(s.spheres[:, 3], 0.25)
    assert np.allclose(s.materials.emission[s.sphere_material[0]], 1.0)
    total = 0.0
    for m in s.meshes:                          # the emitting triangles (the floor's row 0 aside)
        p = m.positions[m.indices[m.face_material > 0]]
        total += float(np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1).sum() / 2)
    assert total == pytest.approx(2 * 0.5 + math.pi * 0.25, rel=0.01)
    assert 2.0 in np.round(s.materials.emission[:, 0], 6)           # the rect light's exposure 1: x2
    assert s.sky.color == pytest.approx((0.2, 0.3, 0.4))


def test_a_camera_and_up_axis_z_and_metres_per_unit(tmp_path):
    stage, path = _stage(tmp_path, up="Z")
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    _quad(stage, "/q", points=((0, 0, 100), (100, 0, 100), (100, 100, 100), (0, 100, 100)))
    cam = UsdGeom.Camera.Define(stage, "/cam")
    cam.CreateFocalLengthAttr(50.0)
    cam.CreateVerticalApertureAttr(20.0)
    cam.AddTranslateOp().Set(Gf.Vec3d(0, 0, 500))
    stage.Save()
    d = read_model(path)
    assert np.allclose(d.positions[:, 1], 1.0)                  # z = 100 cm is y = 1 m
    c = d.extras.cameras[0]
    assert c.position == pytest.approx((0, 5, 0)) and c.direction == pytest.approx((0, -1, 0))
    assert c.yfov == pytest.approx(2 * math.atan(10 / 50))


def test_an_authored_subdivision_scheme_is_named_in_a_warning(tmp_path):
    stage, path = _stage(tmp_path)
    _quad(stage, "/plain")                                          # the fallback catmullClark: no warning
    _quad(stage, "/smooth").CreateSubdivisionSchemeAttr(UsdGeom.Tokens.catmullClark)
    _quad(stage, "/flat").CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    stage.Save()
    d = read_model(path)
    assert len(d.faces) == 6
    assert [w.split(": ", 1)[1] for w in d.warnings] == [
        "/smooth: subdivisionScheme catmullClark is not applied: drawn as its control cage"]


def test_guides_and_proxies_are_skipped(tmp_path):
    stage, path = _stage(tmp_path)
    _quad(stage, "/render")
    _quad(stage, "/proxy").CreatePurposeAttr(UsdGeom.Tokens.proxy)
    _quad(stage, "/guide").CreatePurposeAttr(UsdGeom.Tokens.guide)
    stage.Save()
    assert len(read_model(path).faces) == 2


def test_an_animated_translate_poses_each_frame(tmp_path):
    stage, path = _stage(tmp_path)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(25)
    stage.SetTimeCodesPerSecond(24)
    x = UsdGeom.Xform.Define(stage, "/x")
    op = x.AddTranslateOp()
    op.Set(Gf.Vec3d(0, 0, 0), 1)
    op.Set(Gf.Vec3d(24, 0, 0), 25)
    _quad(stage, "/x/q")
    stage.Save()
    assert read_model(path).extras.time_range == pytest.approx((0.0, 1.0))
    assert read_model(path, time=0.5).positions[:, 0].min() == pytest.approx(12.0)

    from warp_spt.animation import ObjSequence

    seq = ObjSequence([path], fps=24)
    assert len(seq.default_frames()) == 25
    assert seq.scene(6).meshes[0].world_bounds()[0][0] == pytest.approx(6.0)


def test_bad_stages_name_the_file_and_the_prim(tmp_path):
    stage, path = _stage(tmp_path)
    _quad(stage, "/bad", counts=(4,), indices=(0, 1, 2, 9))
    stage.Save()
    with pytest.raises(SceneError, match=r"s\.usda.*/bad.*point 9"):
        read_model(path)
    junk = tmp_path / "junk.usda"
    junk.write_text("#usda 1.0\n(\n this is not usd\n")
    with pytest.raises(SceneError, match="junk.usda"):
        read_model(str(junk))


def test_a_texture_outside_the_stage_folder_is_refused(tmp_path):
    inner = tmp_path / "scene"
    inner.mkdir()
    from PIL import Image

    Image.new("RGB", (2, 2), (255, 0, 0)).save(tmp_path / "outside.png")
    path = _textured_quad(inner, "../outside.png")
    with pytest.raises(SceneError, match=r"/M/t/tex.*outside"):
        read_model(path)


def test_raw_colour_space_is_not_decoded(tmp_path):
    from PIL import Image

    Image.new("RGB", (2, 2), (128, 128, 128)).save(tmp_path / "grey.png")
    path = _textured_quad(tmp_path, "grey.png", colour_space="raw")
    s = load_scene([path], warn=lambda m: None)
    assert s.textures[-1].mean() == pytest.approx(128 / 255, abs=1e-3)     # sRGB would give 0.216


def test_a_stretched_sphere_and_a_cube_become_polygons(tmp_path):
    """A sphere under a non-uniform scale cannot be the renderer's exact sphere: its polygons, whose
    extent is the radius times the scale (to the polygons' 0.22% sag at the equator's edges); a
    Cube of size 2 is the box from -1 to 1."""
    stage, path = _stage(tmp_path)
    ball = UsdGeom.Sphere.Define(stage, "/egg")
    ball.CreateRadiusAttr(0.5)
    ball.AddScaleOp().Set(Gf.Vec3f(2.0, 1.0, 1.0))
    box = UsdGeom.Cube.Define(stage, "/box")
    box.AddTranslateOp().Set(Gf.Vec3d(5.0, 0.0, 0.0))
    stage.Save()
    d = read_model(path)
    assert len(d.spheres) == 0
    egg = d.positions[d.positions[:, 0] < 2.5]
    assert np.allclose(egg.max(0), [1.0, 0.5, 0.5], rtol=3e-3)
    assert np.allclose(egg.min(0), [-1.0, -0.5, -0.5], rtol=3e-3)
    cube = d.positions[d.positions[:, 0] > 2.5]
    assert np.allclose(cube.min(0), [4, -1, -1]) and np.allclose(cube.max(0), [6, 1, 1])
    p = d.positions[d.faces]
    outward = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]),
                        p.mean(1) - np.where(p.mean(1)[:, :1] > 2.5, [5.0, 0, 0], 0.0))
    assert (outward > 0).all()                       # every face counter-clockwise seen from outside


@pytest.mark.parametrize("name", ["bunny", "cube", "sphere", "rocks", "bear", "nonuniform", "square_cloth"])
def test_the_public_samples_warp_lang_ships(name):
    """The USD files in warp-lang's examples/assets (public samples installed with the package): every
    mesh's polygons become their fans' triangles, counted here from the stage's own arrays."""
    warp = pytest.importorskip("warp")
    from pathlib import Path

    path = Path(warp.__file__).parent / "examples" / "assets" / f"{name}.usd"
    if not path.is_file():
        pytest.skip(f"this warp-lang does not ship {path.name}")
    stage = Usd.Stage.Open(str(path))
    expected = 0
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Mesh):
            counts = np.asarray(UsdGeom.Mesh(prim).GetFaceVertexCountsAttr().Get(), np.int64)
            expected += int(np.maximum(counts - 2, 0).sum())
    d = read_model(str(path))
    assert expected > 0 and len(d.faces) + d.dropped_degenerate == expected
    assert np.isfinite(d.positions).all()


def _package(folder, name, files):
    """A .usdz in ``folder`` of ``files`` (paths, the stage first), each under its own name."""
    out = str(folder / name)
    with Sdf.ZipFileWriter.CreateNew(out) as zw:
        for f in files:
            zw.AddFile(str(f), f.name)
    return out


def test_a_usdz_with_its_textures_is_read_from_the_package(tmp_path, monkeypatch):
    """A packaged stage's colour texture and dome light map are read from the archive: the files it was
    made of are gone before it is opened, and nothing is left extracted (the map readers' temporary
    folder, under a temp root of the test's, is removed)."""
    from PIL import Image

    from warp_spt.images.hdr import write_hdr

    src, out, temp = tmp_path / "src", tmp_path / "out", tmp_path / "temp"
    for f in (src, out, temp):
        f.mkdir()
    Image.new("RGB", (2, 2), (200, 100, 50)).save(src / "wood.png")
    sky = np.zeros((4, 8, 3), np.float32)
    sky[:2] = (1.0, 0.5, 0.25)
    sky[2:] = 0.25
    write_hdr(src / "sky.hdr", sky)
    write_hdr(tmp_path / "same.hdr", sky)                      # the same map as a plain file, read after
    path = _textured_quad(src, "wood.png")
    stage = Usd.Stage.Open(path)
    UsdLux.DomeLight.Define(stage, "/dome").CreateTextureFileAttr("sky.hdr")
    stage.Save()
    package = _package(out, "scene.usdz", [src / "s.usda", src / "wood.png", src / "sky.hdr"])
    import shutil
    import tempfile

    shutil.rmtree(src)
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    s = load_scene([package], warn=lambda m: None)
    from warp_spt.io.loader import srgb_to_linear

    expected = srgb_to_linear(np.array([200, 100, 50], np.float32) / 255)
    assert np.allclose(s.textures[-1][..., :3].reshape(-1, 3), expected, atol=1e-6)
    from warp_spt.images.hdr import read_hdr

    assert np.array_equal(s.sky.env.image, read_hdr(tmp_path / "same.hdr"))
    assert sorted(p.name for p in out.iterdir()) == ["scene.usdz"] and not any(temp.iterdir())


def test_a_packaged_texture_outside_the_stage_folder_is_refused(tmp_path):
    """The rule for files holds for packages: a package outside the stage's folder, named by '..', by
    an absolute path or through a link in the folder, is refused before anything is read from it."""
    from PIL import Image

    Image.new("RGB", (2, 2), (255, 0, 0)).save(tmp_path / "tex.png")
    outside = _package(tmp_path, "pkg.usdz", [tmp_path / "tex.png"])
    inner = tmp_path / "scene"
    inner.mkdir()
    (inner / "link.usdz").symlink_to(outside)
    for k, name in enumerate(("../pkg.usdz[tex.png]", f"{outside}[tex.png]", "link.usdz[tex.png]")):
        path = _textured_quad(inner, name, name=f"s{k}.usda")
        with pytest.raises(SceneError, match=r"/M/t/tex.*texture's package .*(outside|leads outside)"):
            read_model(path)
    # the same package inside the folder is read
    (inner / "link.usdz").unlink()
    (inner / "pkg.usdz").write_bytes((tmp_path / "pkg.usdz").read_bytes())
    path = _textured_quad(inner, "pkg.usdz[tex.png]", name="inside.usda")
    s = load_scene([path], warn=lambda m: None)
    assert np.allclose(s.textures[-1][..., :3], [1.0, 0.0, 0.0])


@pytest.mark.parametrize("axis", ["X", "Y", "Z"])
def test_cylinders_cones_and_capsules_about_their_axis(tmp_path, axis):
    """Each shape's extent along its axis and across it, from its radius and height (UsdGeom's
    definitions: centred on the origin; a capsule's height is its spine without the caps); every face
    counter-clockwise seen from outside."""
    stage, path = _stage(tmp_path)
    shapes = ((UsdGeom.Cylinder, 0.5, 2.0), (UsdGeom.Cone, 0.4, 1.5), (UsdGeom.Capsule, 0.25, 1.0))
    for k, (kind, radius, height) in enumerate(shapes):
        prim = kind.Define(stage, f"/s{k}")
        prim.CreateRadiusAttr(radius)
        prim.CreateHeightAttr(height)
        prim.CreateAxisAttr(axis)
        prim.AddTranslateOp().Set(Gf.Vec3d(10.0 * k, 0.0, 0.0))
    stage.Save()
    d = read_model(path)
    a = "XYZ".index(axis)
    for k, (radius, along) in enumerate(((0.5, 1.0), (0.4, 0.75), (0.25, 0.75))):
        p = d.positions - [10.0 * k, 0.0, 0.0]
        p = p[np.abs(p[:, 0]) < 5]
        want = np.full(3, radius)
        want[a] = along
        assert np.allclose(p.max(0), want, atol=1e-9) and np.allclose(p.min(0), -want, atol=1e-9), k
    t = d.positions[d.faces]
    centre = np.round(t.mean(1)[:, :1] / 10.0) * [10.0, 0, 0]
    outward = np.einsum("ij,ij->i", np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0]), t.mean(1) - centre)
    assert (outward > 0).all()


def test_a_point_instancers_colours_per_instance(tmp_path):
    """Warp's render_points writes one displayColor per particle on the instancer: an unbound prototype
    is drawn in each instance's colour (one placed mesh per colour); more colours than
    MAX_INSTANCE_COLOURS are drawn in their mean, with a warning."""
    from warp_spt.usd.stage import MAX_INSTANCE_COLOURS

    def instancer(path, colours):
        stage, _ = _stage(tmp_path, path)
        pi = UsdGeom.PointInstancer.Define(stage, "/pi")
        UsdGeom.Cube.Define(stage, "/pi/protos/box")
        pi.CreatePrototypesRel().SetTargets(["/pi/protos/box"])
        pi.CreateProtoIndicesAttr([0] * len(colours))
        pi.CreatePositionsAttr([Gf.Vec3f(3.0 * k, 0, 0) for k in range(len(colours))])
        pv = UsdGeom.PrimvarsAPI(pi).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray,
                                                   UsdGeom.Tokens.vertex)
        pv.Set([Gf.Vec3f(*c) for c in colours])
        stage.Save()
        return load_scene([str(tmp_path / path)], warn=lambda m: None)

    s = instancer("few.usda", [(1, 0, 0), (0, 0, 1), (1, 0, 0)])
    drawn = sorted((tuple(np.round(s.materials.base_color[m.face_material[0]], 3)), sorted(m.transforms[:, 0, 3]))
                   for m in s.meshes)
    assert drawn == [((0.0, 0.0, 1.0), [3.0]), ((1.0, 0.0, 0.0), [0.0, 6.0])]
    many = [(k / (MAX_INSTANCE_COLOURS + 1), 0.5, 0.5) for k in range(MAX_INSTANCE_COLOURS + 1)]
    s = instancer("many.usda", many)
    assert len(s.meshes) == 1 and np.allclose(s.materials.base_color[s.meshes[0].face_material[0]],
                                              np.mean(many, axis=0), atol=1e-6)
    assert any(f"{MAX_INSTANCE_COLOURS + 1} colours over its instances" in w for w in s.warnings)
