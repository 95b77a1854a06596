"""Regenerate tests/data/seed_baseline_*.npy: images of the renderer BEFORE the light-transport
restructure (commit 2f89ff6), which the seed integrator with the independent sampler must reproduce
bit for bit (tests/integrators/test_seed_baseline.py).

    git worktree add /tmp/baseline 2f89ff6
    PYTHONPATH=/tmp/baseline /work/venv/bin/python tests/data/make_seed_baseline.py tests/data

Only APIs that exist unchanged at 2f89ff6 are used (render keyword arguments, load_scene, Camera,
the CLI's option parser for the demo's default camera).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from warp_spt import Sky, load_scene, render
from warp_spt.cli.options import parse_args
from warp_spt.demo import demo_files

SPHERES_OBJ = """usemtl glass
b 0 0 0 1
usemtl Inner_CheckerTexture
b 0 0 -101 100
usemtl lamp
b 2 -1 3 0.7
usemtl mirror
b -2.2 0.5 0.2 0.9
"""
SPHERES_MTL = """newmtl glass
Kt 0.9 0.95 1.0
Roughness 0
Kn 1.5
Refractable
newmtl lamp
Kl 6 5 4
newmtl mirror
Kr 0.9 0.9 0.9
Roughness 0.3
Fuzz 0.2
"""


def cases(folder: Path):
    """(name, scene, camera, render keyword arguments) of every baseline image."""
    opts = parse_args([])            # the default demo command: its camera
    demo = load_scene(*demo_files())
    yield "demo", demo, opts.camera, dict(width=32, height=32, spp=4, max_depth=8, sky=Sky.gradient(), seed=0)
    yield "demo_bilinear", demo, opts.camera, dict(width=24, height=20, spp=3, max_depth=5, sky=Sky.black(),
                                                    seed=5, texture_filter="bilinear")
    (folder / "spheres.obj").write_text(SPHERES_OBJ)
    (folder / "spheres.mtl").write_text(SPHERES_MTL)
    from warp_spt import Camera
    cam = Camera(position=(0, -8, 2), direction=(0, 1, -0.2), fov=50.0, aperture=0.1, focus=8.0)
    spheres = load_scene([str(folder / "spheres.obj")], [str(folder / "spheres.mtl")])
    yield "spheres", spheres, cam, dict(width=24, height=24, spp=5, max_depth=6, sky=Sky.pink(), seed=11)


if __name__ == "__main__":
    import tempfile
    out = Path(sys.argv[1])
    with tempfile.TemporaryDirectory() as tmp:
        for name, scene, cam, kw in cases(Path(tmp)):
            img = render(scene, cam, **kw)
            np.save(out / f"seed_baseline_{name}.npy", img)
            print(name, img.shape, float(img.mean()))
