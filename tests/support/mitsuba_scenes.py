"""The scenes of the comparison against Mitsuba 3 (tests/bsdfs/test_materials_mitsuba.py), for both renderers.

Each scene is one object (a flat-shaded sphere or a flat disc, as OBJ text), a rectangular area light
above and in front of it, off-centre in x so that a mirrored image would be caught, and a constant
grey sky. The same OBJ files are read by warp_spt (with an MTL file of the standard dialect, i.e. the
``pbr`` kind) and by Mitsuba 3 (with a BSDF chosen to match the model, see ``mitsuba_bsdf``).

Why flat shading: with interpolated normals each renderer treats a shading normal that faces away
from the viewer its own way (warp_spt bends it back, Mitsuba does not), which would show at the
silhouette; with face normals the geometry, and so the comparison, is exact. 96 x 48 faces are about
a quarter of a pixel each at the comparison's 32 x 32.

The light faces down and lies above the camera and every object, so nothing sees its back face
(warp_spt's emitting triangles are two-sided, Mitsuba's area lights one-sided).

This module imports neither renderer: ``tests/data/make_mitsuba_material_refs.py`` turns a scene
into Mitsuba's dictionary, the test into warp_spt's files.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

WIDTH = HEIGHT = 32
SKY = 0.25                          # constant sky radiance (grey)
LIGHT = 6.0                         # area light radiance
CAMERA = dict(position=(0.0, -5.0, 0.0), target=(0.0, 0.0, 0.0), up=(0.0, 0.0, 1.0), fov=28.0)
# warp_spt counts surface hits, Mitsuba path vertices (-1: no limit, Russian roulette), so ours gets a
# depth whose cut-off is invisible: a ray entering the glass sphere at a glancing angle meets its
# inner surface just below the critical angle, where it reflects nearly all, and stays trapped for
# many bounces (measured: depth 16 left the sphere's rim 2.5% darker than Mitsuba's, depth 100
# agrees to 0.02% +- 0.04% over the whole image).
MAX_DEPTH = 100

# Gold's F0 in linear sRGB (the glTF 2.0 specification's example value for gold).
GOLD = (1.0, 0.766, 0.336)
SILVER = (0.972, 0.960, 0.915)


@dataclass(frozen=True)
class MitsubaScene:
    """One comparison scene: its object, our MTL tags, and Mitsuba's BSDF (a plugin dictionary)."""

    name: str
    obj: str                         # "sphere" or "disc"
    mtl: dict                        # standard MTL tags of the object's material (warp_spt's side)
    bsdf: dict                       # Mitsuba's BSDF
    note: str = ""


def principled_anisotropic(roughness: float, anisotropy: float) -> tuple[float, float]:
    """Mitsuba's ``principled`` (roughness, anisotropic) giving our alphas: ours are
    alpha_x = mix(r^2, 1, s^2) along the tangent, alpha_y = r^2; Mitsuba's principled has
    alpha_x = r'^2 / aspect, alpha_y = r'^2 aspect with aspect = sqrt(1 - 0.9 anisotropic)."""
    a = roughness**2
    ax, ay = a + (1.0 - a) * anisotropy**2, a
    aspect = math.sqrt(ay / ax)
    return math.sqrt(math.sqrt(ax * ay)), (1.0 - aspect**2) / 0.9


def _principled_metal(color, roughness: float, anisotropy: float = 0.0) -> dict:
    r, an = principled_anisotropic(roughness, anisotropy)
    return {"type": "principled", "base_color": {"type": "rgb", "value": list(color)}, "metallic": 1.0,
            "roughness": r, "anisotropic": an, "specular": 0.5, "spec_tint": 0.0, "spec_trans": 0.0,
            "sheen": 0.0, "clearcoat": 0.0}


PLASTIC = (0.8, 0.25, 0.1)
PLASTIC_ALPHA = 0.4**2
# Mitsuba's roughplastic (linear) is base / pi x T(wo) T(wi) / (eta^2 (1 - R_int)), T the layer's
# transmittance: with its constant a white base under the layer reflects 0.84 of the light at normal
# incidence. Ours (Kulla-Conty's normalisation) conserves energy: a white base reflects all that the
# layer lets through. Scaling Mitsuba's diffuse reflectance by this factor, (1 - E_spec(1)) over its
# white base's diffuse albedo at normal incidence, makes its white base conserve energy too, so the
# test compares the rest: the angular shape and the specular layer. make_mitsuba_material_refs.py
# recomputes it from Mitsuba's own BSDF (--check-plastic) and refuses to render if it is off.
PLASTIC_DIFFUSE_SCALE = 1.199


