"""The scene of the environment-map comparison against Mitsuba 3 (tests/emitters/test_envmap.py), for both
renderers: three flat-shaded spheres in a row (a Lambertian grey, rough gold, rough glass: the
materials of tests/support/mitsuba_scenes.py) lit by nothing but the synthetic sun + sky map of
scripts/make_test_envmap.py, Y up. Imports neither renderer."""

from __future__ import annotations

from pathlib import Path

from tests.support import mitsuba_scenes as MS

WIDTH, HEIGHT = 48, 24
MAX_DEPTH = 100                 # as the material comparison (its glass traps rays for many bounces)
MAP_WIDTH = 256
# a broad sun up and to the right, behind the camera's left shoulder: lit sides, shadows between spheres
SUN = dict(sun_elevation=40.0, sun_azimuth=150.0, sun_radius=8.0, sun_radiance=150.0)
CAMERA = dict(position=(0.0, 0.8, 7.5), target=(0.0, 0.0, 0.0), up=(0.0, 1.0, 0.0), fov=48.0)
GREY = (0.6, 0.6, 0.6)
SPHERES = (        # (name, x, our MTL tags, Mitsuba's BSDF)
    ("grey", -2.2, {"Kd": GREY, "Ks": 0, "Pm": 0, "Pr": 1},
     {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(GREY)}}),
    ("gold", 0.0, MS.by_name("gold").mtl, MS.by_name("gold").bsdf),
    ("glass", 2.2, MS.by_name("glass").mtl, MS.by_name("glass").bsdf),
)


def write_files(folder: Path) -> tuple[list[str], list[str]]:
    """The three spheres' OBJ files (each moved to its place) and our MTL: ([objs], [mtl])."""
    folder.mkdir(parents=True, exist_ok=True)
    objs, mtl = [], []
    for name, x, tags, _ in SPHERES:
        lines = []
        for line in MS.sphere_obj().splitlines():
            if line.startswith("v "):
                _, a, b, c = line.split()
                line = f"v {float(a) + x:.9f} {b} {c}"
            elif line.startswith("usemtl"):
                line = f"usemtl {name}"
            lines.append(line)
        p = folder / f"{name}.obj"
        p.write_text("\n".join(lines) + "\n")
        objs.append(str(p))
        body = "\n".join(f"{k} {' '.join(str(v) for v in val)}" if isinstance(val, tuple) else f"{k} {val}"
                         for k, val in tags.items())
        mtl.append(f"newmtl {name}\n{body}\n")
    m = folder / "spheres.mtl"
    m.write_text("\n".join(mtl))
    return objs, [str(m)]
