"""Image losses for inverse rendering: each returns ``(value, adjoint)`` for an image.

A loss is any callable ``loss(image) -> (float, d loss / d image)`` on float (H, W, 3) arrays;
:func:`warp_spt.diff.gradients.render_gradients` takes one. The helpers here compare against a target
image, as means over all pixels and channels (so the value does not scale with the resolution).
"""

from __future__ import annotations

from typing import Callable

import numpy as np

Loss = Callable[[np.ndarray], "tuple[float, np.ndarray]"]


def _target(target) -> np.ndarray:
    t = np.asarray(target, dtype=np.float64)
    if t.ndim != 3 or t.shape[2] != 3 or not np.all(np.isfinite(t)):
        raise ValueError(f"target must be a finite (H, W, 3) image, got shape {t.shape}")
    return t


def _checked(image: np.ndarray, t: np.ndarray) -> np.ndarray:
    im = np.asarray(image, dtype=np.float64)
    if im.shape != t.shape:
        raise ValueError(f"image shape {im.shape} does not match the target's {t.shape}")
    return im - t


def l2(target) -> Loss:
    """Mean squared error against ``target``: mean((image - target)^2)."""
    t = _target(target)

    def loss(image: np.ndarray) -> tuple[float, np.ndarray]:
        r = _checked(image, t)
        return float(np.mean(r * r)), 2.0 * r / r.size
    return loss


def l1(target) -> Loss:
    """Mean absolute error against ``target``: mean(|image - target|) (sign(0) = 0)."""
    t = _target(target)

    def loss(image: np.ndarray) -> tuple[float, np.ndarray]:
        r = _checked(image, t)
        return float(np.mean(np.abs(r))), np.sign(r) / r.size
    return loss
