"""What procedural textures cost: render time of one scene whose floor and spheres take their colour
from a constant, the seed's built-in checker, or each procedural built-in (proc:NAME), and the kernel
compile (or cache load) time of each variant.

    python benchmarks/bench_proctex.py            # 256x256, 16 spp, depth 6
    python benchmarks/bench_proctex.py --quick    # 96x96, 4 spp

Times are medians of 3 renders after a warm-up; compare the ratios within one run.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING   # no banner or module-load lines (Warp 1.19 dropped config.quiet)

from warp_spt.upload.device_scene import DeviceScene  # noqa: E402
from warp_spt.emitters import declare_sky  # noqa: E402
from warp_spt.integrators import get_kernel  # noqa: E402
from warp_spt.io.loader import load_scene  # noqa: E402
from warp_spt.rendering.settings import RenderSettings  # noqa: E402
from warp_spt.rendering.tiles import render_scene  # noqa: E402
from warp_spt.scene.camera import Camera  # noqa: E402
from warp_spt.scene.sky import Sky  # noqa: E402

VARIANTS = {"constant": "Kd 0.6 0.5 0.4", "seed checker (built-in material)": None}
VARIANTS.update({f"proc:{n}": f"map_Kd proc:{n}" for n in ("checker", "noise", "marble", "wood", "grid")})
OBJ = """v -20 -20 -1
v 20 -20 -1
v 20 20 -1
v -20 20 -1
vt 0 0
vt 1 0
vt 1 1
vt 0 1
usemtl {m}
f 1/1 2/2 3/3
f 1/1 3/3 4/4
b -2.2 0 0 1
b 0 0 0 1
b 2.2 0 0 1
usemtl lamp
b 0 -3 8 2
"""


def scene_for(tmp: Path, name: str, statement: str | None) -> DeviceScene:
    material = "Inner_CheckerTexture" if statement is None else "m"
    (tmp / "s.obj").write_text(OBJ.format(m=material))
    (tmp / "s.mtl").write_text(f"newmtl m\nRoughness 0.9\n{statement or ''}\nnewmtl lamp\nKl 6 6 6\nKd 0 0 0\n")
    return DeviceScene(load_scene([str(tmp / "s.obj")], [str(tmp / "s.mtl")]))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    size, spp = (96, 4) if args.quick else (256, 16)
    settings = RenderSettings(width=size, height=size, spp=spp, max_depth=6, sky=Sky.gradient())
    camera = Camera(position=(0.0, -9.0, 2.5), direction=(0.0, 1.0, -0.25), fov=45.0, aperture=0.0, focus=9.0)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name, statement in VARIANTS.items():
            dev = scene_for(Path(tmp), name, statement)
            start = time.perf_counter()
            get_kernel(dev.features.with_lights(declare_sky(settings.sky)))
            load = time.perf_counter() - start
            render_scene(dev, camera, settings)
            times = [render_scene(dev, camera, settings).stats.seconds for _ in range(3)]
            rows.append((name, load, statistics.median(times)))
    base = rows[0][2]
    print(f"{size}x{size}, {spp} spp, depth 6, all threads")
    print(f"{'colour source':34s} {'compile/load s':>14s} {'render s':>9s} {'vs constant':>11s}")
    for name, load, t in rows:
        print(f"{name:34s} {load:14.2f} {t:9.3f} {t / base:10.2f}x")


if __name__ == "__main__":
    main()
