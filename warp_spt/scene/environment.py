"""An environment map on the host: an equirectangular (latitude-longitude) float32 radiance image,
checked once when it is made (no Warp, no files: ``warp_spt.images.environment`` reads them).

Orientation, Mitsuba 3's (its ``envmap`` emitter, Y up): row 0 is the zenith of the sky's up axis
and the last row its nadir (polar angle theta = pi (row + 0.5) / height at a row's centre); the map's
u = (c + 0.5) / width is psi / 2 pi with psi = atan2(-d.t, -d.b) in the sky frame (t, b, up)
(``emitters.sky.sky_frame``): for Y up, t = -X and b = +Z, so psi = atan2(x, -z) as Mitsuba's;
for Z up, psi = atan2(-x, -y) (u = 1/2 straight along +Y). Seen from inside, u grows to the right,
so the picture is not mirrored. A rotation of a degrees turns the map right-handedly about up (as
Mitsuba's ``to_world`` rotation about its up axis): the direction at psi shows u = psi / 2 pi + a / 360.

Only 2:1 maps are accepted: a lat-long map covers 360 x 180 degrees, so any other shape is another
projection (a cube cross is 4:3 or 3:4, a mirror ball 1:1) that would render as nonsense; refusing it
with the shape named is better than a silently wrong sky.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_spt.scene.atlas_layout import TEXEL_BUDGET
from warp_spt.scene.limits import MAX_RADIANCE


# how light sampling draws directions from a map (``sampling_weights``): "importance" (luminance x
# sin theta, the default), "compensated" (pbrt-v4's MIS compensation) or "uniform" (over the sphere:
# for comparisons, benchmarks/bench_envmap.py)
SAMPLINGS = ("importance", "compensated", "uniform")


@dataclass(frozen=True, eq=False)
class EnvironmentMap:
    """``image`` (H, W, 3) float32 radiance, row 0 the zenith; ``name`` says where it came from (the
    file, in every error); ``sampling`` one of SAMPLINGS. Compared and hashed by identity: a light
    table is cached per map."""

    image: np.ndarray
    name: str = "environment map"
    sampling: str = "importance"

    def __post_init__(self) -> None:
        problem = environment_problem(self.image, self.name)
        if not problem and self.sampling not in SAMPLINGS:
            problem = f"{self.name}: sampling must be one of {', '.join(SAMPLINGS)}, got {self.sampling!r}"
        if problem:
            raise ValueError(problem)
        img = np.ascontiguousarray(self.image, dtype=np.float32)
        img.setflags(write=False)
        object.__setattr__(self, "image", img)

    @property
    def height(self) -> int:
        return int(self.image.shape[0])

    @property
    def width(self) -> int:
        return int(self.image.shape[1])

    def __repr__(self) -> str:
        return f"EnvironmentMap({self.name!r}, {self.width}x{self.height})"


def environment_problem(image, name: str, budget: int = TEXEL_BUDGET) -> str | None:
    """Why ``image`` cannot be an environment map, or None: shape (H, W, 3) with W = 2 H (within a
    pixel), at most ``budget`` texels, every texel finite and in [0, MAX_RADIANCE]."""
    img = np.asarray(image)
    if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 1:
        return f"{name}: an environment map must be an RGB image (height, width, 3), got shape {img.shape}"
    h, w = img.shape[:2]
    if abs(w - 2 * h) > 1:
        return (f"{name}: an environment map must be equirectangular (latitude-longitude), twice as wide as "
                f"high, got {w}x{h} (a cube map or mirror ball must be converted to a lat-long map first)")
    if h * w > budget:
        return f"{name}: {w}x{h} = {h * w:,} texels, more than the texel budget of {budget:,}"
    if not np.issubdtype(img.dtype, np.floating) and not np.issubdtype(img.dtype, np.integer):
        return f"{name}: texels must be numbers, got dtype {img.dtype}"
    f = img.astype(np.float32, copy=False)
    bad = ~np.isfinite(f)
    if bad.any():
        r, c, _ = np.argwhere(bad)[0]
        return f"{name}: {int(bad.sum())} texel value(s) are not finite (NaN or infinite), the first at row {r}, column {c}"
    neg = f < 0
    if neg.any():
        r, c, _ = np.argwhere(neg)[0]
        return (f"{name}: {int(neg.sum())} texel value(s) are negative (radiance is >= 0), the first at row {r}, "
                f"column {c}: {float(f[r, c].min()):g}")
    if f.size and float(f.max()) > MAX_RADIANCE:
        return f"{name}: texel values must be at most {MAX_RADIANCE:g}, got {float(f.max()):g}"
    return None


def texel_luminance(image: np.ndarray) -> np.ndarray:
    """(H, W) float64: the mean of each texel's RGB, the quantity sampling follows (as the light
    table's choice weights do)."""
    return np.asarray(image, dtype=np.float64).mean(axis=2)


