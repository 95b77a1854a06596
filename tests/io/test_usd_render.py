"""USD stages rendered: a stage and its twin written by hand as OBJ/MTL text give the same image, and
a stage written by Warp's own ``warp.render.UsdRenderer`` loads and renders (the round trip of Warp's
and Newton's users). The twins share no reader code: the OBJ side goes through io/obj.py and
io/mtl.py, the USD side through usd/."""

from __future__ import annotations

import math

import numpy as np
import pytest

pxr = pytest.importorskip("pxr")
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade  # noqa: E402

from warp_spt.io.loader import load_scene  # noqa: E402
from warp_spt.rendering.settings import RenderSettings  # noqa: E402
from warp_spt.rendering.tiles import render_scene  # noqa: E402
from warp_spt.scene.camera import Camera  # noqa: E402
from warp_spt.scene.sky import Sky  # noqa: E402

# the cube's corners (unit cube at the origin) and its six faces as quads, counter-clockwise from outside
_CUBE_POINTS = [(x, y, z) for x in (0.0, 1.0) for y in (0.0, 1.0) for z in (0.0, 1.0)]
_CUBE_FACES = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
_FLOOR = [(-3.0, 0.0, -3.0), (-3.0, 0.0, 3.0), (3.0, 0.0, 3.0), (3.0, 0.0, -3.0)]
_LAMP = [(-0.75, 3.0, -0.75), (0.75, 3.0, -0.75), (0.75, 3.0, 0.75), (-0.75, 3.0, 0.75)]     # faces -Y
_OFFSET = (-0.5, 0.0, -0.25)           # the cube's translate
# (name, diffuse colour, roughness, metallic, emission)
_MATERIALS = [("floor", (0.7, 0.7, 0.7), 0.8, 0.0, (0.0, 0.0, 0.0)),
              ("box", (0.8, 0.2, 0.1), 0.3, 0.0, (0.0, 0.0, 0.0)),
              ("gold", (1.0, 0.75, 0.3), 0.4, 1.0, (0.0, 0.0, 0.0)),
              ("lamp", (0.0, 0.0, 0.0), 0.5, 0.0, (12.0, 12.0, 10.0))]


def _write_usd(path: str) -> None:
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    mats = {}
    for name, colour, rough, metal, emit in _MATERIALS:
        mat = UsdShade.Material.Define(stage, f"/Looks/{name}")
        sh = UsdShade.Shader.Define(stage, f"/Looks/{name}/pbr")
        sh.CreateIdAttr("UsdPreviewSurface")
        sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*colour))
        sh.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(rough)
        sh.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(metal)
        sh.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*emit))
        mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
        mats[name] = mat

    def mesh(where, points, faces, material):
        m = UsdGeom.Mesh.Define(stage, where)
        m.CreatePointsAttr([Gf.Vec3f(*p) for p in points])
        m.CreateFaceVertexCountsAttr([len(f) for f in faces])
        m.CreateFaceVertexIndicesAttr([i for f in faces for i in f])
        UsdShade.MaterialBindingAPI.Apply(m.GetPrim()).Bind(mats[material])
        return m

    mesh("/World/floor", _FLOOR, [(0, 1, 2, 3)], "floor")
    mesh("/World/lamp", _LAMP, [(0, 1, 2, 3)], "lamp")
    box = UsdGeom.Xform.Define(stage, "/World/boxes")
    box.AddTranslateOp().Set(Gf.Vec3d(*_OFFSET))
    cube = mesh("/World/boxes/cube", _CUBE_POINTS, _CUBE_FACES, "box")
    # the top face in gold through a subset
    sub = UsdGeom.Subset.CreateGeomSubset(cube, "top", UsdGeom.Tokens.face, [3], "materialBind")
    UsdShade.MaterialBindingAPI.Apply(sub.GetPrim()).Bind(mats["gold"])
    stage.Save()


def _write_obj(folder) -> tuple[str, str]:
    """The same scene as OBJ/MTL text, in world coordinates, quads as quads (the reader fans them)."""
    mtl = []
    for name, colour, rough, metal, emit in _MATERIALS:
        mtl += [f"newmtl {name}", "Kd {} {} {}".format(*colour), f"Pr {rough}", f"Pm {metal}",
                "Ke {} {} {}".format(*emit), ""]
    lines, k = ["mtllib twin.mtl"], 1
    cube = [tuple(float(np.float32(c)) + o for c, o in zip(p, _OFFSET)) for p in _CUBE_POINTS]
    for name, points, faces in (("floor", _FLOOR, [(0, 1, 2, 3)]), ("lamp", _LAMP, [(0, 1, 2, 3)]),
                                ("box", cube, _CUBE_FACES)):
        lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in points]
        for j, f in enumerate(faces):
            lines.append(f"usemtl {'gold' if name == 'box' and j == 3 else name}")
            lines.append("f " + " ".join(str(k + i) for i in f))
        k += len(points)
    (folder / "twin.mtl").write_text("\n".join(mtl) + "\n")
    (folder / "twin.obj").write_text("\n".join(lines) + "\n")
    return str(folder / "twin.obj"), str(folder / "twin.mtl")


