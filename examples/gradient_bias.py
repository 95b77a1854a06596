"""Discontinuities and the pathwise derivative: where the boundary term is needed, and one it lacks.

    PYTHONPATH=. python examples/gradient_bias.py

Two cases. **Fuzz**, below: a step the gradient does not see. **Camera**: a noise-textured quad under
the gradient sky, seen from 2 units up, the camera moved along its view axis (``camera.position`` z).
A quad larger than the view shows no edge: the pathwise (interior) gradient and finite differences
agree. A smaller quad seen whole against the sky grows in the image as the camera comes down; its
edges move, which finite differences see and the interior term alone (``boundary=False``) does not:
the boundary term of primary visibility (warp_spt.diff.boundary) carries it.

Fuzz:

A glossy quad (Roughness 0, Fuzz 0.3) under the gradient sky, seen at several elevations. The fuzzed
mirror direction ``normalize(r + fuzz * u)`` is absorbed when it points below the quad: a step in
the image for each sample, as a silhouette is for geometry. ``d image / d fuzz`` from
render_gradients (pathwise, continuous part only) is compared with central finite differences of
the expected image (common random numbers, h = 0.02, many samples, which do see the absorbed
fraction change). Looking steeply down, nothing is absorbed and the two agree; towards grazing views
the absorbed fraction grows with fuzz and the gradient misses it.
"""

from __future__ import annotations

import math
import tempfile
from dataclasses import replace
from pathlib import Path

import numpy as np

import warp_spt
from warp_spt.diff.gradients import render_gradients
from warp_spt.diff.params import parameters
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene


def glossy_quad(folder: Path):
    (folder / "q.mtl").write_text("newmtl q\nKd 0.9 0.9 0.9\nRoughness 0\nFuzz 0.3\n")
    (folder / "q.obj").write_text("mtllib q.mtl\nv -50 -50 0\nv 50 -50 0\nv 50 50 0\nv -50 50 0\n"
                                  "usemtl q\nf 1 2 3\nf 1 3 4\n")
    return warp_spt.load_scene([str(folder / "q.obj")], [str(folder / "q.mtl")])


def compare(elevation_deg: float, size: int = 8, spp: int = 512, h: float = 0.02) -> tuple[float, float]:
    """(gradient, finite difference) of the image sum in fuzz, the camera looking down at this angle."""
    with tempfile.TemporaryDirectory() as tmp:
        scene = glossy_quad(Path(tmp))
    e = math.radians(elevation_deg)
    cam = warp_spt.Camera(position=(0.0, -2.0 * math.cos(e), 2.0 * math.sin(e)),
                          direction=(0.0, math.cos(e), -math.sin(e)), fov=10.0, aperture=0.0, focus=2.0)
    params = parameters(scene, cam, warp_spt.Sky.gradient())
    rs = RenderSettings(width=size, height=size, spp=spp, max_depth=2, sky=params.sky, integrator="seed")
    g = float(render_gradients(params, rs, adjoint=np.ones((size, size, 3)), wrt=["q.fuzz"]).grads["q.fuzz"])
    sums = []
    for s in (h, -h):
        params["q.fuzz"] = 0.3 + s
        sums.append(float(render_scene(params.scene, params.camera, replace(rs, sky=params.sky)).image
                          .astype(np.float64).sum()))
    params["q.fuzz"] = 0.3
    return g, (sums[0] - sums[1]) / (2 * h)


NOISE_MTL = ("newmtl quad\nKd 1 1 1\nmap_Kd proc:noise scale=1.5 color1=0.1,0.2,0.3 color2=0.9,0.8,0.6\n"
             "Roughness 0.5\nFuzz 0.2\n")


def noise_quad(folder: Path, half: float):
    (folder / "n.mtl").write_text(NOISE_MTL)
    corners = [(-half, -half), (half, -half), (half, half), (-half, half)]
    (folder / "n.obj").write_text("mtllib n.mtl\n" + "".join(f"v {x} {y} 0\n" for x, y in corners)
                                  + "usemtl quad\nf 1 2 3\nf 1 3 4\n")
    return warp_spt.load_scene([str(folder / "n.obj")], [str(folder / "n.mtl")])


def camera_compare(half: float, size: int = 8, spp: int = 256, seeds: int = 4, h: float = 0.02):
    """(gradient, interior term alone, finite difference, standard error of gradient - FD) of the image
    sum in the camera's height, over ``seeds`` seeds: central FD with step h, common random numbers."""
    with tempfile.TemporaryDirectory() as tmp:
        scene = noise_quad(Path(tmp), half)
    cam = warp_spt.Camera(position=(0.1, -0.2, 2.0), direction=(0.05, 0.1, -1.0), fov=60.0, aperture=0.0,
                          focus=2.0, up=(0.0, 1.0, 0.0))
    params = parameters(scene, cam, warp_spt.Sky.gradient(zenith=(0.4, 0.6, 1.0), nadir=(0.9, 0.8, 0.7)))
    g, g0, fd = [], [], []
    for seed in range(seeds):
        rs = RenderSettings(width=size, height=size, spp=spp, max_depth=2, seed=seed, sky=params.sky,
                            integrator="seed")
        r = render_gradients(params, rs, adjoint=np.ones((size, size, 3)), wrt=["camera.position"])
        g.append(float(r.grads["camera.position"][2]))
        r0 = render_gradients(params, rs, adjoint=np.ones((size, size, 3)), wrt=["camera.position"], boundary=False)
        g0.append(float(r0.grads["camera.position"][2]))
        sums = []
        for s in (h, -h):
            params["camera.position"] = np.add(cam.position, (0.0, 0.0, s))
            sums.append(float(render_scene(params.scene, params.camera, rs).image.astype(np.float64).sum()))
        params["camera.position"] = cam.position
        fd.append((sums[0] - sums[1]) / (2 * h))
    se = math.sqrt(np.var(g, ddof=1) / seeds + np.var(fd, ddof=1) / seeds)
    return float(np.mean(g)), float(np.mean(g0)), float(np.mean(fd)), se


def main() -> None:
    print("elevation  gradient  finite difference  (image sum, d/d fuzz)")
    for elev in (80, 45, 25, 12, 6):
        g, fd = compare(elev)
        print(f"{elev:7d}°  {g:9.3f}  {fd:9.3f}")
    print("\nquad half-size  edges in view  gradient  interior only  finite difference  std. error  "
          "(image sum, d/d camera z)")
    for half in (2.0, 1.0, 0.5):
        g, g0, fd, se = camera_compare(half)
        print(f"{half:14.1f}  {'no' if half > 1.2 else 'yes':>13}  {g:8.3f}  {g0:13.3f}  {fd:17.3f}  {se:10.3f}")


if __name__ == "__main__":
    main()
