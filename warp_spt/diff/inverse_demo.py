"""Inverse rendering demos: recover a Cornell wall's colour, and a 16x16 texture, from images.

``examples/inverse_rendering.py`` runs both at the documented sizes (docs/gradients.md) and
``notebooks/inverse_rendering.ipynb`` at small ones; they live in the package so that the notebook
finds them wherever Jupyter starts its kernel.

Each run renders a target with the true value (more samples, another seed), starts from grey and
runs Adam (:mod:`warp_spt.diff.optim`) on the L2 loss, with a fresh seed per iteration (stochastic
gradient descent on the expected loss, not a fit to one noise pattern). The reported value is the
mean of the last iterates.
"""

from __future__ import annotations

import tempfile
import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from warp_spt.demo import demo_dir
from warp_spt.diff.gradients import render_gradients
from warp_spt.diff.optim import Adam
from warp_spt.diff.params import parameters
from warp_spt.io.loader import load_scene
from warp_spt.losses import l2
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky


@dataclass
class Recovery:
    """The outcome of one optimisation."""

    name: str
    target: np.ndarray
    start: np.ndarray
    value: np.ndarray          # mean of the last ``average`` iterates
    losses: list[float]
    seconds_per_iteration: float

    @property
    def max_relative_error(self) -> float:
        return float(np.max(np.abs(self.value - self.target) / np.abs(self.target)))

    @property
    def max_abs_error(self) -> float:
        return float(np.max(np.abs(self.value - self.target)))

    @property
    def rmse_of_range(self) -> float:
        return float(np.sqrt(np.mean((self.value - self.target) ** 2)) / np.ptp(self.target))


def _optimise(params, name: str, target_value, start, settings: RenderSettings, iterations: int, lr: float,
              average: int, target_spp: int, decay: float) -> Recovery:
    params[name] = target_value
    target = render_scene(params.scene, params.camera,
                          replace(settings, sky=params.sky, spp=target_spp, seed=10_000)).image
    params[name] = start
    opt = Adam(params, [name], lr=lr, decay=decay)
    losses, tail = [], []
    t0 = time.perf_counter()
    for it in range(iterations):
        # image and gradient from independent samples: an unbiased gradient of the expected loss
        r = render_gradients(params, replace(settings, seed=2 * it), loss=l2(target), wrt=[name],
                             gradient_seed=2 * it + 1)
        losses.append(r.loss)
        opt.step(r.grads)
        if it >= iterations - average:
            tail.append(params[name])
    seconds = (time.perf_counter() - t0) / iterations
    return Recovery(name, np.asarray(target_value, np.float64), np.asarray(start, np.float64),
                    np.mean(tail, axis=0), losses, seconds)


