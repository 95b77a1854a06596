"""Inverse lighting with warp_spt: recover an environment's tint and the sun's direction from an image.

    python examples/inverse_lighting.py            (PYTHONPATH=. python ... from a checkout not installed)
    python examples/inverse_lighting.py --quick    (smaller, fewer iterations: what tests/ runs)

A grey ball is lit by a sky (an environment map: blue above, brown below the horizon) times an
unknown RGB tint, and by a sun of known irradiance from an unknown direction. The sky is hidden from
the camera (``background``): both must be read from the ball's shading. (Nothing casts a shadow on
what the camera sees: a moving shadow's edge is a visibility discontinuity, whose derivative the
tape does not hold; with a floor under the ball, the sun converged some 10 degrees off.) A target
image is rendered with the true values (more samples, another seed); the optimisation starts from
a white tint and a sun straight overhead and runs Adam on the L2 loss with a fresh seed per
iteration (and another for the gradient: an unbiased gradient of the expected loss).

The tint is not a parameter of its own: the map is ``base x tint``, so the tint's gradient is the
map's, ``environment.texels``, summed against the base map per channel (the chain rule). The sun's
direction is ``sun.direction``, differentiated by the tape (it moves the sampled direction), which
then differentiates the texels too. The reported values are the means of the last quarter of the
iterates.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

import warp_spt as ws
from warp_spt import SunLight
from warp_spt.losses import l2
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

TRUE_TINT = np.array([1.0, 0.7, 0.45])
TRUE_SUN = np.array([0.6, -0.5, 0.62]) / np.linalg.norm([0.6, -0.5, 0.62])
SUN_COLOR = (3.0, 3.0, 3.0)
CAMERA = Camera(position=(0.0, -4.0, 0.8), direction=(0.0, 4.0, -0.8), fov=34.0, up=(0.0, 0.0, 1.0))


def base_map(height: int = 16) -> np.ndarray:
    """(H, 2H, 3) a sky: blue brightening towards the zenith above the horizon, brown below."""
    theta = np.pi * (np.arange(height) + 0.5) / height
    up = np.cos(theta)[:, None, None]
    sky = np.array([0.35, 0.55, 1.0]) * (0.4 + 0.6 * np.clip(up, 0, 1))
    ground = np.array([0.3, 0.24, 0.18]) * np.ones_like(up)
    img = np.where(up > 0, sky, ground) * np.ones((1, 2 * height, 1))
    return img.astype(np.float32)


def scene(folder: Path):
    (folder / "s.obj").write_text("usemtl grey\nb 0 0 0 1\n")
    (folder / "s.mtl").write_text("newmtl grey\nKd 0.8 0.8 0.8\nRoughness 1\n")
    return ws.load_scene([str(folder / "s.obj")], [str(folder / "s.mtl")])


@dataclass
class Result:
    tint: np.ndarray
    sun: np.ndarray
    losses: list[float]
    tint_tail_std: np.ndarray          # the spread of the averaged iterates (their noise)
    sun_tail_std_deg: float
    seconds_per_iteration: float

    @property
    def sun_error_deg(self) -> float:
        return float(np.degrees(np.arccos(np.clip(self.sun @ TRUE_SUN, -1, 1))))


def recover(quick: bool = False, seed: int = 0) -> Result:
    size, spp, iterations = (16, 8, 100) if quick else (32, 16, 150)
    base = base_map()
    with tempfile.TemporaryDirectory() as tmp:
        sc = scene(Path(tmp))
    sc.add_light(SunLight(direction=tuple(TRUE_SUN), color=SUN_COLOR, name="sun"))
    sky = Sky.environment(base * TRUE_TINT.astype(np.float32), up=(0, 0, 1), background=(0.0, 0.0, 0.0))
    params = ws.parameters(sc, CAMERA, sky)
    rs = ws.RenderSettings(width=size, height=size, spp=spp, max_depth=2, integrator="nee", tile_pixels=size * size)
    target = ws.render_scene(params.scene, CAMERA, replace(rs, sky=params.sky, spp=16 * spp, seed=10_000 + seed)).image

    # Adam over (tint, sun direction); the direction is renormalised after each step
    x = np.concatenate([np.ones(3), [0.0, 0.0, 1.0]])
    m, v = np.zeros(6), np.zeros(6)
    lr, b1, b2 = 0.1, 0.9, 0.999
    losses, tail = [], []
    t0 = time.perf_counter()
    for it in range(iterations):
        params["environment.texels"] = base * x[:3].astype(np.float32)
        params["sun.direction"] = x[3:]
        r = ws.render_gradients(params, replace(rs, seed=1000 * seed + 2 * it), loss=l2(target),
                                wrt=["environment.texels", "sun.direction"], gradient_seed=1000 * seed + 2 * it + 1)
        losses.append(float(r.loss))
        g = np.concatenate([np.einsum("hwc,hwc->c", r.grads["environment.texels"], base), r.grads["sun.direction"]])
        m = b1 * m + (1 - b1) * g
        v = b2 * v + (1 - b2) * g * g
        x = x - lr * (m / (1 - b1 ** (it + 1))) / (np.sqrt(v / (1 - b2 ** (it + 1))) + 1e-12)
        x[:3] = np.maximum(x[:3], 1e-3)
        x[3:] /= np.linalg.norm(x[3:])
        lr *= 0.97
        if it >= iterations - iterations // 4:
            tail.append(x.copy())
    tail = np.array(tail)
    sun = tail[:, 3:].mean(axis=0)
    sun /= np.linalg.norm(sun)
    spread = np.degrees(np.arccos(np.clip(tail[:, 3:] @ sun, -1, 1)))
    return Result(tail[:, :3].mean(axis=0), sun, losses, tail[:, :3].std(axis=0),
                  float(np.sqrt(np.mean(spread ** 2))), (time.perf_counter() - t0) / iterations)


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    r = recover(ap.parse_args().quick)
    print(f"tint: true {np.round(TRUE_TINT, 3)} recovered {np.round(r.tint, 3)} (start 1 1 1; "
          f"spread of the last iterates {np.round(r.tint_tail_std, 3)})")
    print(f"sun direction: true {np.round(TRUE_SUN, 3)} recovered {np.round(r.sun, 3)} (start 0 0 1): "
          f"{r.sun_error_deg:.2f} degrees off (spread {r.sun_tail_std_deg:.2f})")
    print(f"loss {r.losses[0]:.3e} -> {r.losses[-1]:.3e}; {r.seconds_per_iteration:.2f} s per iteration")


if __name__ == "__main__":
    main()
