"""Scenes and statistics for the numerical-stability suite (tests/rendering/test_stability.py).

Scenes are written as OBJ/MTL text, independent of the code under test. Image comparisons are
statistical: each image is rendered as K independent batches (disjoint sample ranges), and two images
agree when every block of pixels agrees within a bound derived from the batches' own spread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from warp_spt.upload.device_scene import DeviceScene, Features
from warp_spt.io.loader import load_scene
from warp_spt.rendering import tiles as R
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

from tests.support.scenes import material, write_scene_files

GENERAL = Features.general()     # one kernel serves every scene of the suite (one compile)

# --------------------------------------------------------------------------------------------
# Geometry as OBJ text


def quads_obj(quads: list[tuple[str, list[tuple[float, float, float]]]], spheres=()) -> str:
    """OBJ text for (material, 4 corners) quads, each split into two triangles, and (material, c, r) spheres."""
    lines, faces = [], []
    for k, (mat, corners) in enumerate(quads):
        lines += [f"v {x!r} {y!r} {z!r}" for x, y, z in corners]
        b = 4 * k + 1
        faces += [f"usemtl {mat}", f"f {b} {b + 1} {b + 2}", f"f {b} {b + 2} {b + 3}"]
    out = lines + faces
    for mat, (x, y, z), r in spheres:
        out += [f"usemtl {mat}", f"b {x!r} {y!r} {z!r} {r!r}"]
    return "\n".join(out) + "\n"


def box_quads(lo, hi, mat: str) -> list[tuple[str, list[tuple[float, float, float]]]]:
    """The six faces of an axis-aligned box (outward winding) as quads."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    return [
        (mat, [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)]),   # bottom
        (mat, [(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]),   # top
        (mat, [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)]),   # y = y0
        (mat, [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)]),   # y = y1
        (mat, [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)]),   # x = x0
        (mat, [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)]),   # x = x1
    ]


CORNELL_SIZE = 32.0


def cornell_files(folder: Path, scale: float = 1.0, shift: float = 0.0, light_gap: float = 0.25,
                  exact32: bool = True) -> tuple[list[str], list[str]]:
    """A closed Cornell-like room (32 units, seed-sized) with a ceiling light ``light_gap`` below the ceiling,
    two blocks standing on the floor, a glossy ball and a glass ball; every coordinate is
    ``c * scale + shift``, rounded to float32 unless ``exact32`` is False (then written in float64).
    Unscaled coordinates are multiples of 1/4, so a shift of 1e5 is exact in float32 and the shifted
    room is the same room.
    """
    s = CORNELL_SIZE

    def tr(p):
        return tuple(float(np.float32(c * scale + shift)) if exact32 else c * scale + shift for c in p)

    quads = [
        ("white", [(0, 0, 0), (s, 0, 0), (s, s, 0), (0, s, 0)]),          # floor
        ("white", [(0, 0, s), (0, s, s), (s, s, s), (s, 0, s)]),          # ceiling
        ("white", [(0, s, 0), (s, s, 0), (s, s, s), (0, s, s)]),          # back wall
        ("white", [(0, 0, 0), (0, 0, s), (s, 0, s), (s, 0, 0)]),          # front wall (behind the camera)
        ("red", [(0, 0, 0), (0, s, 0), (0, s, s), (0, 0, s)]),            # left
        ("green", [(s, 0, 0), (s, 0, s), (s, s, s), (s, s, 0)]),          # right
        ("light", [(10, 10, s - light_gap), (22, 10, s - light_gap), (22, 22, s - light_gap), (10, 22, s - light_gap)]),
    ]
    quads += box_quads((6, 16, 0), (14, 24, 16), "white")                 # tall block on the floor
    quads += box_quads((18, 6, 0), (26, 14, 8), "white")                  # short block on the floor
    quads = [(m, [tr(p) for p in corners]) for m, corners in quads]
    spheres = [("gloss", tr((22, 22, 5)), 4.0 * scale), ("glass", tr((10, 8, 4)), 3.5 * scale)]
    mtl = (material("white", Kd=(0.75, 0.75, 0.75), Roughness=1)
           + material("red", Kd=(0.75, 0.2, 0.2), Roughness=1)
           + material("green", Kd=(0.2, 0.75, 0.2), Roughness=1)
           + material("light", Kd=(0.75, 0.75, 0.75), Kl=(5, 5, 5), Roughness=1)
           + material("gloss", Kd=(0.8, 0.6, 0.3), Roughness=0.5, Fuzz=0.2)
           + material("glass", Kd=(0.95, 0.95, 0.95), Kt=(0.95, 0.95, 0.95), Roughness=0, Fuzz=0,
                      Kn=1.5, Refractable=True))
    name = f"cornell_{scale:g}_{shift:g}_{light_gap:g}_{int(exact32)}".replace(".", "p").replace("-", "m").replace("+", "")
    return write_scene_files(folder, name, quads_obj(quads, spheres), mtl)