def recover_wall_colour(iterations: int = 160, size: int = 32, spp: int = 32, max_depth: int = 4) -> Recovery:
    """The demo Cornell box's red wall: true Kd (0.9, 0.12, 0.1), start (0.5, 0.5, 0.5). Next-event
    estimation with the Sobol' sampler: far less noise than the seed's estimator in this box. The
    dim channels (0.12, 0.1) converge slowest: a slow learning-rate decay and the mean of the last
    quarter of the iterates bring them within about 1% of their value."""
    d = demo_dir()
    scene = load_scene([str(d / "cornell.obj")], [str(d / "demo.mtl")])
    params = parameters(scene, Camera(), Sky.black())
    rs = RenderSettings(width=size, height=size, spp=spp, max_depth=max_depth, integrator="nee", sampler="sobol",
                        tile_pixels=256)
    return _optimise(params, "red.diffuse", params["red.diffuse"], (0.5, 0.5, 0.5), rs, iterations, lr=0.03,
                     average=max(1, iterations // 4), target_spp=16 * spp, decay=0.98)


def target_texture(n: int = 16) -> np.ndarray:
    """A 16x16 test pattern in [0.1, 0.9]: smooth ramps plus a checker, row 0 at the top."""
    y, x = np.mgrid[0:n, 0:n] / (n - 1)
    checker = ((np.arange(n)[:, None] // 4 + np.arange(n)[None, :] // 4) % 2).astype(float)
    img = np.stack([0.1 + 0.8 * x, 0.1 + 0.8 * y, 0.1 + 0.8 * checker], axis=-1)
    return img.astype(np.float32)


def textured_quad(folder: Path, n: int = 16):
    """A 2x2 diffuse quad at z = 0 with an n x n texture (initially grey) under a white sky, and a
    camera looking straight down that sees the quad's central 1.9 x 1.9 (no sky in view)."""
    Image.fromarray(np.full((n, n, 3), 128, np.uint8)).save(folder / "tex.png")
    (folder / "quad.mtl").write_text("newmtl quad\nKd 1 1 1\nmap_Kd tex.png\nRoughness 1\n")
    (folder / "quad.obj").write_text(
        "mtllib quad.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
        "usemtl quad\nf 1/1 2/2 3/3\nf 1/1 3/3 4/4\n")
    scene = load_scene([str(folder / "quad.obj")], [str(folder / "quad.mtl")])
    camera = Camera(position=(0.0, 0.0, 2.0), direction=(0.0, 0.0, -1.0),
                             fov=2 * np.degrees(np.arctan(0.475)), aperture=0.0, focus=2.0)
    return scene, camera


def recover_texture(iterations: int = 60, size: int = 48, spp: int = 4) -> Recovery:
    """A 16x16 texture on a quad seen by 48x48 pixels (about 3x3 per texel), nearest filtering."""
    with tempfile.TemporaryDirectory() as tmp:
        scene, camera = textured_quad(Path(tmp))
    params = parameters(scene, camera, Sky.constant(1.0, 1.0, 1.0))
    rs = RenderSettings(width=size, height=size, spp=spp, max_depth=2, tile_pixels=576, integrator="seed")
    return _optimise(params, "quad.diffuse_map", target_texture(), np.full((16, 16, 3), 0.5), rs, iterations,
                     lr=0.05, average=10, target_spp=16 * spp, decay=0.95)


def plot_losses(runs: list[Recovery], width: int = 480, height: int = 240, what: str = "L2") -> Image.Image:
    """Loss curves (log10 scale) as an image, drawn with PIL (no plotting dependency); each run has a
    ``name`` and ``losses`` (``what`` they are: the legend's word)."""
    img = Image.new("RGB", (width, height), "white")
    draw = ImageDraw.Draw(img)
    logs = [np.log10(np.maximum(np.asarray(r.losses), 1e-12)) for r in runs]
    lo, hi = min(l.min() for l in logs), max(l.max() for l in logs)
    m = 30
    draw.rectangle([m, 10, width - 10, height - m], outline="black")
    colours = ["#c0392b", "#2471a3", "#229954"]
    for k, (r, l) in enumerate(zip(runs, logs)):
        xs = m + (width - 10 - m) * np.arange(len(l)) / max(1, len(l) - 1)
        ys = height - m - (height - m - 10) * (l - lo) / max(hi - lo, 1e-9)
        draw.line(list(zip(xs.tolist(), ys.tolist())), fill=colours[k % 3], width=2)
        draw.text((m + 8, 14 + 12 * k), f"{r.name}: {what} {r.losses[0]:.2e} -> {r.losses[-1]:.2e}", fill=colours[k % 3])
    draw.text((m, height - m + 6), f"iteration (0..{max(len(l) for l in logs) - 1}); log10 {what} {lo:.1f}..{hi:.1f}",
              fill="black")
    return img


@dataclass
class OptimisationRun:
    """What a demo's optimisation leaves: its error at the start and per iteration, the loss per
    iteration, the seconds per iteration, the target and the renders at the start and the end."""

    start_error: float
    errors: list[float]
    losses: list[float]
    seconds_per_iteration: float
    target: np.ndarray
    start_image: np.ndarray
    final_image: np.ndarray

    def strip(self, name: str, scale: int) -> Image.Image:
        """The start, the result and the target side by side over the error curve (log10)."""
        return strip_figure([self.start_image, self.final_image, self.target], name, self.errors, scale)


def strip_figure(images: list, name: str, errors: list[float], scale: int = 4, what: str = "error") -> Image.Image:
    """``images`` (the start, the result, the target: linear (H, W, 3) arrays) side by side, each
    scaled up ``scale`` times, over the curve of ``errors`` (log10) named ``name`` (``what`` they
    are: the legend's word), as a PIL image."""
    from types import SimpleNamespace

    from warp_spt.images.files import to_display

    tiles = [Image.fromarray(to_display(a)).resize((a.shape[1] * scale, a.shape[0] * scale), Image.NEAREST)
             for a in images]
    w = sum(t.width for t in tiles) + 10 * (len(tiles) - 1)
    curve = plot_losses([SimpleNamespace(name=name, losses=errors)], width=w, height=200, what=what)
    out = Image.new("RGB", (w, tiles[0].height + curve.height + 10), "white")
    x = 0
    for t in tiles:
        out.paste(t, (x, 0))
        x += t.width + 10
    out.paste(curve, (0, tiles[0].height + 10))
    return out