def row_solid_angles(height: int, width: int) -> np.ndarray:
    """(H,) float64: the solid angle of one texel of each row, 2 pi / W x (cos theta_top - cos theta_bottom)."""
    edges = np.cos(np.pi * np.arange(height + 1) / height)
    return (2.0 * np.pi / width) * (edges[:-1] - edges[1:])


def mean_radiance(image: np.ndarray) -> np.ndarray:
    """(3,) float64: the map's radiance averaged over the sphere of directions (by solid angle)."""
    img = np.asarray(image, dtype=np.float64)
    w = row_solid_angles(img.shape[0], img.shape[1])
    return np.einsum("hwc,h->c", img, w) / (4.0 * np.pi)


def sampling_weights(image: np.ndarray, sampling: str = "importance") -> np.ndarray:
    """(H, W) float64 weights of the piecewise-constant distribution: luminance (each texel's mean of
    the radiance as looked up, see below) x sin(theta) at each
    row's centre (the lat-long map's area distortion); "uniform": sin theta alone (uniform over the
    sphere); "compensated": pbrt-v4's MIS
    compensation, max(0, luminance - its mean): the dim part is left to BSDF sampling, which MIS
    weighs in full where light sampling cannot reach (falls back to the plain weights when that
    leaves nothing, a constant map)."""
    lum = texel_luminance(image)
    # the radiance is linear between texel centres in azimuth (emitters.environment.env_radiance): a
    # texel's mean over its area is 3/4 its own value and 1/8 of each neighbour's in its row, which
    # is also > 0 wherever the radiance is (else light sampling could never reach a bright texel's
    # spill into its dark neighbours: unbiased through BSDF sampling, but with wild variance)
    lum = 0.75 * lum + 0.125 * (np.roll(lum, 1, axis=1) + np.roll(lum, -1, axis=1))
    if sampling == "uniform":
        lum = np.ones_like(lum)
    h = lum.shape[0]
    sin_theta = np.sin(np.pi * (np.arange(h) + 0.5) / h)
    if sampling == "compensated":
        sa = row_solid_angles(h, lum.shape[1])
        mean = float((lum * sa[:, None]).sum() / (4.0 * np.pi))
        comp = np.maximum(lum - mean, 0.0)
        if comp.max() > 0.0:
            lum = comp
    return lum * sin_theta[:, None]


def distribution(weights: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The piecewise-constant 2-D distribution over (u, v) in [0, 1]^2 of (H, W) ``weights``: the
    marginal CDF over rows (H,), the conditional CDF over columns within each row (H, W; a row of
    zero weight is uniform, never chosen), each ending in exactly 1, and the density p(u, v) of
    each texel (H, W), whose mean is 1. The CDFs are float32, as the device holds them, and the
    density is computed from their differences; sampling a row and then a column by these CDFs,
    uniformly within the texel, has density p(u, v)."""
    w = np.asarray(weights, dtype=np.float64)
    h, width = w.shape
    row_sum = w.sum(axis=1)
    total = row_sum.sum()
    if total <= 0.0:
        raise ValueError("an environment map's sampling weights are all zero")
    cond = np.cumsum(w, axis=1)
    empty = row_sum <= 0.0
    cond[empty] = np.arange(1, width + 1)[None, :]
    cond = (cond / cond[:, -1:]).astype(np.float32)
    cond[:, -1] = 1.0
    marginal = (np.cumsum(row_sum) / total).astype(np.float32)
    marginal[-1] = 1.0
    # the density of exactly what the float32 CDFs sample (as the light table's choice): a texel too
    # dim for float32 to give it any probability gets density 0, and BSDF sampling the whole MIS weight
    p_row = np.diff(marginal.astype(np.float64), prepend=0.0)
    p_col = np.diff(cond.astype(np.float64), axis=1, prepend=0.0)
    density = p_row[:, None] * p_col * (h * width)
    return marginal, cond, density
