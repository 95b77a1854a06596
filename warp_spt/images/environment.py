"""Environment maps from files: ``load_environment(path, ...) -> Sky``.

Formats, by extension: Radiance ``.hdr`` (our reader, ``images.hdr``), ``.pfm`` and ``.exr`` (the
optional ``exr`` extra) as float32 radiance; ``.npy`` (an (H, W, 3) float array); an 8-bit ``.png``
or ``.jpg`` is accepted as a low-dynamic-range map with a warning (decoded from sRGB to linear, so at
most 1: a sun clipped to white lights a scene far too little). Every map is checked by
``scene.environment`` (2:1, within the texel budget, finite, non-negative), the file named in each
error.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Callable

import numpy as np

from warp_spt.scene.atlas_layout import TEXEL_BUDGET
from warp_spt.scene.environment import EnvironmentMap
from warp_spt.scene.sky import Sky

FORMATS = (".hdr", ".exr", ".pfm", ".npy", ".png", ".jpg", ".jpeg")
LDR = (".png", ".jpg", ".jpeg")


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB transfer function inverted (values in [0, 1])."""
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def read_environment_image(path: str | os.PathLike, warn: Callable[[str], None] | None = None) -> np.ndarray:
    """The image of an environment map file as (H, W, 3) float32 radiance, row 0 the top (ValueError
    naming the file and what was expected)."""
    p = Path(path)
    ext = p.suffix.lower()
    if ext not in FORMATS:
        raise ValueError(f"{path}: unsupported environment map extension {ext or '(none)'!r}; expected one of "
                         f"{', '.join(FORMATS)}")
    if not p.is_file():
        raise ValueError(f"{path}: no such environment map file")
    try:
        if ext == ".hdr":
            from warp_spt.images.hdr import read_hdr
            return read_hdr(p)
        if ext == ".pfm":
            from warp_spt.images.files import read_pfm
            return read_pfm(p)
        if ext == ".npy":
            _check_npy_header(p)
            img = np.load(p, allow_pickle=False)
            if not np.issubdtype(img.dtype, np.number):
                raise ValueError(f"{path}: expected a numeric (H, W, 3) array, got dtype {img.dtype}")
            return img.astype(np.float32)
        if ext == ".exr":
            try:
                import OpenEXR
            except ImportError:
                from warp_spt.runtime.extras import install_hint
                raise ValueError(f"{path}: reading .exr needs the optional 'openexr' package: "
                                 f"{install_hint('exr')}") from None
            with OpenEXR.File(str(p)) as exr:
                channels = exr.channels()
                if "RGB" not in channels:
                    raise ValueError(f"{path}: expected an RGB (or R, G, B) image, found channels "
                                     f"{', '.join(sorted(channels))}")
                return np.asarray(channels["RGB"].pixels, dtype=np.float32)
        from PIL import Image

        with Image.open(p) as im:
            _check_size(path, *im.size)              # from the header, before anything is decoded
            img = np.asarray(im.convert("RGB"), dtype=np.uint8)
        if warn is not None:
            warn(f"{path}: an 8-bit image is a low-dynamic-range environment (radiance at most 1, its bright "
                 "parts clipped): lighting from it is flatter than from an .hdr or .exr map")
        return srgb_to_linear(img / 255.0).astype(np.float32)
    except ValueError as err:
        if str(err).startswith((f"{path}: ", f"{p}: ")):     # ours, already naming the file
            raise
        raise ValueError(f"{path}: cannot read the environment map: {' '.join(str(err).split())}") from None
    except Exception as err:        # the image libraries' own (OpenEXR's RuntimeError, PIL's bomb guard...)
        text = " ".join(str(err).split()) or type(err).__name__
        raise ValueError(f"{path}: cannot read the environment map: {text}") from None


def _check_size(path, width: int, height: int) -> None:
    """The texel budget, from the size a header gives (a PNG of 220 KB once decoded to 3.9 GB)."""
    if width * height > TEXEL_BUDGET:
        raise ValueError(f"{path}: {width}x{height} = {width * height:,} texels, more than the texel budget of "
                         f"{TEXEL_BUDGET:,}")


def _check_npy_header(p: Path) -> None:
    """An .npy map's shape and type from its header, before its data is read."""
    with open(p, "rb") as f:
        try:
            version = np.lib.format.read_magic(f)
            shape, _, dtype = (np.lib.format.read_array_header_1_0(f) if version == (1, 0)
                               else np.lib.format.read_array_header_2_0(f))
        except ValueError as err:
            raise ValueError(f"{p}: not an .npy array: {' '.join(str(err).split())}") from None
    if len(shape) != 3 or shape[2] != 3:
        raise ValueError(f"{p}: an environment map must be an RGB image (height, width, 3), got shape {shape}")
    if not np.issubdtype(dtype, np.number):
        raise ValueError(f"{p}: expected a numeric (H, W, 3) array, got dtype {dtype}")
    _check_size(p, shape[1], shape[0])


def load_environment(path: str | os.PathLike, rotate: float = 0.0, strength: float = 1.0, background=None,
                     up=None, warn: Callable[[str], None] | None = None, sampling: str = "importance") -> Sky:
    """An environment sky from an equirectangular map file (see :meth:`warp_spt.Sky.environment` for
    ``rotate`` (degrees about the up axis), ``strength``, ``background`` and ``up``); ``warn`` is
    called with a warning (an 8-bit map); ``sampling``: ``scene.environment.SAMPLINGS``."""
    img = read_environment_image(path, warn)
    env = EnvironmentMap(img, str(path), sampling)
    return Sky.environment(env, rotate=rotate, strength=strength, background=background, up=up)