def cornell_camera(scale: float = 1.0, shift: float = 0.0, aperture: float = 0.0) -> Camera:
    """A camera inside the room near the front wall, looking at the back wall, scaled with the room."""
    s = CORNELL_SIZE
    p = tuple(float(np.float32(c * scale + shift)) for c in (s / 2, 1.0, s / 2))
    return Camera(position=p, direction=(0.0, 1.0, -0.05), fov=75.0, aperture=aperture * scale, focus=scale)


def load(objs: list[str], mtls: list[str]) -> DeviceScene:
    """Load OBJ/MTL files and upload them (warnings collected, not printed)."""
    return DeviceScene(load_scene(objs, mtls, warn=lambda message: None))


def scene_from_text(folder: Path, name: str, obj: str, mtl: str | None = None) -> DeviceScene:
    """A DeviceScene from OBJ (and MTL) text."""
    return load(*write_scene_files(folder, name, obj, mtl))


# --------------------------------------------------------------------------------------------
# Rendering with the invariants checked


def render_checked(scene: DeviceScene, camera: Camera, **kw) -> np.ndarray:
    """render() with the general kernel; asserts a finite image and no dropped (non-finite) samples.

    The integrator defaults to the seed's: many checks here are exact identities (every sample of a
    closed furnace is the same number, a closed room's image is bit-identical under any sky) that
    hold for pure path tracing only. NEE is checked statistically (the Cornell box at every scale
    here, furnaces and analytic lighting in tests/integrators/test_light_transport.py).
    """
    kw.setdefault("features", GENERAL)
    kw.setdefault("integrator", "seed")
    res = R.render_scene(scene, camera, RenderSettings(**kw))
    img = res.image
    assert res.stats.dropped_samples == 0, f"{res.stats.dropped_samples} non-finite samples dropped"
    assert np.isfinite(img).all(), "non-finite pixel"
    return img


def render_batches(scene: DeviceScene, camera: Camera, batches: int, spp: int, **kw) -> np.ndarray:
    """(K, H, W, 3): K independent images of ``spp`` samples (disjoint sample ranges, same seed)."""
    return np.stack([render_checked(scene, camera, spp=spp, sample_offset=k * spp, **kw)
                     for k in range(batches)])


# --------------------------------------------------------------------------------------------
# Statistics


def t_quantile(p: float, dof: float) -> float:
    """Upper p-quantile of Student's t with ``dof`` degrees of freedom (Cornish-Fisher expansion of
    the normal quantile to third order in 1/dof; accurate to < 1% for dof >= 10 and p >= 1e-8)."""
    z = normal_quantile(p)
    g1 = (z**3 + z) / 4
    g2 = (5 * z**5 + 16 * z**3 + 3 * z) / 96
    g3 = (3 * z**7 + 19 * z**5 + 17 * z**3 - 15 * z) / 384
    return z + g1 / dof + g2 / dof**2 + g3 / dof**3


