"""docs/usd_stage.png: a USD stage the reader draws, written here with pxr and packed as a ``.usdz``.

The stage is Z up in centimetres (``metersPerUnit`` 0.01): a floor; three pillars, one ``Cube``
prototype placed by instanceable prims (TLAS instances); a ring of eight ``Sphere`` prototypes
placed by a ``PointInstancer``; a red ball of ``UsdPreviewSurface`` with a clearcoat (an exact
sphere); a sign whose ``diffuseColor`` is a ``UsdUVTexture`` inside the package; a rect light, a
distant light and a dome light; the ``UsdGeom.Camera`` looked through. The stage and its texture
are packed into one ``scene.usdz`` and rendered by one warp-spt command line, run in-process; the
command is printed. Needs usd-core (``pip install ".[usd]"``).

    python scripts/make_usd_stage_image.py [--width 256] [--spp 64]
"""

from __future__ import annotations

import argparse
import io
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from warp_spt.cli.main import run  # noqa: E402
from warp_spt.cli.options import parse_args  # noqa: E402


def write_stage(folder: Path) -> Path:
    """The stage and its texture in ``folder``, packed into ``folder/scene.usdz``."""
    from PIL import Image
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade

    checker = np.kron((np.indices((8, 8)).sum(0) % 2)[..., None] * np.array([[[200, 170, 60]]]) + 30,
                      np.ones((8, 8, 1))).astype(np.uint8)
    Image.fromarray(checker).save(folder / "sign.png")
    path = folder / "scene.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)

    def material(name, colour, rough, metallic=0.0, coat=0.0, texture=None):
        mat = UsdShade.Material.Define(stage, f"/Looks/{name}")
        sh = UsdShade.Shader.Define(stage, f"/Looks/{name}/pbr")
        sh.CreateIdAttr("UsdPreviewSurface")
        colour_in = sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f)
        colour_in.Set(Gf.Vec3f(*colour))
        sh.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(rough)
        sh.CreateInput("metallic", Sdf.ValueTypeNames.Float).Set(metallic)
        sh.CreateInput("clearcoat", Sdf.ValueTypeNames.Float).Set(coat)
        sh.CreateInput("clearcoatRoughness", Sdf.ValueTypeNames.Float).Set(0.02)
        if texture:
            tex = UsdShade.Shader.Define(stage, f"/Looks/{name}/tex")
            tex.CreateIdAttr("UsdUVTexture")
            tex.CreateInput("file", Sdf.ValueTypeNames.Asset).Set(texture)
            colour_in.ConnectToSource(tex.ConnectableAPI(), "rgb")
        mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
        return mat

    def bind(prim, mat):
        UsdShade.MaterialBindingAPI.Apply(prim.GetPrim()).Bind(mat)

    floor = UsdGeom.Mesh.Define(stage, "/World/floor")
    floor.CreatePointsAttr([(-300, -300, 0), (300, -300, 0), (300, 300, 0), (-300, 300, 0)])
    floor.CreateFaceVertexCountsAttr([4])
    floor.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    bind(floor, material("floor", (0.55, 0.55, 0.6), 0.7))

    pillar = UsdGeom.Xform.Define(stage, "/Prototypes/pillar")
    pillar.GetPrim().SetSpecifier(Sdf.SpecifierClass)
    cube = UsdGeom.Cube.Define(stage, "/Prototypes/pillar/cube")
    cube.AddTranslateOp().Set(Gf.Vec3d(0, 0, 0.5))          # a unit cube on the floor, 24 cm square
    cube.AddScaleOp().Set(Gf.Vec3f(24, 24, 1))
    cube.CreateSizeAttr(1.0)
    bind(cube, material("stone", (0.8, 0.78, 0.72), 0.6))
    for k, (x, h) in enumerate(((-120, 70), (-20, 100), (80, 70))):
        inst = UsdGeom.Xform.Define(stage, f"/World/pillar{k}")
        inst.GetPrim().GetReferences().AddInternalReference("/Prototypes/pillar")
        inst.GetPrim().SetInstanceable(True)
        inst.AddTranslateOp().Set(Gf.Vec3d(x, 60, 0))
        inst.AddScaleOp().Set(Gf.Vec3f(1, 1, h))

    ring = UsdGeom.PointInstancer.Define(stage, "/World/ring")
    bead = UsdGeom.Sphere.Define(stage, "/World/ring/protos/bead")
    bead.CreateRadiusAttr(9.0)
    bind(bead, material("gold", (1.0, 0.76, 0.33), 0.3, metallic=1.0))
    ring.CreatePrototypesRel().SetTargets([bead.GetPath()])
    angles = np.linspace(0.0, 2.0 * math.pi, 8, endpoint=False)
    ring.CreateProtoIndicesAttr([0] * 8)
    ring.CreatePositionsAttr([Gf.Vec3f(float(60 * math.cos(a)), float(60 * math.sin(a) - 20), 9.0) for a in angles])

    ball = UsdGeom.Sphere.Define(stage, "/World/ball")
    ball.CreateRadiusAttr(28.0)
    ball.AddTranslateOp().Set(Gf.Vec3d(0, -20, 28))
    bind(ball, material("coated", (0.6, 0.04, 0.03), 0.5, coat=1.0))

    sign = UsdGeom.Mesh.Define(stage, "/World/sign")
    sign.CreatePointsAttr([(115, 45, 10), (185, 20, 10), (185, 20, 80), (115, 45, 80)])
    sign.CreateFaceVertexCountsAttr([4])
    sign.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    st = UsdGeom.PrimvarsAPI(sign).CreatePrimvar("st", Sdf.ValueTypeNames.TexCoord2fArray, UsdGeom.Tokens.vertex)
    st.Set([(0, 0), (1, 0), (1, 1), (0, 1)])
    bind(sign, material("sign", (1, 1, 1), 0.5, texture="sign.png"))

    lamp = UsdLux.RectLight.Define(stage, "/World/lamp")
    lamp.CreateWidthAttr(120.0)
    lamp.CreateHeightAttr(60.0)
    lamp.CreateIntensityAttr(6.0)
    lamp.AddTranslateOp().Set(Gf.Vec3d(-60, -80, 260))
    lamp.AddRotateXOp().Set(20.0)
    sun = UsdLux.DistantLight.Define(stage, "/World/sun")
    sun.CreateIntensityAttr(1.2)
    sun.CreateEnableColorTemperatureAttr(True)
    sun.CreateColorTemperatureAttr(4500.0)
    sun.AddRotateXYZOp().Set(Gf.Vec3f(50.0, 0.0, 35.0))
    UsdLux.DomeLight.Define(stage, "/World/sky").CreateColorAttr(Gf.Vec3f(0.12, 0.16, 0.25))

    cam = UsdGeom.Camera.Define(stage, "/World/camera")
    cam.CreateFocalLengthAttr(30.0)
    cam.CreateVerticalApertureAttr(20.0)
    cam.CreateHorizontalApertureAttr(20.0 * 4 / 3)
    eye, target = Gf.Vec3d(40, -330, 150), Gf.Vec3d(20, 20, 35)
    view = Gf.Matrix4d().SetLookAt(eye, target, Gf.Vec3d(0, 0, 1)).GetInverse()
    cam.AddTransformOp().Set(view)
    stage.SetDefaultPrim(stage.GetPrimAtPath("/World"))
    stage.Save()
    package = folder / "scene.usdz"
    with Sdf.ZipFileWriter.CreateNew(str(package)) as zw:
        zw.AddFile(str(path), path.name)
        zw.AddFile(str(folder / "sign.png"), "sign.png")
    return package


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--spp", type=int, default=64)
    args = ap.parse_args()
    out = ROOT / "docs" / "usd_stage.png"
    with tempfile.TemporaryDirectory() as tmp:
        package = write_stage(Path(tmp))
        argv = ["-obj", str(package), "-res", str(args.width), str(args.width * 3 // 4), "-sr", str(args.spp),
                "--camera", "camera", "--tonemap", "srgb", "-out", str(out)]
        print("warp-spt " + " ".join(argv).replace(tmp + "/", "").replace(str(ROOT) + "/", ""))
        log = io.StringIO()
        run(parse_args(argv), stderr=log)
    print("".join(line for line in log.getvalue().splitlines(True) if "warning" in line), end="")
    print(f"wrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