def _render(scene, spp=8):
    camera = Camera.look_at((1.8, 2.2, 4.5), (0.0, 0.5, 0.0), up="y", fov=40.0)
    settings = RenderSettings(width=40, height=30, spp=spp, max_depth=4, sky=Sky.constant(0.05, 0.05, 0.08),
                              threads=1)
    return render_scene(scene, camera, settings).film.image()


def test_a_stage_renders_as_its_obj_twin(tmp_path):
    """Bit for bit: the same triangles (the cube's translate applied in float64, then rounded to float32
    as the OBJ's decimal text is), the same materials, the same random streams."""
    _write_usd(str(tmp_path / "twin.usda"))
    obj, mtl = _write_obj(tmp_path)
    usd = load_scene([str(tmp_path / "twin.usda")], warn=lambda m: None, smooth_angle=None)
    twin = load_scene([obj], [mtl], warn=lambda m: None, smooth_angle=None)
    a, b = _render(usd), _render(twin)
    assert a.shape == (30, 40, 3) and a.max() > 0.05              # lit: not an empty frame
    assert np.array_equal(a, b), f"largest difference {np.abs(a - b).max():.3g}"


def _warp_stage(path: str) -> None:
    """A stage written by Warp's UsdRenderer as a simulation writes one: Z up, 30 frames a second, a
    ground, a ball that moves from z = 1 to 2 over one second, a box, a mesh, two particles, a capsule
    (along the stage's Y: the writer's default up_axis 1) and a cloud of points."""
    render = pytest.importorskip("warp.render")
    if not hasattr(render, "UsdRenderer"):
        pytest.skip("this warp-lang has no warp.render.UsdRenderer")
    r = render.UsdRenderer(path, up_axis="Z", fps=30)
    still = (0.0, 0.0, 0.0, 1.0)
    r.begin_frame(0.0)
    r.render_ground(size=5.0)
    r.render_sphere("ball", pos=(0.0, 0.0, 1.0), rot=still, radius=0.5, color=(0.9, 0.1, 0.1))
    r.render_box("crate", pos=(1.5, 0.0, 0.25), rot=still, extents=(0.25, 0.5, 0.25), color=(0.1, 0.2, 0.9))
    r.render_mesh("tri", points=np.array([[0, 2, 0], [1, 2, 0], [0, 2, 1]], np.float32), indices=np.array([0, 1, 2]),
                  colors=(0.2, 0.8, 0.2))
    r.render_points("dots", points=np.array([[-1, -1, 0.1], [-1.5, -1, 0.1]], np.float32), radius=0.1,
                    colors=(0.9, 0.9, 0.1))
    r.render_capsule("cap", pos=(0.0, 0.0, 3.0), rot=still, radius=0.1, half_height=0.3, color=(0.5, 0.5, 0.5))
    r.render_points("cloud", points=np.array([[2, 2, 2]], np.float32), radius=0.05, as_spheres=False)
    r.end_frame()
    r.begin_frame(1.0)
    r.render_sphere("ball", pos=(0.0, 0.0, 2.0), rot=still, radius=0.5, color=(0.9, 0.1, 0.1))
    r.end_frame()
    r.save()


