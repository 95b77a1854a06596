"""Optional denoising with Intel Open Image Denoise (the ``pyoidn`` package, extra ``[denoise]``).

Never silent: the CLI denoises when asked (``--denoise``) and, when pyoidn is installed, a
standard file's .png/.jpg first image (:func:`warp_spt.rendering.first_view.denoise_by_default`;
``--no-denoise`` turns it off), and says so; the convergence report when asked. A denoised image is
biased (it trades noise for blur); the convergence report's "denoised" line measures its error
against the reference, so users see that trade.

Feature buffers: OIDN is better with albedo and normal images of the first non-specular hit;
:func:`warp_spt.rendering.aux_buffers.feature_buffers` renders them, and the CLI and the convergence report
pass them. :func:`denoise` also works on colour alone.
"""

from __future__ import annotations

import time

import numpy as np

from warp_spt.runtime.extras import install_hint

# the extra is named in pyproject.toml ([project.optional-dependencies] denoise); from a clone the
# package is not on PyPI under that name yet, so both forms are given
INSTALL_HINT = '--denoise needs Intel Open Image Denoise (the pyoidn package): ' + install_hint("denoise")


def available() -> bool:
    """True when pyoidn can be imported."""
    try:
        import pyoidn  # noqa: F401
    except ImportError:
        return False
    return True


# What a denoise costs, for the CLI's --time-budget reserve. Measured with pyoidn 2.5.1 (OIDN's RT
# filter, colour + albedo + normal) on this project's 2-core machine under load: 7-8 us per pixel once
# warm at 64x64 to 512x512, the first call at a new size 1.3-1.6x that (the filter's set-up), the first
# call in a process 0.15 s more (the device). Without a measurement we assume twice that.
SECONDS_PER_PIXEL = 16e-6
SECONDS_FIXED = 0.3
PROBE_SIZE = 64          # the measured probe: 64 x 64 pixels
FIRST_CALL_FACTOR = 1.6  # a first call at a new size over a warm one, as measured at 512 x 512


def seconds(width: int, height: int) -> float:
    """Seconds that denoising a ``width`` x ``height`` image with feature buffers will take here.

    With pyoidn, measured: a warm-up denoise of a PROBE_SIZE square of noise (it also creates OIDN's
    device, so the real call does not pay for that), then a timed one, scaled by pixels and by
    FIRST_CALL_FACTOR. About 0.1 s spent. Without pyoidn, the conservative SECONDS_FIXED +
    SECONDS_PER_PIXEL x pixels."""
    pixels = width * height
    if not available():
        return SECONDS_FIXED + SECONDS_PER_PIXEL * pixels
    rng = np.random.default_rng(0)
    probe = [rng.random((PROBE_SIZE, PROBE_SIZE, 3), dtype=np.float32) for _ in range(3)]
    probe[2] = probe[2] * 2.0 - 1.0                     # normals in [-1, 1]
    denoise(*probe)
    t = time.perf_counter()
    denoise(*probe)
    per_pixel = (time.perf_counter() - t) / PROBE_SIZE**2
    return FIRST_CALL_FACTOR * per_pixel * max(pixels, PROBE_SIZE**2)


def require() -> None:
    """Raise RuntimeError with the install hint when pyoidn is missing."""
    if not available():
        raise RuntimeError(INSTALL_HINT)


def denoise(image: np.ndarray, albedo: np.ndarray | None = None, normal: np.ndarray | None = None) -> np.ndarray:
    """Denoise a linear HDR (H, W, 3) image with OIDN's "RT" filter; returns float32 (H, W, 3).

    ``albedo`` (values in [0, 1]) and ``normal`` (in [-1, 1]) are optional feature images of the same
    size; OIDN prefilters them (they may be noisy). Non-finite or negative input is rejected.
    """
    require()
    import pyoidn

    color = np.ascontiguousarray(image, dtype=np.float32)
    if color.ndim != 3 or color.shape[2] != 3:
        raise ValueError(f"denoise: image must be (H, W, 3), got shape {color.shape}")
    if not np.isfinite(color).all() or (color < 0).any():
        raise ValueError("denoise: image must be finite and non-negative (linear radiance)")
    aux = {}
    for name, buf in (("albedo", albedo), ("normal", normal)):
        if buf is not None:
            a = np.ascontiguousarray(buf, dtype=np.float32)
            if a.shape != color.shape:
                raise ValueError(f"denoise: {name} must have the image's shape {color.shape}, got {a.shape}")
            aux[name] = a
    if "normal" in aux and "albedo" not in aux:
        raise ValueError("denoise: OIDN takes a normal image only together with an albedo image")
    return np.asarray(pyoidn.denoise(color, aux.get("albedo"), aux.get("normal"), hdr=True), dtype=np.float32)
