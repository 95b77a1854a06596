"""Optional denoising with Intel Open Image Denoise (the ``pyoidn`` package, extra ``[denoise]``).

Never the default and never silent: the CLI and the convergence report call it only when asked
(``--denoise``) and say so. A denoised image is biased (it trades noise for blur); the convergence
report's "denoised" line measures its error against the reference, so users see that trade.

Feature buffers: OIDN is better with albedo and normal images of the first non-specular hit;
:func:`warp_spt.aux_buffers.feature_buffers` renders them, and the CLI and the convergence report
pass them. :func:`denoise` also works on colour alone.
"""

from __future__ import annotations

import numpy as np

INSTALL_HINT = 'denoising needs Intel Open Image Denoise: pip install "warp-spt[denoise]" (the pyoidn package)'


def available() -> bool:
    """True when pyoidn can be imported."""
    try:
        import pyoidn  # noqa: F401
    except ImportError:
        return False
    return True


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
