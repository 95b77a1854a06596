#!/usr/bin/env python3
"""Render one small gallery image per built-in procedural texture: docs/proctex_<name>.png.

    python scripts/make_proctex_gallery.py [--size 128] [--spp 64]

Each image is a diffuse sphere (radius 1) textured with the built-in's default parameters
(``map_Kd proc:NAME``) under the seed's gradient sky. All spheres are in one scene, far apart, so a
single kernel renders every image (one camera per sphere).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import warp  # noqa: E402

from warp_spt.images.files import save_image  # noqa: E402
from warp_spt.io.loader import load_scene  # noqa: E402
from warp_spt.rendering.tiles import render  # noqa: E402
from warp_spt.scene.camera import Camera  # noqa: E402  (after the path set-up, to use this checkout)
from warp_spt.scene.sky import Sky  # noqa: E402

warp.config.log_level = warp.LOG_WARNING

BUILTINS = ("checker", "noise", "marble", "wood", "grid")
SPACING = 10.0


def scene_text() -> tuple[str, str]:
    """OBJ and MTL text: sphere k at x = k * SPACING with material proc_k."""
    obj, mtl = [], []
    for k, name in enumerate(BUILTINS):
        obj += [f"usemtl proc_{name}", f"b {k * SPACING:g} 0 0 1"]
        mtl += [f"newmtl proc_{name}", "Roughness 1", f"map_Kd proc:{name}"]
    return "\n".join(obj) + "\n", "\n".join(mtl) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=64)
    args = ap.parse_args()
    obj, mtl = scene_text()
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "g.obj").write_text(obj)
        (Path(tmp) / "g.mtl").write_text(mtl)
        scene = load_scene([str(Path(tmp) / "g.obj")], [str(Path(tmp) / "g.mtl")])
    for k, name in enumerate(BUILTINS):
        cam = Camera(position=(k * SPACING, -4.0, 1.5), direction=(0.0, 4.0, -1.5), fov=36.0, aperture=0.0,
                     focus=4.3)
        start = time.perf_counter()
        img = render(scene, cam, width=args.size, height=args.size, spp=args.spp, max_depth=4,
                     sky=Sky.gradient())
        out = REPO / "docs" / f"proctex_{name}.png"
        save_image(out, img, tonemap="srgb")
        print(f"{out.relative_to(REPO)}: {args.size}x{args.size}, {args.spp} spp, {time.perf_counter() - start:.1f} s")


if __name__ == "__main__":
    main()
