"""Texture atlas packing (numpy) and texture sampling (Warp functions, with numpy references).

All image textures of a scene are stored in ONE flat float32 atlas (N, 3), one texture after
another (see :mod:`warp_spt.scene.atlas_layout`), so that a kernel takes a single
``wp.array(dtype=wp.vec3)`` plus a tile table of (offset, w, h, stride) per texture: texel (row, col)
is ``offset + row * stride + col``. The atlas holds the sum of the textures' areas, whatever their
shapes. Stored row 0 is the top row of an image; texture coordinate v = 0 is its bottom row, as in
the seed.

Addressing (both filters), per axis with n texels (w for u, the REAL height h for v):

* repeat wrap; a coordinate c maps to ``floor(c * n)`` — the seed truncated toward zero, so
  u in (-1/w, 0) gave column 0; with floor it gives column w-1, which is what repeat means;
* v uses the texture's own height (the seed used the width: quirk Q5);
* robustness: a NaN coordinate is replaced by 0, and ``c * n`` is clamped to +-2**30 before the
  integer conversion (beyond that float32 has no sub-texel precision anyway), so no index can
  ever leave its tile, whatever the uv.

Bilinear filtering puts texel centres at (i + 0.5) / n and takes the four neighbours with the same
repeat wrap inside the tile, so it never bleeds into a neighbouring tile of the atlas.

:func:`tile_view` gives a texture's (h, w, 3) view into the flat atlas, or into a gradient of it.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from warp_spt.scene.atlas_layout import flat_layout

MAX_ATLAS_TEXELS = 2**31 - 1      # the kernel forms texel indices in int32
COORD_LIMIT = float(2**30)        # |c * n| is clamped here before converting to int (see above)
_COORD_LIMIT = wp.constant(COORD_LIMIT)
CHECKER_WHITE = (1.0, 1.0, 1.0)
CHECKER_GREEN = (0.25, 0.75, 0.25)
INT32_LIMIT = float(2**31)        # Java's (int) cast saturates from here
_INT32_LIMIT = wp.constant(INT32_LIMIT)


@dataclass
class Atlas:
    """``texels`` (N, 3) float32, the textures one after another; ``tiles`` (T, 4) int32 rows
    (offset, w, h, stride).

    With no textures the atlas is one black texel and ``tiles`` holds one dummy tile (0, 1, 1, 1), so
    the Warp arrays are never empty; no material refers to it.
    """

    texels: np.ndarray
    tiles: np.ndarray

    def texture(self, k: int) -> np.ndarray:
        """Texture ``k`` as an (h, w, 3) view into ``texels``."""
        return tile_view(self.texels, self.tiles[k])


def tile_view(flat: np.ndarray, tile) -> np.ndarray:
    """The (h, w, 3) view of one tile (a row of the tile table) into a flat (N, 3) atlas array or
    an array shaped like it (the texels' gradient); row 0 is the image's top row."""
    offset, w, h, stride = (int(c) for c in tile)
    return flat[offset:offset + h * stride].reshape(h, stride, *flat.shape[1:])[:, :w]


def _check_shape(k: int, img: np.ndarray) -> tuple[int, int]:
    shape = np.shape(img)
    if len(shape) != 3 or shape[2] != 3 or shape[0] < 1 or shape[1] < 1:
        raise ValueError(f"texture {k}: expected an (H, W, 3) image with H, W >= 1, got shape {shape}")
    return int(shape[0]), int(shape[1])


def _check_values(k: int, img: np.ndarray) -> np.ndarray:
    a = np.asarray(img, dtype=np.float32)
    if not np.isfinite(a).all():
        raise ValueError(f"texture {k}: texel values must be finite")
    return a


def pack_atlas(textures: list[np.ndarray]) -> Atlas:
    """Store (H, W, 3) images one after another in one flat float32 atlas (:mod:`warp_spt.scene.atlas_layout`).

    Raises ValueError for malformed images or an atlas of more than MAX_ATLAS_TEXELS texels.
    """
    if not textures:
        return Atlas(np.zeros((1, 3), dtype=np.float32), np.array([[0, 1, 1, 1]], dtype=np.int32))
    sizes = [_check_shape(k, t) for k, t in enumerate(textures)]
    tiles, total = flat_layout(sizes)
    if total > MAX_ATLAS_TEXELS:      # checked before touching any texel or allocating
        listed = ", ".join(f"{w}x{h}" for h, w in sizes)
        raise ValueError(f"texture atlas would hold {total} texels (limit {MAX_ATLAS_TEXELS}); "
                         f"texture sizes (WxH): {listed}")
    texels = np.zeros((total, 3), dtype=np.float32)
    for k, (tile, img) in enumerate(zip(tiles, textures)):
        tile_view(texels, tile)[...] = _check_values(k, img)
    return Atlas(texels, tiles.astype(np.int32))


# ---------------------------------------------------------------------------------------------
# Warp functions (importable by the kernels; device-agnostic, no prints)


@wp.func
def _scaled(c: float, n: int) -> float:
    """c * n with NaN -> 0, clamped to +-COORD_LIMIT so that the int conversion cannot overflow."""
    x = c * float(n)
    if wp.isnan(x):
        x = 0.0
    return wp.clamp(x, -_COORD_LIMIT, _COORD_LIMIT)


@wp.func
def _wrap(i: int, n: int) -> int:
    """i modulo n in [0, n): Warp's % truncates like C, so shift negative remainders up."""
    r = i % n
    if r < 0:
        r += n
    return r


@wp.func
def _texel(texels: wp.array(dtype=wp.vec3), tile: wp.vec4i, col: int, row_from_bottom: int) -> wp.vec3:
    """Texel at wrapped (col, row counted from the bottom) of ``tile`` = (offset, w, h, stride)."""
    return texels[tile[0] + (tile[2] - 1 - row_from_bottom) * tile[3] + col]


@wp.func
def sample_texture(
    texels: wp.array(dtype=wp.vec3),
    tiles: wp.array(dtype=wp.vec4i),
    tex: int,
    uv: wp.vec2,
    bilinear: int,
) -> wp.vec3:
    """Colour of texture ``tex`` at ``uv``: nearest (bilinear == 0) or bilinear, repeat wrap.

    An out-of-range ``tex`` returns black rather than reading outside the tile table.
    """
    if tex < 0 or tex >= tiles.shape[0]:
        return wp.vec3(0.0)
    tile = tiles[tex]
    w = tile[1]
    h = tile[2]
    if bilinear == 0:
        col = int(wp.floor(_scaled(uv[0], w)))
        row = int(wp.floor(_scaled(uv[1], h)))
        return _texel(texels, tile, _wrap(col, w), _wrap(row, h))
    # texel centres at (i + 0.5) / n: the lower neighbour is floor(c * n - 0.5)
    x = _scaled(uv[0], w) - 0.5
    y = _scaled(uv[1], h) - 0.5
    fx = wp.floor(x)
    fy = wp.floor(y)
    x0 = _wrap(int(fx), w)
    x1 = _wrap(int(fx) + 1, w)
    y0 = _wrap(int(fy), h)
    y1 = _wrap(int(fy) + 1, h)
    bottom = wp.lerp(_texel(texels, tile, x0, y0), _texel(texels, tile, x1, y0), x - fx)
    top = wp.lerp(_texel(texels, tile, x0, y1), _texel(texels, tile, x1, y1), x - fx)
    return wp.lerp(bottom, top, y - fy)


@wp.func
def checker(uv: wp.vec2) -> wp.vec3:
    """The seed's Inner_CheckerTexture (SEMANTICS §10): parity of trunc(1000*u*v), Java semantics.

    Java's (int) cast maps NaN to 0 and saturates to +-2**31 bounds (MAX_VALUE is odd, so white);
    Java's % keeps the sign, so only a positive odd k is white. No int overflow can happen here.
    """
    p = 1000.0 * uv[0] * uv[1]
    odd = False
    if p >= _INT32_LIMIT:
        odd = True
    elif p > -_INT32_LIMIT:          # false for NaN and for saturation to MIN_VALUE (even)
        odd = int(p) % 2 == 1
    if odd:
        return wp.vec3(1.0, 1.0, 1.0)
    return wp.vec3(0.25, 0.75, 0.25)


# ---------------------------------------------------------------------------------------------
# numpy references (independent of the Warp code path; used by tests)


def _np_scaled(c: np.ndarray, n: int) -> np.ndarray:
    """c * n in float32 with NaN -> 0 and the +-COORD_LIMIT clamp, as the kernel does."""
    x = np.asarray(c, dtype=np.float32) * np.float32(n)
    x = np.where(np.isnan(x), np.float32(0.0), x)
    return np.clip(x, -COORD_LIMIT, COORD_LIMIT).astype(np.float32)


def sample_texture_np(image: np.ndarray, uv: np.ndarray, bilinear: bool = False) -> np.ndarray:
    """Reference lookup straight into one SOURCE image (H, W, 3) for uv (N, 2); returns (N, 3).

    Same addressing as :func:`sample_texture`, written with plain numpy indexing.
    """
    h, w = image.shape[:2]
    uv = np.asarray(uv, dtype=np.float32).reshape(-1, 2)
    x = _np_scaled(uv[:, 0], w)
    y = _np_scaled(uv[:, 1], h)
    if not bilinear:
        col = np.mod(np.floor(x).astype(np.int64), w)
        row = np.mod(np.floor(y).astype(np.int64), h)
        return image[h - 1 - row, col].astype(np.float32)
    x = (x - np.float32(0.5)).astype(np.float32)
    y = (y - np.float32(0.5)).astype(np.float32)
    i, j = np.floor(x), np.floor(y)
    ax, ay = (x - i)[:, None].astype(np.float64), (y - j)[:, None].astype(np.float64)
    i, j = i.astype(np.int64), j.astype(np.int64)

    def at(di: int, dj: int) -> np.ndarray:
        return image[h - 1 - np.mod(j + dj, h), np.mod(i + di, w)].astype(np.float64)

    return ((1 - ay) * ((1 - ax) * at(0, 0) + ax * at(1, 0)) + ay * ((1 - ax) * at(0, 1) + ax * at(1, 1)))


def checker_np(uv: np.ndarray) -> np.ndarray:
    """Reference checker colours (N, 3) for uv (N, 2), emulating Java's float-to-int cast."""
    uv = np.asarray(uv, dtype=np.float32).reshape(-1, 2)
    with np.errstate(over="ignore", invalid="ignore"):
        p = np.float32(1000.0) * uv[:, 0] * uv[:, 1]
    finite_part = np.where(np.abs(p) < INT32_LIMIT, p, 0.0)     # NaN and out-of-range handled below
    k = np.trunc(np.nan_to_num(finite_part)).astype(np.int64)
    k = np.where(p >= INT32_LIMIT, 2**31 - 1, k)                  # saturation: MAX_VALUE is odd
    k = np.where(p <= -INT32_LIMIT, -(2**31), k)
    white = (k > 0) & (k % 2 == 1)
    return np.where(white[:, None], np.float32(CHECKER_WHITE), np.float32(CHECKER_GREEN)).astype(np.float32)
