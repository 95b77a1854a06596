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
