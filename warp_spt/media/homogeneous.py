"""The homogeneous medium kind: the same coefficients everywhere inside its region."""

from __future__ import annotations

from types import SimpleNamespace

import warp as wp

from warp_spt.device.media_table import Media

NAME = "homogeneous"


def declare(medium) -> frozenset:
    """What a medium of this kind needs compiled in (``Features.media``): its name: no code path of its own."""
    return frozenset({NAME})


def make(features) -> SimpleNamespace:
    """``coefficients(media, m, x) -> (sigma_a, sigma_s)`` at point ``x`` of medium row ``m``, and
    ``segment(media, m, o, d, t, t_max) -> (t_end, sigma_bar)``: the majorant (per channel) that
    holds from ``t`` to ``t_end`` along the ray: the medium's own, up to ``t_max``."""

    @wp.func
    def coefficients(media: Media, m: int, x: wp.vec3):
        return media.sigma_a[m], media.sigma_s[m]

    @wp.func
    def segment(media: Media, m: int, o: wp.vec3, d: wp.vec3, t: float, t_max: float):
        return t_max, media.majorant[m]

    return SimpleNamespace(coefficients=coefficients, segment=segment)
