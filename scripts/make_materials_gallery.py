"""The pbr material kind's gallery (docs/materials_gallery.png) and the side-by-side against Mitsuba 3
(docs/materials_vs_mitsuba.png).

    PYTHONPATH=$PWD python scripts/make_materials_gallery.py            # both figures (a few minutes)
    PYTHONPATH=$PWD python scripts/make_materials_gallery.py --quick    # small and noisy: a smoke run
    PYTHONPATH=$PWD python scripts/make_materials_gallery.py --only gallery   # or: mitsuba

Gallery panels, each one scene written here as OBJ/MTL text of the standard dialect (so every
material is of the ``pbr`` kind), under a gradient sky and an area light:

1. metallic (rows 0, 0.5, 1) x roughness (columns 0 to 1), a copper-coloured base;
2. rough glass: roughness 0, 0.1, 0.25 and 0.5 in front of a checker board;
3. anisotropy: a brushed metal sphere (uv sphere, tangent along the longitude) at anisotropy 0,
   0.5, 0.8, and 0.8 turned a quarter turn (``anisor 0.25``);
4. a normal map (tangent space, generated here: a grid of rounded studs) on a plastic and a metal
   tile, and, once the loader honours ``map_d``, a cut-out (a leaf-like mask generated here) casting
   its shadow on the ground (until then the panel says so and leaves it out).

The Mitsuba figure renders our side of the scenes of tests/bsdfs/test_materials_mitsuba.py (compensation
off, as there) and puts it beside Mitsuba's stored mean image (tests/data/mitsuba_material_refs.npz,
made by tests/data/make_mitsuba_material_refs.py), with the difference.
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING

from warp_spt.upload.device_scene import DeviceScene  # noqa: E402
from warp_spt.device.structs import Features  # noqa: E402
from warp_spt.images.files import tonemap_srgb  # noqa: E402
from warp_spt.io.loader import load_scene  # noqa: E402
from warp_spt.rendering import tiles as R  # noqa: E402
from warp_spt.rendering.settings import RenderSettings  # noqa: E402
from warp_spt.scene.camera import Camera  # noqa: E402
from warp_spt.scene.sky import Sky  # noqa: E402

DOCS = REPO / "docs"
LIGHT = "newmtl light\nKd 0 0 0\nKs 0\nKe 5 5 5\n"
SKY = Sky.gradient(zenith=(0.35, 0.5, 0.8), nadir=(0.75, 0.75, 0.75))


def union(features: list[Features]) -> Features:
    """One feature set for every panel: one kernel compile."""
    out = {}
    for f in dataclasses.fields(Features):
        values = [getattr(x, f.name) for x in features]
        if isinstance(values[0], bool):
            out[f.name] = any(values)
        elif f.name == "lobes":
            out[f.name] = int(np.bitwise_or.reduce(values))
        elif f.name == "bvh_stack":
            out[f.name] = max(values)
        elif f.name == "material_kinds":
            kinds = set().union(*values)
            out[f.name] = tuple(k for k in Features().material_kinds if k in kinds)
        else:
            out[f.name] = tuple(sorted(set().union(*values)))
    return dataclasses.replace(features[0], **out)


# ----------------------------------------------------------------------------- geometry (OBJ text)


class Obj:
    """OBJ text built up from parts, with running vertex indices."""

    def __init__(self):
        self.lines: list[str] = []
        self.nv = self.nt = self.nn = 0

    def quad(self, corners, material: str, uv_scale: float = 1.0) -> "Obj":
        self.lines.append(f"usemtl {material}")
        for p in corners:
            self.lines.append("v {} {} {}".format(*p))
        for u, v in ((0, 0), (1, 0), (1, 1), (0, 1)):
            self.lines.append(f"vt {u * uv_scale} {v * uv_scale}")
        a = self.nv
        t = self.nt
        self.lines.append(f"f {a + 1}/{t + 1} {a + 2}/{t + 2} {a + 3}/{t + 3}")
        self.lines.append(f"f {a + 1}/{t + 1} {a + 3}/{t + 3} {a + 4}/{t + 4}")
        self.nv += 4
        self.nt += 4
        return self

    def ball(self, centre, radius: float, material: str) -> "Obj":
        """An analytic sphere (the ``b`` statement)."""
        self.lines.append(f"usemtl {material}\nb {centre[0]} {centre[1]} {centre[2]} {radius}")
        return self

    def uv_sphere(self, centre, radius: float, material: str, n_phi: int = 64, n_theta: int = 32) -> "Obj":
        """A smooth uv sphere about z: u along the longitude (the anisotropy's tangent), v the colatitude."""
        self.lines.append(f"usemtl {material}")
        base_v, base_t, base_n = self.nv, self.nt, self.nn
        for j in range(n_theta + 1):
            th = math.pi * j / n_theta
            for i in range(n_phi + 1):
                ph = 2.0 * math.pi * i / n_phi
                n = (math.sin(th) * math.cos(ph), math.sin(th) * math.sin(ph), math.cos(th))
                self.lines.append("v {} {} {}".format(*(c + radius * d for c, d in zip(centre, n))))
                self.lines.append(f"vt {i / n_phi} {1.0 - j / n_theta}")
                self.lines.append("vn {} {} {}".format(*n))
        self.nv += (n_theta + 1) * (n_phi + 1)
        self.nt += (n_theta + 1) * (n_phi + 1)
        self.nn += (n_theta + 1) * (n_phi + 1)

        def k(i, j):
            return j * (n_phi + 1) + i + 1

        def corner(x):
            return f"{base_v + x}/{base_t + x}/{base_n + x}"

        for j in range(n_theta):
            for i in range(n_phi):
                a, b, c, d = k(i, j), k(i + 1, j), k(i + 1, j + 1), k(i, j + 1)
                if j != 0:
                    self.lines.append(f"f {corner(a)} {corner(d)} {corner(b)}")
                if j != n_theta - 1:
                    self.lines.append(f"f {corner(b)} {corner(d)} {corner(c)}")
        return self

    def text(self) -> str:
        return "\n".join(self.lines) + "\n"


def ground(obj: Obj, z: float, half: float = 30.0, material: str = "ground") -> Obj:
    return obj.quad([(-half, -half, z), (half, -half, z), (half, half, z), (-half, half, z)], material)


def light(obj: Obj, centre, size: float) -> Obj:
    """An area light facing down."""
    x, y, z = centre
    h = size / 2
    return obj.quad([(x - h, y - h, z), (x - h, y + h, z), (x + h, y + h, z), (x + h, y - h, z)], "light")


# ----------------------------------------------------------------------------- textures


def write_checker(path: Path, n: int = 8, px: int = 32) -> None:
    cells = (np.add.outer(np.arange(n * px) // px, np.arange(n * px) // px) % 2).astype(np.float64)
    img = 0.15 + 0.7 * cells
    Image.fromarray((np.stack([img] * 3, -1) * 255).astype(np.uint8)).save(path)


def write_stud_normal_map(path: Path, studs: int = 6, px: int = 48) -> None:
    """A tangent-space normal map of a grid of rounded studs: the normal of a height field of
    spherical caps, encoded as (n + 1) / 2 (x along u, y along v: MikkTSpace / OpenGL)."""
    size = studs * px
    y, x = np.mgrid[0:size, 0:size] + 0.5
    cx = (x % px) / px - 0.5
    cy = 0.5 - (y % px) / px                 # image rows go down, v goes up
    r2 = cx * cx + cy * cy
    rad = 0.38
    inside = r2 < rad * rad
    h = np.sqrt(np.maximum(rad * rad - r2, 1e-9))
    nx = np.where(inside, cx / h, 0.0) * 0.8
    ny = np.where(inside, cy / h, 0.0) * 0.8
    n = np.stack([nx, ny, np.ones_like(nx)], -1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)
    Image.fromarray(((n + 1) * 0.5 * 255 + 0.5).astype(np.uint8)).save(path)


def write_leaf_mask(path: Path, px: int = 256) -> None:
    """An RGBA texture whose alpha is a leaf shape with holes (the cut-out), green in colour."""
    y, x = (np.mgrid[0:px, 0:px] + 0.5) / px
    u, v = x - 0.5, 0.5 - y
    leaf = (u / 0.28) ** 2 + (v / 0.45) ** 2 < 1.0 - 0.25 * np.cos(10 * math.atan2(1, 1) * v)
    holes = ((np.hypot(u - 0.08, v - 0.12) < 0.06) | (np.hypot(u + 0.07, v + 0.1) < 0.05)
             | (np.abs(u) < 0.008))
    alpha = (leaf & ~holes).astype(np.uint8) * 255
    rgb = np.zeros((px, px, 3), np.uint8)
    rgb[..., 0], rgb[..., 1], rgb[..., 2] = 60, 150, 50
    Image.fromarray(np.dstack([rgb, alpha]), "RGBA").save(path)


# ----------------------------------------------------------------------------- panels


@dataclasses.dataclass
class Panel:
    title: str
    obj: str
    mtl: str
    camera: Camera
    aspect: float                      # width / height
    labels: tuple[str, ...] = ()       # evenly spaced along the bottom


def panel_grid() -> Panel:
    rough = (0.0, 0.25, 0.5, 0.75, 1.0)
    metal = (1.0, 0.5, 0.0)
    o = Obj()
    mtl = [LIGHT, "newmtl ground\nKd 0.5 0.5 0.5\nPr 0.8\n"]
    for i, r in enumerate(rough):
        for j, m in enumerate(metal):
            name = f"m{i}{j}"
            mtl.append(f"newmtl {name}\nKd 0.95 0.64 0.54\nPm {m}\nPr {r}\n")
            o.ball(((i - 2) * 1.1, 0.0, 1.1 * (2 - j) + 0.5), 0.5, name)
    ground(o, 0.0)
    light(o, (-2.0, -4.0, 6.0), 4.0)
    cam = Camera.look_at((0, -9.5, 2.7), (0, 0, 1.6), fov=40.0)
    return Panel("metallic 1 / 0.5 / 0 (rows) x roughness", o.text(), "\n".join(mtl), cam, 5.8 / 3.6,
                 tuple(f"roughness {r:g}" for r in rough))


def panel_glass(folder: Path) -> Panel:
    write_checker(folder / "checker.png")
    rough = (0.0, 0.1, 0.25, 0.5)
    o = Obj()
    mtl = [LIGHT, "newmtl ground\nKd 0.5 0.5 0.5\nPr 0.8\n", "newmtl board\nKd 1 1 1\nPr 1\nmap_Kd checker.png\n"]
    for i, r in enumerate(rough):
        mtl.append(f"newmtl g{i}\nKd 1 1 1\nPr {r}\nd 0\nNi 1.5\n")
        o.ball(((i - 1.5) * 1.25, 0.0, 0.55), 0.55, f"g{i}")
    ground(o, 0.0)
    o.quad([(-4, 1.6, 0), (4, 1.6, 0), (4, 1.6, 3), (-4, 1.6, 3)], "board", uv_scale=1.0)
    light(o, (1.5, -4.0, 6.0), 4.0)
    cam = Camera.look_at((0, -7, 1.6), (0, 0, 0.7), fov=45.0)
    return Panel("rough glass (index 1.5)", o.text(), "\n".join(mtl), cam, 2.4,
                 tuple(f"roughness {r:g}" for r in rough))


def panel_aniso() -> Panel:
    cases = ((0.0, 0.0), (0.5, 0.0), (0.8, 0.0), (0.8, 0.25))
    o = Obj()
    mtl = [LIGHT, "newmtl ground\nKd 0.5 0.5 0.5\nPr 0.8\n"]
    for i, (a, rot) in enumerate(cases):
        mtl.append(f"newmtl a{i}\nKd 0.95 0.93 0.88\nPm 1\nPr 0.3\naniso {a}\nanisor {rot}\n")
        o.uv_sphere(((i - 1.5) * 1.25, 0.0, 0.55), 0.55, f"a{i}")
    ground(o, 0.0)
    light(o, (0.0, -3.0, 5.0), 2.0)
    light(o, (-3.0, -2.0, 4.0), 1.2)
    cam = Camera.look_at((0, -7, 1.6), (0, 0, 0.6), fov=45.0)
    return Panel("anisotropy (brushed metal, roughness 0.3)", o.text(), "\n".join(mtl), cam, 2.4,
                 ("anisotropy 0", "0.5", "0.8", "0.8, turned 90 deg"))


def panel_maps(folder: Path, cutout: bool) -> Panel:
    """The normal-mapped tiles, and the cut-out leaf where ``cutout`` (map_d is honoured)."""
    write_stud_normal_map(folder / "studs.png")
    write_leaf_mask(folder / "leaf.png")
    o = Obj()
    mtl = [LIGHT, "newmtl ground\nKd 0.5 0.5 0.5\nPr 0.8\n",
           "newmtl plastic\nKd 0.2 0.35 0.8\nPr 0.35\nnorm studs.png\n",
           "newmtl metal\nKd 0.95 0.64 0.54\nPm 1\nPr 0.3\nnorm studs.png\n",
           "newmtl leaf\nKd 1 1 1\nmap_Kd leaf.png\nmap_d leaf.png\nPr 0.6\n"]
    s = 1.1
    o.quad([(-3.4, 0, 0.2), (-3.4 + 2 * s, 0, 0.2), (-3.4 + 2 * s, 0.0, 0.2 + 2 * s), (-3.4, 0.0, 0.2 + 2 * s)],
           "plastic")
    o.quad([(-1.0, 0, 0.2), (-1.0 + 2 * s, 0, 0.2), (-1.0 + 2 * s, 0.0, 0.2 + 2 * s), (-1.0, 0.0, 0.2 + 2 * s)],
           "metal")
    if cutout:
        o.quad([(1.5, -0.6, 0.6), (3.5, -0.6, 0.6), (3.5, -0.6, 2.6), (1.5, -0.6, 2.6)], "leaf")
    ground(o, 0.0)
    light(o, (2.0, -4.5, 4.5), 2.0)
    light(o, (-2.0, -4.0, 5.0), 2.5)
    if cutout:
        cam = Camera.look_at((0, -8, 2.0), (0, 0, 1.2), fov=48.0)
        return Panel("normal map (plastic, metal) and cut-out (map_d)", o.text(), "\n".join(mtl), cam, 2.4,
                     ("normal map, plastic", "normal map, metal", "cut-out and its shadow"))
    cam = Camera.look_at((-1.15, -6.5, 1.6), (-1.15, 0, 1.3), fov=40.0)
    return Panel("normal map (tangent space, generated)", o.text(), "\n".join(mtl), cam, 2.4,
                 ("plastic", "metal"))


def cutouts_supported(folder: Path) -> bool:
    """Whether the loader honours map_d (a scene with it asks for the cut-out code path)."""
    write_leaf_mask(folder / "leaf.png")
    o = Obj().quad([(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)], "leaf")
    dev = load(folder, "probe", Panel("", o.text(), "newmtl leaf\nKd 1 1 1\nmap_d leaf.png\n", Camera(), 1.0))
    return "cutout" in dev.features.material_flags


def load(folder: Path, name: str, panel: Panel) -> DeviceScene:
    (folder / f"{name}.obj").write_text(panel.obj)
    (folder / f"{name}.mtl").write_text(panel.mtl)
    return DeviceScene(load_scene([str(folder / f"{name}.obj")], [str(folder / f"{name}.mtl")]))


def caption(img: np.ndarray, title: str, labels: tuple[str, ...]) -> Image.Image:
    """An 8-bit panel with its title above and labels below."""
    im = Image.fromarray(img)
    w, h = im.size
    out = Image.new("RGB", (w, h + 34), (255, 255, 255))
    out.paste(im, (0, 18))
    d = ImageDraw.Draw(out)
    d.text((4, 3), title, fill=(0, 0, 0))
    for i, lab in enumerate(labels):
        x = int((i + 0.5) * w / len(labels))
        d.text((x - 3 * len(lab), h + 20), lab, fill=(0, 0, 0))
    return out


def gallery(width: int, spp: int, out: Path) -> None:
    folder = Path(tempfile.mkdtemp())
    cutout = cutouts_supported(folder)
    if not cutout:
        print("  map_d cut-outs are not honoured yet: the cut-out is left out")
    panels = [panel_grid(), panel_glass(folder), panel_aniso(), panel_maps(folder, cutout)]
    devs = [load(folder, f"p{i}", p) for i, p in enumerate(panels)]
    features = union([d.features for d in devs])
    images = []
    for p, dev in zip(panels, devs):
        t = time.perf_counter()
        h = int(round(width / p.aspect))
        res = R.render_scene(dev, p.camera, RenderSettings(width=width, height=h, spp=spp, max_depth=8, seed=1,
                                                           sky=SKY, integrator="nee", features=features))
        images.append(caption(tonemap_srgb(res.image), p.title, p.labels))
        print(f"  {p.title}: {width}x{h}, {spp} spp, {time.perf_counter() - t:.0f} s", flush=True)
    total = Image.new("RGB", (width, sum(im.size[1] for im in images)), (255, 255, 255))
    y = 0
    for im in images:
        total.paste(im, (0, y))
        y += im.size[1]
    total.save(out)
    print(f"wrote {out}")


def versus_mitsuba(spp: int, scale: int, out: Path) -> None:
    from tests.support import mitsuba_scenes as MS
    from tests.bsdfs.test_materials_mitsuba import REFS, camera, load_ours

    if not REFS.exists():
        raise SystemExit(f"{REFS} is absent: run tests/data/make_mitsuba_material_refs.py first")
    refs = np.load(REFS)
    folder = Path(tempfile.mkdtemp())
    devs = [load_ours(folder, s) for s in MS.SCENES]
    features = union([d.features for d in devs])
    rows = []
    for s, dev in zip(MS.SCENES, devs):
        integrator = "seed" if s.name == "glass" else "nee"     # docs/materials.md: nee and rough glass
        res = R.render_scene(dev, camera(), RenderSettings(
            width=MS.WIDTH, height=MS.HEIGHT, spp=spp, max_depth=MS.MAX_DEPTH, seed=11, integrator=integrator,
            sky=Sky.constant(MS.SKY, MS.SKY, MS.SKY), features=features))
        ours, theirs = res.image.astype(np.float64), refs[f"{s.name}_mean"].astype(np.float64)
        diff = (ours - theirs).mean(-1) / max(theirs.mean(), 1e-6)
        d = np.clip(diff / 0.1, -1, 1)                          # +-10% of the image mean: full colour
        heat = np.stack([np.maximum(d, 0), np.zeros_like(d), np.maximum(-d, 0)], -1)
        heat = (255 * (1 - 0.85 * np.abs(d)[..., None]) + 255 * 0.85 * heat).clip(0, 255).astype(np.uint8)
        tiles = [tonemap_srgb(theirs), tonemap_srgb(ours), heat]
        big = [np.kron(t, np.ones((scale, scale, 1), np.uint8)) for t in tiles]
        rows.append((s.name, big))
    w = MS.WIDTH * scale
    gap = 6
    canvas = Image.new("RGB", (3 * w + 2 * gap + 70, len(rows) * (w + gap) + 18), (255, 255, 255))
    d = ImageDraw.Draw(canvas)
    for k, t in enumerate(("Mitsuba 3", "warp_spt", "difference (+-10%)")):
        d.text((70 + k * (w + gap) + 4, 3), t, fill=(0, 0, 0))
    for r, (name, big) in enumerate(rows):
        y = 18 + r * (w + gap)
        d.text((4, y + w // 2), name, fill=(0, 0, 0))
        for k, b in enumerate(big):
            canvas.paste(Image.fromarray(b), (70 + k * (w + gap), y))
    canvas.save(out)
    print(f"wrote {out}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="small and noisy")
    ap.add_argument("--only", choices=("gallery", "mitsuba"))
    ap.add_argument("--out-dir", type=Path, default=DOCS)
    a = ap.parse_args()
    t = time.perf_counter()
    if a.only in (None, "gallery"):
        gallery(160 if a.quick else 480, 4 if a.quick else 256, a.out_dir / "materials_gallery.png")
    if a.only in (None, "mitsuba"):
        versus_mitsuba(16 if a.quick else 4096, 6, a.out_dir / "materials_vs_mitsuba.png")
    print(f"{time.perf_counter() - t:.0f} s")


if __name__ == "__main__":
    main()
