"""RenderSettings: everything a render needs besides the scene and the camera, and its validation.

:func:`check_args` is the one place that decides which settings a kernel may see; every renderer
(tiles, progressive, gradients, the cluster) calls it before anything is uploaded.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from typing import Any, Mapping

import numpy as np

from warp_spt.device.structs import Features
from warp_spt.integrators import DEFAULT_INTEGRATOR, get_integrator
from warp_spt.runtime.warp_init import check_device
from warp_spt.samplers import DEFAULT_SAMPLER, check_sampler
from warp_spt.scene import limits
from warp_spt.scene.sky import Sky

TILE_PIXELS = 4096        # pixels per launch
MAX_PIXELS = 1 << 28      # far beyond any sane image; guards the int32 pixel index in the kernel
SAMPLE_INDEX_LIMIT = 2**31 - 1   # the kernels' sample index is an int32


@dataclass(frozen=True)
class RenderSettings:
    """Everything a render needs besides the scene and the camera.

    ``spp`` samples per pixel starting at global sample index ``sample_offset`` (renders of disjoint
    sample ranges can be merged, see :class:`warp_spt.rendering.film.Film`); ``max_depth`` counts surface hits
    as in the seed; ``sky`` defaults to the seed's (blue) BlackSky; ``integrator`` and ``sampler`` are
    names from ``warp_spt.integrators.INTEGRATORS`` and ``warp_spt.samplers.SAMPLERS``;
    ``roulette_depth`` starts Russian roulette after that many hits (0: off; the seed integrator
    ignores it); ``threads`` defaults to every core; ``features`` overrides the scene's own feature set
    (a superset gives the same image, slower); ``device`` ("cpu", "cuda" or "cuda:N") is where a host
    Scene is uploaded and its kernels run (a DeviceScene keeps its own); on a CUDA device each pass is
    one launch over the whole image from one thread, whatever ``tile_pixels`` and ``threads`` say.
    ``integrator_options`` sets the integrator's parameters by name (``Integrator.params``, e.g.
    ``{"alpha": 0.25}`` for ``guided``; see ``warp_spt.integrators.describe_options``); the rest keep
    their defaults. It is read, never changed.

    ``roulette_depth`` stays a setting of its own, not an integrator option: it is a per-launch
    kernel input (``RenderParams``) that the fast, path-replay and tape kernels of ``nee`` share.
    """

    width: int = 500
    height: int = 500
    spp: int = 16
    max_depth: int = 6
    sky: Sky | None = None
    seed: int = 0
    integrator: str = DEFAULT_INTEGRATOR
    sampler: str = DEFAULT_SAMPLER
    roulette_depth: int = 0
    texture_filter: str = "nearest"
    sample_offset: int = 0
    threads: int | None = None
    tile_pixels: int = TILE_PIXELS
    features: Features | None = None
    device: str = "cpu"
    integrator_options: Mapping[str, Any] = field(default_factory=dict)


_SETTING_NAMES = {f.name for f in fields(RenderSettings)}


def settings_from(kw: dict) -> RenderSettings:
    """A :class:`RenderSettings` from keyword arguments; a TypeError names any unknown ones."""
    unknown = set(kw) - _SETTING_NAMES
    if unknown:
        raise TypeError(f"unknown render setting(s): {', '.join(sorted(unknown))}")
    return RenderSettings(**kw)


def _is_int(v) -> bool:
    """An integer that is not a bool (True is no image height)."""
    return isinstance(v, (int, np.integer)) and not isinstance(v, (bool, np.bool_))


def check_int(name: str, value, low: int, high: int | None = None) -> None:
    """ValueError naming ``name`` unless ``value`` is an integer (not a bool) in [low, high]."""
    if not _is_int(value) or value < low or (high is not None and value > high):
        where = f"in [{low}, {high}]" if high is not None else f">= {low}"
        raise ValueError(f"{name} must be an integer {where}, got {value!r}")


def check_args(rs: RenderSettings) -> None:
    """Raise ValueError naming the first setting of ``rs`` a kernel must not see (sizes, sample indices,
    seed, depths, threads, tile size, sky, texture filter, integrator and sampler names, the
    integrator's options, the device: a CUDA device this machine lacks); the bounds are
    :mod:`warp_spt.scene.limits`', the command line's and the viewer's too. Raises TypeError for a sky
    that is not a :class:`Sky`."""
    check_int("width", rs.width, 1)
    check_int("height", rs.height, 1)
    check_int("spp", rs.spp, 1, limits.MAX_SPP)
    check_int("max_depth", rs.max_depth, 1, limits.MAX_DEPTH)
    check_int("tile_pixels", rs.tile_pixels, 1, limits.MAX_TILE_PIXELS)
    if rs.width * rs.height > MAX_PIXELS:
        raise ValueError(f"width x height: an image of {rs.width}x{rs.height} pixels is too large (at most "
                         f"{MAX_PIXELS} pixels)")
    check_int("sample_offset", rs.sample_offset, 0)
    if rs.sample_offset + rs.spp > SAMPLE_INDEX_LIMIT:
        raise ValueError("sample indices must lie in [0, 2**31)")
    if not _is_int(rs.seed):
        raise ValueError(f"seed must be an integer, got {rs.seed!r}")
    check_int("roulette_depth", rs.roulette_depth, 0, limits.MAX_DEPTH)
    if rs.threads is not None:
        check_int("threads", rs.threads, 1, limits.MAX_THREADS)
    if rs.sky is not None and not isinstance(rs.sky, Sky):
        raise TypeError(f"sky must be a warp_spt.Sky (e.g. Sky.constant(1, 1, 1)) or None, got {rs.sky!r}")
    if rs.texture_filter not in ("nearest", "bilinear"):
        raise ValueError(f"texture_filter must be 'nearest' or 'bilinear', got {rs.texture_filter!r}")
    get_integrator(rs.integrator).options(rs.integrator_options)    # unknown, ill-typed, out of range
    check_sampler(rs.sampler)
    check_device(rs.device)     # "cuda" where there is none: one line, before any upload


def check_rows(rows, height: int) -> None:
    """Raise ValueError unless ``rows`` is None or (first, stop) with 0 <= first < stop <= height."""
    if rows is not None and not (isinstance(rows, tuple) and len(rows) == 2
                                 and all(isinstance(r, (int, np.integer)) for r in rows)
                                 and 0 <= rows[0] < rows[1] <= height):
        raise ValueError(f"rows must be (first, stop) with 0 <= first < stop <= height, got {rows!r}")
