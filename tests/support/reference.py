"""Independent reference implementations used by several tests (written from SEMANTICS.md, not from warp_spt)."""

from __future__ import annotations

import numpy as np


def literal_seed_search(x: float) -> int:
    """SEMANTICS §4 transcribed literally: float32 LUT, L=0, R=255, M=128, return the last M."""
    lut = [np.float32((i / 256) ** 2) if i <= 204 else np.float32(0.128 / (1 - i / 256)) for i in range(256)]
    xf = np.float32(x)
    lo, hi, mid = 0, 255, 128
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if lut[mid] < xf:
            lo = mid
        else:
            hi = mid
    return mid
