"""A new user's first image of their own model (issue 22): generated models and the checks.

Each model is written by :mod:`tests.support.models` (or here, for the flat cut-out), rendered by a command
with no flags but ``-obj`` (and what the case's ``flags`` add), and judged on three counts, by
code that does not share the renderer's shading:

* **upright**: the model's true up axis points up in the image: it makes less than 45 degrees with
  the camera's image-up direction (cosine >= 0.7; a three-quarter view from 25 degrees above gives
  0.91, a model lying on its back 0.42 or less), and in the image itself, one ray per pixel centre
  (the view checks' ``wp.mesh_query_ray`` probe) finds visible points whose height along that
  axis falls from the top row to the bottom (rank correlation below -0.5);
* **in frame**: the probe's hits cover 10%..85% of the image and none lies on its border;
* **lit**: in the rendered image, the model's pixels (the probe's hits) are not a silhouette: the
  luminance varies across them (coefficient of variation >= 0.15) and their mean is at least a
  fifth of the image's brightest percentile.

The camera judged is the one the command printed ("framed the scene ... -cam ... [--up A]"), or
the seed's default camera when it printed none. ``scripts/first_image_table.py`` runs the same
checks on another commit's command, for the before/after table of the closing note.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import numpy as np

from tests.support.models import write_model

# name: (shape, true up, scale, offset, flags)
MODELS: dict[str, tuple] = {
    "cow, Y up": ("cow", "y", 1.0, (0, 0, 0), []),
    "bunny, Y up": ("bunny", "y", 1.0, (0, 0, 0), []),
    "teapot, Y up": ("teapot", "y", 1.0, (0, 0, 0), []),
    "cow, Y up, tiny and off-centre": ("cow", "y", 1e-3, (1000.0, -20.0, 5.0), []),
    "bunny, Y up, huge": ("bunny", "y", 1e3, (0, 0, 0), []),
    "cow, Y up, half in the default view": ("cow", "y", 10.0, (-5.0, -25.0, 8.0), []),
    "flat cut-out, Y up": ("cutout", "y", 1.0, (0, 0, 0), []),
    "cow, Z up, seed's MTL dialect": ("cow", "z", 1.0, (0, 0, 0), ["seed-mtl"]),
    "bunny, Z up, --up z": ("bunny", "z", 1.0, (0, 0, 0), ["--up", "z"]),
    # issue 31: what exporters and scanners write
    "teapot, Y up, Blender MTL": ("teapot", "y", 1.0, (0, 0, 0), ["blender-mtl"]),
    "bust scan, Z up, flat base, no flags": ("bust", "z", 1.0, (0, 0, 0), []),
    "bust, Y up, flat base": ("bust", "y", 1.0, (0, 0, 0), []),
    "relief plaque, Y up, flat back": ("plaque", "y", 1.0, (0, 0, 0), []),
    "8 egg-shaped balls on a 24-unit floor, Y up": ("spheres_on_floor", "y", 1.0, (0, 0, 0), ["base"]),
    "8 egg-shaped balls on a 24-unit floor, Z up, no flags": ("spheres_on_floor", "z", 1.0, (0, 0, 0), ["base"]),
    # issue 32: a small model far from the origin
    "bunny, Y up, 1.6 units at 1e9": ("bunny", "y", 1.0, (1e9, 2e9, -3e9), []),
}
SEED_LOOK = {"cow, Z up, seed's MTL dialect"}     # not bare: the seed's look (no studio) is kept
DEFAULT_CAM = [4.0, -55.0, 16.0, 0.0, 1.0, 0.0, 38.0, 27.0, 0.001]
SIZE = (96, 72)
LUMA = np.array([0.2126, 0.7152, 0.0722])        # Rec. 709 luminance weights
SEED_MTL = "newmtl hide\nKd 0.7 0.6 0.5\nRoughness 1\n"
# What Blender's OBJ exporter writes for its default material (a colour, no light)
BLENDER_MTL = """# Blender MTL File: 'None'
# Material Count: 1