def normal_quantile(p: float) -> float:
    """Upper p-quantile of the standard normal (bisection on erfc: exact to 1e-12)."""
    lo, hi = 0.0, 40.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if 0.5 * math.erfc(mid / math.sqrt(2.0)) > p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


@dataclass
class Comparison:
    """Two batched images compared block by block and as a whole (Welch t statistics)."""

    z: np.ndarray          # (blocks, 3) per block and channel
    z_total: float         # of the whole image's mean
    bound: float           # a block |z| above this fails
    bound_total: float     # the whole-image |z| above this fails
    rel_diff: float        # whole-image mean difference, relative to the mean
    rel_se: float          # its standard error, relative

    @property
    def worst(self) -> float:
        return float(np.abs(self.z).max())


def block_means(batches: np.ndarray, block: int) -> np.ndarray:
    """(K, blocks, 3): per-batch means over block x block pixel tiles."""
    k, h, w, _ = batches.shape
    b = batches[:, : h - h % block, : w - w % block]
    b = b.reshape(k, h // block, block, w // block, block, 3).mean(axis=(2, 4))
    return b.reshape(k, -1, 3)


def welch(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Welch t statistic of the means of samples a and b (axis 0); 0 where both are constant and equal."""
    k = a.shape[0]
    diff = a.mean(axis=0) - b.mean(axis=0)
    se = np.sqrt(a.var(axis=0, ddof=1) / k + b.var(axis=0, ddof=1) / k)
    return np.where(se > 0, diff / np.where(se > 0, se, 1.0), np.where(diff == 0, 0.0, np.inf))


def compare(a: np.ndarray, b: np.ndarray, block: int = 4, alpha: float = 1e-4) -> Comparison:
    """Compare two batched images (K, H, W, 3) block by block and as a whole.

    Each block mean is averaged over K independent batches and its standard error comes from the
    batches' spread. Welch statistics are held against Student's t quantiles at a family-wise
    false-failure probability ``alpha``: half for the blocks (Bonferroni over blocks x channels),
    half for the whole image's mean. Degrees of freedom K - 1, the least Welch's approximation can give, so the
    bound is conservative. Blocks where both images have zero spread must agree exactly.
    """
    k = a.shape[0]
    ma, mb = block_means(a, block), block_means(b, block)
    z = welch(ma, mb)
    tot_a, tot_b = a.mean(axis=(1, 2, 3)), b.mean(axis=(1, 2, 3))
    mean = 0.5 * (tot_a.mean() + tot_b.mean())
    rel_se = math.sqrt(tot_a.var(ddof=1) / k + tot_b.var(ddof=1) / k) / mean
    # half of alpha for the blocks (two-sided, Bonferroni), half for the whole image
    return Comparison(z, float(welch(tot_a[:, None], tot_b[:, None])[0]),
                      t_quantile(alpha / (4 * z.size), k - 1), t_quantile(alpha / 4, k - 1),
                      abs(tot_a.mean() - tot_b.mean()) / mean, rel_se)


def assert_same_image(a: np.ndarray, b: np.ndarray, what: str, block: int = 4, alpha: float = 1e-4) -> Comparison:
    """Fail unless the batched images agree block by block and as a whole within the statistical bound."""
    c = compare(a, b, block, alpha)
    assert c.worst <= c.bound and abs(c.z_total) <= c.bound_total, (
        f"{what}: worst block |t| = {c.worst:.2f} (bound {c.bound:.2f}); whole image differs by "
        f"{c.rel_diff:.2%} (standard error {c.rel_se:.2%}, |t| = {abs(c.z_total):.2f})")
    return c


def furnace_value(emission: float, albedo: float, depth: int) -> float:
    """Radiance of a closed furnace: every path makes exactly ``depth`` hits, hit k adds E * A^k."""
    return emission * depth if albedo == 1 else emission * (1 - albedo**depth) / (1 - albedo)


def sky(value: float) -> Sky:
    """A constant sky of radiance ``value``."""
    return Sky.constant(value, value, value)