def _roughplastic(diffuse) -> dict:
    return {"type": "roughplastic", "distribution": "ggx", "alpha": PLASTIC_ALPHA, "int_ior": 1.5, "ext_ior": 1.0,
            "nonlinear": False, "diffuse_reflectance": {"type": "rgb", "value": list(diffuse)}}

SCENES = (
    MitsubaScene(
        "gold", "sphere", {"Kd": GOLD, "Pm": 1, "Pr": 0.3},
        _principled_metal(GOLD, 0.3),
        "Mitsuba principled, metallic 1: Schlick's Fresnel from the base colour as ours; its Smith "
        "masking is separable, ours height-correlated (at alpha 0.09 that changes the albedo by at "
        "most 0.2% down to 78 degrees)"),
    MitsubaScene(
        "glass", "sphere", {"Kd": (1, 1, 1), "Pm": 0, "Pr": 0.3, "Ni": 1.5, "d": 0},
        {"type": "roughdielectric", "distribution": "ggx", "alpha": 0.3**2, "int_ior": 1.5, "ext_ior": 1.0,
         "sample_visible": True},
        "Mitsuba roughdielectric ggx: Walter et al. with the exact Fresnel as ours; separable masking"),
    MitsubaScene(
        "brushed", "disc", {"Kd": SILVER, "Pm": 1, "Pr": 0.4, "aniso": 0.6},
        _principled_metal(SILVER, 0.4, 0.6),
        "Mitsuba principled, metallic 1, anisotropic; alpha_u along dp/du in both renderers"),
    MitsubaScene(
        "plastic", "sphere", {"Kd": PLASTIC, "Pm": 0, "Pr": 0.4, "Ni": 1.5},
        _roughplastic([c * PLASTIC_DIFFUSE_SCALE for c in PLASTIC]),
        "Mitsuba roughplastic ggx (linear), its diffuse reflectance scaled by PLASTIC_DIFFUSE_SCALE: the "
        "same layering as ours, base / pi x T(wo) T(wi) x a constant, where its constant lets a white "
        "base reflect 0.84 at normal incidence, ours 1; exact Fresnel (ours Schlick), separable masking"),
)

# Measured against ours, not compared in the test: a rougher gold, other Mitsuba models of the
# plastic (docs/materials.md, "Against Mitsuba 3").
ALTERNATIVES = (
    MitsubaScene(
        "gold_rough", "sphere", {"Kd": GOLD, "Pm": 1, "Pr": 0.5},
        _principled_metal(GOLD, 0.5),
        "as gold, roughness 0.5: here the separable masking takes up to 2% off the albedo at 78 degrees"),
    MitsubaScene(
        "plastic_principled", "sphere", {"Kd": PLASTIC, "Pm": 0, "Pr": 0.4, "Ni": 1.5},
        {"type": "principled", "base_color": {"type": "rgb", "value": list(PLASTIC)}, "metallic": 0.0,
         "roughness": 0.4, "specular": 0.5, "spec_tint": 0.0, "spec_trans": 0.0, "sheen": 0.0,
         "clearcoat": 0.0},
        "Mitsuba principled, metallic 0: Burley's diffuse with retro-reflection, not Lambert"),
    MitsubaScene(
        "plastic_unscaled", "sphere", {"Kd": PLASTIC, "Pm": 0, "Pr": 0.4, "Ni": 1.5}, _roughplastic(PLASTIC),
        "Mitsuba roughplastic ggx (linear) as it is: a white base reflects 0.84 at normal incidence"),
)


def by_name(name: str) -> MitsubaScene:
    for s in SCENES + ALTERNATIVES:
        if s.name == name:
            return s
    raise KeyError(name)


# ------------------------------------------------------------------------------------ geometry