newmtl Material
Ns 250.000000
Ka 1.000000 1.000000 1.000000
Kd 0.800000 0.300000 0.200000
Ks 0.500000 0.500000 0.500000
Ke 0.000000 0.000000 0.000000
Ni 1.450000
d 1.000000
illum 2
"""
MARKERS = ("seed-mtl", "blender-mtl", "base")     # case notes, not flags of the command


def cutout(path: Path, up: str, scale: float, offset) -> Path:
    """A flat figure (a house outline: a square with a roof) in the plane facing the model's front,
    one triangle fan, 0.4 thick in nothing: every vertex lies in the plane."""
    outline = np.array([[-1, 0], [1, 0], [1, 1.2], [0, 2.0], [-1, 1.2]], dtype=np.float64)
    pts = np.column_stack([outline[:, 0], np.zeros(len(outline)), outline[:, 1]])   # Z up, front -Y
    if up == "y":
        pts = np.column_stack([pts[:, 0], pts[:, 2], -pts[:, 1]])
    pts = pts * scale + np.asarray(offset, dtype=np.float64)
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in pts]
    lines += [f"f 1 {k + 1} {k + 2}" for k in range(1, len(pts) - 1)]
    path.write_text("\n".join(lines) + "\n")
    return path


def write_case(folder: Path, name: str) -> tuple[str, list[str]]:
    """The OBJ file of a case (and an MTL beside it for the seed's dialect) and the command's flags."""
    shape, up, scale, offset, flags = MODELS[name]
    path = folder / (re.sub(r"[^a-z0-9]+", "_", name.lower()).strip("_") + ".obj")
    if shape == "cutout":
        cutout(path, up, scale, offset)
    else:
        write_model(path, shape, up=up, scale=scale, offset=offset)
    if "seed-mtl" in flags:
        (folder / "hide.mtl").write_text(SEED_MTL)
        path.write_text("mtllib hide.mtl\nusemtl hide\n" + path.read_text())
    if "blender-mtl" in flags:
        (folder / "untitled.mtl").write_text(BLENDER_MTL)
        path.write_text("# Blender v2.93 OBJ File: ''\nmtllib untitled.mtl\no Teapot\nusemtl Material\ns off\n"
                        + path.read_text())
    return str(path), [f for f in flags if f not in MARKERS]


@dataclass
class Verdict:
    """What the checks found for one first image."""

    framed: bool
    up: str
    coverage: float
    touches_border: bool
    up_alignment: float        # cosine between the model's up axis and the camera's image-up direction
    height_order: float        # rank correlation of hit height with image row (upright: about -1)
    variation: float           # coefficient of variation of the model's luminance
    brightness: float          # model mean / image 99th percentile luminance

    @property
    def upright(self) -> bool:
        return self.up_alignment >= 0.7 and self.height_order < -0.5

    @property
    def in_frame(self) -> bool:
        return 0.10 <= self.coverage <= 0.85 and not self.touches_border

    @property
    def lit(self) -> bool:
        return self.variation >= 0.15 and self.brightness >= 0.2

    def row(self) -> str:
        mark = lambda ok: "yes" if ok else "NO"
        return (f"{mark(self.upright)} (cos {self.up_alignment:+.2f}) | {mark(self.in_frame)} ({100 * self.coverage:.0f}%"
                f"{', at the border' if self.touches_border else ''}) | {mark(self.lit)} (cv {self.variation:.2f})")


_NUMBER = r"[-+0-9.eE]+"
_CAM = re.compile(rf"framed the scene .*[:;] -cam ((?:{_NUMBER} ){{8}}{_NUMBER})(?: --up[ =](\S+))?")


def printed_camera(said: str, up_default: str):
    """(camera, up axis, framed?) from what a command printed; the seed's camera if it framed nothing."""
    from warp_spt.scene.camera import AXES, Camera

    m = _CAM.search(said)
    values = [float(v) for v in m.group(1).split()] if m else DEFAULT_CAM
    up = (m.group(2) if m and m.group(2) else None) or up_default
    cam = Camera(position=tuple(values[:3]), direction=tuple(values[3:6]), fov=values[6], focus=values[7],
                 aperture=values[8], up=AXES[up])
    return cam, up, bool(m)


def judge(obj: str, true_up: str, image: np.ndarray, said: str, up_default: str, base: bool = False) -> Verdict:
    """The checks of the module docs for the image a command made of ``obj`` and what it printed;
    ``base``: the model stands on a ground, which is not judged (only what stands on it)."""
    from warp_spt.cli.view_checks import probe
    from warp_spt.io.loader import load_scene
    from warp_spt.scene.camera import up_vector
    from warp_spt.scene.recentre import recentre

    camera, up, framed = printed_camera(said, up_default)
    h, w = image.shape[:2]
    scene = load_scene([obj], warn=lambda m: None)
    if base:
        scene = _without_base(scene, true_up)
    scene, camera, _ = recentre(scene, camera)           # as the render: far-off models in float64
    pr = probe(scene, camera, w, h)
    hits = pr.hits
    points = np.asarray(camera.position) + pr.t[..., None] * pr.directions
    rows = np.broadcast_to(np.arange(h)[:, None], (h, w))
    order = _rank_correlation(points[hits] @ up_vector(true_up), rows[hits]) if hits.sum() > 2 else 0.0
    border = bool(hits[0].any() or hits[-1].any() or hits[:, 0].any() or hits[:, -1].any())
    lum = image.astype(np.float64) @ LUMA
    model = lum[hits]
    top = float(np.percentile(lum, 99)) or 1.0
    cv = float(model.std() / model.mean()) if hits.any() and model.mean() > 0 else 0.0
    alignment = float(np.dot(up_vector(true_up), camera.axes()[2]))
    return Verdict(framed, up, float(hits.mean()), border, alignment, order, cv,
                   float(model.mean() / top) if hits.any() else 0.0)


def _without_base(scene, up: str):
    """The scene without its faces in the lowest plane along ``up`` (the ground a model stands on)."""
    from dataclasses import replace

    from warp_spt.scene.camera import up_vector

    u = up_vector(up)
    low = float(np.min(scene.bounds @ u))
    meshes = []
    for m in scene.meshes:
        keep = ~np.all(m.positions.astype(np.float64)[m.indices] @ u <= low + 1e-6, axis=1)
        meshes.append(replace(m, indices=m.indices[keep], corner_uv=m.corner_uv[keep],
                              face_material=m.face_material[keep],
                              corner_normal=None if m.corner_normal is None else m.corner_normal[keep]))
    return replace(scene, meshes=meshes)


def _rank_correlation(a: np.ndarray, b: np.ndarray) -> float:
    ra, rb = np.argsort(np.argsort(a)), np.argsort(np.argsort(b))
    if ra.std() == 0 or rb.std() == 0:
        return 0.0
    return float(np.corrcoef(ra, rb)[0, 1])


def run_case(folder: Path, name: str, render: Callable[[list[str], Path], tuple[np.ndarray, str]],
             up_default: str = "z", extra: tuple[str, ...] = ()) -> Verdict:
    """Write the model, render its first image with ``render(argv, out) -> (linear image, printed)``
    and judge it; ``up_default`` is the axis of a camera the command printed without --up."""
    obj, flags = write_case(folder, name)
    argv = ["-obj", obj, *flags, *extra, "-res", str(SIZE[0]), str(SIZE[1]), "-sr", "16"]
    image, said = render(argv, folder / "first.npy")
    return judge(obj, MODELS[name][1], image, said, up_default, base="base" in MODELS[name][4])
