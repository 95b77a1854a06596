"""The one pass schedule: which samples each launch adds, in which order, for every renderer.

Images are bit-identical over threads, tiles, processes and machines because every pixel's float64
sum is built in a fixed order of passes that depends on the image size only. The tile renderer
(:mod:`warp_spt.rendering.tiles`), the cluster (which merges passes rendered on different machines)
and the progressive driver (batches) all take their passes from here.
"""

from __future__ import annotations

import numpy as np

PASS_SAMPLES = 8          # samples per launch: bounds the time between progress reports / Ctrl-C checks
TILE_PASS_WORK = 1 << 16  # ...but at least this many pixel-samples per launch, so tiny images with huge
                          # spp (1x1 at 2**20 spp: 131072 launches, ~3 s of launch overhead) are not
                          # launch-bound. Depends on the image size only: the image stays independent
                          # of tiles and threads.
DEFAULT_BATCHES = 8       # progressive renders: independent batches per pixel (the error estimate)
BATCH_PASS_WORK = 1 << 20  # progressive renders: pixel-samples per pass once the schedule has grown
                           # (about 4 s here)


def samples_per_pass(width: int, height: int) -> int:
    """Samples per launch of a plain render of a width x height image (depends on the size only)."""
    return max(PASS_SAMPLES, TILE_PASS_WORK // (width * height))


def pass_ranges(spp: int, width: int, height: int, sample_offset: int = 0) -> list[tuple[int, int]]:
    """A plain render's passes as (first sample index, sample count), in the order they enter the film."""
    per_pass = samples_per_pass(width, height)
    return [(sample_offset + s, min(per_pass, spp - s)) for s in range(0, spp, per_pass)]


def batch_seed(seed: int, batch: int) -> int:
    """The 32-bit seed of batch ``batch``: a bijective integer hash of (seed, batch) (splitmix-style)."""
    x = (int(seed) * 0x9E3779B97F4A7C15 + (batch + 1) * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    x = ((x ^ (x >> 30)) * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
    x = ((x ^ (x >> 27)) * 0x94D049BB133111EB) & 0xFFFFFFFFFFFFFFFF
    return (x ^ (x >> 31)) & 0xFFFFFFFF


def batch_counts(spp: int, batches: int) -> np.ndarray:
    """Samples per batch for a render of ``spp`` samples per pixel: as equal as possible, first ones first."""
    b = np.arange(batches)
    return spp // batches + (b < spp % batches).astype(np.int64)


def pass_samples(k: int, pixels: int, batches: int) -> int:
    """Samples per batch in progressive pass ``k`` >= 1: 1, 2, 4, ... up to about BATCH_PASS_WORK
    pixel-samples per pass.

    (Pass 0 renders 2 spp, one sample in each of the first two batches: the first error estimate.)"""
    cap = max(1, BATCH_PASS_WORK // max(1, pixels * batches))
    return int(min(1 << max(0, k - 1), cap))


# The cluster's batched renders (warp_spt.cluster.render_progressive) cut work into *units*: one
# pass of one batch each, batches in turn, so that a batch's film is always a plain render's.


def unit_passes(u: int, spp: int, per_pass: int, batches: int) -> tuple[int, tuple[int, int]]:
    """Unit ``u`` of a batched render of ``spp`` samples per pixel: (batch, (first sample, count)).

    Unit u covers samples [u * per_pass, (u + 1) * per_pass) of the whole render (the last unit
    may be short) and is pass ``u // batches`` of batch ``u % batches`` (``per_pass``:
    :func:`samples_per_pass` of the image).
    """
    return u % batches, ((u // batches) * per_pass, min(per_pass, spp - u * per_pass))


def batch_spp(units: int, spp: int, per_pass: int, batches: int) -> np.ndarray:
    """Samples per pixel of each batch after the first ``units`` units."""
    counts = np.zeros(batches, np.int64)
    for u in range(units):
        b, (_, count) = unit_passes(u, spp, per_pass, batches)
        counts[b] += count
    return counts