def sphere_obj(n_phi: int = 96, n_theta: int = 48, radius: float = 1.0) -> str:
    """A UV sphere at the origin, flat-shaded (no normals), outward-facing counter-clockwise triangles;
    u = longitude / 2 pi, v = colatitude / pi."""
    lines = []
    for j in range(n_theta + 1):
        th = math.pi * j / n_theta
        for i in range(n_phi + 1):
            ph = 2.0 * math.pi * i / n_phi
            lines.append(f"v {radius * math.sin(th) * math.cos(ph):.9f} {radius * math.sin(th) * math.sin(ph):.9f} "
                         f"{radius * math.cos(th):.9f}")
            lines.append(f"vt {i / n_phi:.9f} {1.0 - j / n_theta:.9f}")
    lines.append("usemtl m")

    def k(i, j):
        return j * (n_phi + 1) + i + 1

    for j in range(n_theta):
        for i in range(n_phi):
            a, b, c, d = k(i, j), k(i + 1, j), k(i + 1, j + 1), k(i, j + 1)
            # colatitude (j) grows southwards, longitude (i) eastwards: (a, d, b) and (b, d, c) face outwards
            if j != 0:
                lines.append(f"f {a}/{a} {d}/{d} {b}/{b}")
            if j != n_theta - 1:
                lines.append(f"f {b}/{b} {d}/{d} {c}/{c}")
    return "\n".join(lines) + "\n"


DISC_NORMAL = (0.0, -math.sqrt(0.5), math.sqrt(0.5))


def disc_obj(n: int = 64, radius: float = 1.1) -> str:
    """A flat disc at the origin facing the camera and the light (normal (0, -1, 1)/sqrt 2); u grows
    along world x (the tangent, the direction of alpha_x), v along (0, 1, 1)/sqrt 2."""
    eu = np.array([1.0, 0.0, 0.0])
    ev = np.array([0.0, math.sqrt(0.5), math.sqrt(0.5)])
    lines = ["v 0 0 0", "vt 0.5 0.5"]
    for i in range(n):
        t = 2.0 * math.pi * i / n
        x, y = math.cos(t), math.sin(t)
        p = radius * (x * eu + y * ev)
        lines.append(f"v {p[0]:.9f} {p[1]:.9f} {p[2]:.9f}")
        lines.append(f"vt {0.5 + 0.5 * x:.9f} {0.5 + 0.5 * y:.9f}")
    lines.append("usemtl m")
    for i in range(n):
        a, b = i + 2, (i + 1) % n + 2
        lines.append(f"f 1/1 {a}/{a} {b}/{b}")       # eu x ev = the disc's normal: counter-clockwise
    return "\n".join(lines) + "\n"


def light_obj() -> str:
    """The area light: a 1.2 x 0.6 rectangle at height 3, off-centre in x, facing down."""
    x0, x1, y0, y1, z = -0.1, 1.1, -1.1, -0.5, 3.0
    return (f"v {x0} {y0} {z}\nv {x0} {y1} {z}\nv {x1} {y1} {z}\nv {x1} {y0} {z}\n"
            "usemtl light\nf 1 2 3\nf 1 3 4\n")


def geometry(scene: MitsubaScene) -> str:
    return sphere_obj() if scene.obj == "sphere" else disc_obj()


def mtl_text(scene: MitsubaScene) -> str:
    """Our side's MTL (standard dialect: the pbr kind), the object's material and the light's."""
    def tag(k, v):
        return f"{k} {' '.join(str(x) for x in v)}" if isinstance(v, tuple) else f"{k} {v}"

    obj = "\n".join(tag(k, v) for k, v in scene.mtl.items())
    # The light reflects nothing: no base colour and no specular layer (Ks 0).
    return f"newmtl m\n{obj}\n\nnewmtl light\nKd 0 0 0\nKs 0\nKe {LIGHT} {LIGHT} {LIGHT}\n"


def write_files(folder: Path, scene: MitsubaScene) -> tuple[list[str], list[str]]:
    """Write the scene's OBJ and MTL files into ``folder``: ([object, light], [mtl]) paths."""
    folder.mkdir(parents=True, exist_ok=True)
    obj = folder / f"{scene.obj}.obj"
    light = folder / "light.obj"
    mtl = folder / f"{scene.name}.mtl"
    obj.write_text(geometry(scene))
    light.write_text(light_obj())
    mtl.write_text(mtl_text(scene))
    return [str(obj), str(light)], [str(mtl)]
