"""The homogeneous medium kind: the same coefficients everywhere inside its region."""

from __future__ import annotations

from types import SimpleNamespace

import warp as wp

from warp_spt.core.media.table import Media

NAME = "homogeneous"


def make(features) -> SimpleNamespace:
    """``coefficients(media, m, x) -> (sigma_a, sigma_s)`` at point ``x`` of medium row ``m``, and
    ``majorant(media, m) -> sigma_bar`` (per channel) over the whole medium."""

    @wp.func
    def coefficients(media: Media, m: int, x: wp.vec3):
        return media.sigma_a[m], media.sigma_s[m]

    @wp.func
    def majorant(media: Media, m: int) -> wp.vec3:
        return media.majorant[m]

    return SimpleNamespace(coefficients=coefficients, majorant=majorant)