def test_a_stage_written_by_warps_usd_renderer(tmp_path):
    """What warp.render.UsdRenderer writes is read where it matters: spheres (exact ones, or as polygons
    under a PointInstancer), cubes scaled to boxes, meshes, displayColor as the base colour, its dome
    and distant lights with their colour temperature, its frames, capsules as polygons; a cloud of
    ``Points`` is named in a warning.
    The expected values are the writer's inputs, turned from Z up to Y up: (x, y, z) -> (x, z, -y)."""
    path = str(tmp_path / "sim.usda")
    _warp_stage(path)
    from warp_spt.io.loader import read_model
    from warp_spt.usd.shapes import SPHERE_SEGMENTS

    d = read_model(path)
    assert [w.split(": ", 1)[1] for w in d.warnings] == ["/root/cloud: Points prims are not read (meshes are)"]
    assert np.allclose(d.spheres, [[0.0, 1.0, 0.0, 0.5]])
    assert np.allclose(read_model(path, time=1.0).spheres, [[0.0, 2.0, 0.0, 0.5]])
    assert d.extras.time_range == pytest.approx((0.0, 1.0))
    (dots, placements), = d.extras.placed
    assert np.allclose(placements[:, :3, 3], [[-1.0, 0.1, 1.0], [-1.5, 0.1, 1.0]])
    assert np.allclose(placements[:, :3, :3], 0.1 * np.array([[1, 0, 0], [0, 0, 1], [0, -1, 0]]))
    assert np.allclose(np.linalg.norm(dots.positions, axis=1), 1.0)            # the unit sphere's polygons
    assert len(dots.faces) == 2 * SPHERE_SEGMENTS * (SPHERE_SEGMENTS // 2 - 1)

    s = load_scene([path], warn=lambda m: None)
    assert not s.seed_dialect                  # the stage's spheres do not make it an OBJ of the seed's
    corners = {}                                # base colour -> the corners of its triangles
    for m in s.meshes:
        for row in np.unique(m.face_material):
            key = tuple(round(float(c), 3) for c in s.materials.base_color[row])
            corners.setdefault(key, []).append(m.positions[m.indices[m.face_material == row]].reshape(-1, 3))
    corners = {k: np.concatenate(v) for k, v in corners.items()}
    assert set(corners) >= {(0.1, 0.2, 0.9), (0.2, 0.8, 0.2), (0.9, 0.9, 0.1)}
    assert np.allclose(s.materials.base_color[s.sphere_material[0]], (0.9, 0.1, 0.1))
    crate = corners[(0.1, 0.2, 0.9)]
    assert np.allclose(crate.min(0), [1.25, 0.0, -0.5]) and np.allclose(crate.max(0), [1.75, 0.5, 0.5])
    assert np.allclose(np.unique(corners[(0.2, 0.8, 0.2)], axis=0), [[0, 0, -2], [0, 1, -2], [1, 0, -2]])
    cap = corners[(0.5, 0.5, 0.5)]                 # the stage's Y is our -Z: the spine 0.6 plus two caps of 0.1
    assert np.allclose(cap.min(0), [-0.1, 2.9, -0.4], atol=1e-6) and np.allclose(cap.max(0), [0.1, 3.1, 0.4], atol=1e-6)
    # the dome (6150 K) and the sun (7250 K) tinted by UsdLux's blackbody: warm and cool, exposure 9 and 10
    sun, = s.lights
    assert s.sky.color[0] > s.sky.color[2] and sun.color[2] > sun.color[0]
    assert sum(s.sky.color) / 3 == pytest.approx(2.0 ** 9, rel=0.1)
    assert sun.direction[1] > 0                                                 # above the ground

    camera = Camera.look_at((0.0, 1.0, 4.0), (0.0, 1.0, 0.0), up="y", fov=30.0)
    image = render_scene(s, camera, RenderSettings(width=24, height=24, spp=4, max_depth=3, threads=1)).image
    assert np.isfinite(image).all()
    r, g, b = image[12, 12]
    assert r > 3 * g and r > 3 * b                       # the ball in the middle, in its displayColor


def test_the_command_line_renders_a_stage_through_its_camera(tmp_path, capsys, monkeypatch):
    """``-obj stage.usda --camera NAME`` renders and exits 0; without usd-core the same command line is
    one line saying how to install it, exit status 1, no traceback."""
    from warp_spt.cli.main import main

    _write_usd(str(tmp_path / "twin.usda"))
    stage = Usd.Stage.Open(str(tmp_path / "twin.usda"))
    cam = UsdGeom.Camera.Define(stage, "/World/cam")
    cam.AddTranslateOp().Set(Gf.Vec3d(0.0, 1.5, 6.0))
    stage.Save()
    out = tmp_path / "o.png"
    argv = ["-obj", str(tmp_path / "twin.usda"), "-res", "16", "12", "-sr", "1", "--camera", "cam", "-out", str(out)]
    assert main(argv) == 0 and out.stat().st_size > 0
    capsys.readouterr()
    monkeypatch.setitem(__import__("sys").modules, "pxr", None)             # usd-core not installed
    assert main(argv[:-1] + [str(tmp_path / "p.png")]) == 1
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if "error" in line]
    assert len(lines) == 1 and 'pip install ".[usd]"' in lines[0] and "Traceback" not in err, err
    assert not (tmp_path / "p.png").exists()
