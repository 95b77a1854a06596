"""The film: per-pixel float64 sample sums, merged exactly (its files: :func:`Film.save`/``load``).

Splitting and merging renders: a :class:`Film` stores per-pixel *sums* and the number of samples
per pixel. Renders of disjoint sample ranges (``render(..., sample_offset=...)``) can be produced on
different machines and merged with :meth:`Film.add`. Because every sample's random stream depends
only on (seed, pixel, sample index), the merged result is deterministic; it is bit-for-bit identical
to a single film that accumulated the same partial sums in the same order (float64 addition is not
associative, so merge in a fixed order, e.g. by increasing sample offset). Tone maps and image
files are :mod:`warp_spt.images.files`.
"""

from __future__ import annotations

import os
from typing import BinaryIO

import numpy as np

from warp_spt.images.files import atomic_write

FILM_FORMAT_VERSION = 1


# ---------------------------------------------------------------------------------------------
# Film


class Film:
    """Per-pixel float64 radiance sums ``sum`` (H, W, 3) over ``spp`` samples per pixel.

    ``Film(sums, spp)`` takes the array as it is (no copy when it is already float64): the film
    owns it from then on, and :meth:`add` / :meth:`accumulate` update it in place.
    """

    def __init__(self, sum: np.ndarray, spp: int = 0) -> None:  # noqa: A002 - the field's name
        a = np.ascontiguousarray(sum, dtype=np.float64)
        if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] < 1 or a.shape[1] < 1:
            raise ValueError(f"film sums must be (H, W, 3) with H, W >= 1, got shape {a.shape}")
        if int(spp) < 0:
            raise ValueError(f"spp must be >= 0, got {spp}")
        self.sum = a
        self.spp = int(spp)

    @classmethod
    def empty(cls, height: int, width: int) -> "Film":
        """A film of height x width pixels with no samples."""
        if height < 1 or width < 1:
            raise ValueError(f"film size must be at least 1x1, got {width}x{height}")
        return cls(np.zeros((height, width, 3), dtype=np.float64), 0)

    @property
    def shape(self) -> tuple[int, int]:
        return self.sum.shape[0], self.sum.shape[1]

    def accumulate(self, sample_sum: np.ndarray, spp: int) -> None:
        """Add a block of sums over ``spp`` further samples per pixel."""
        a = np.asarray(sample_sum, dtype=np.float64)
        if a.shape != self.sum.shape:
            raise ValueError(f"cannot accumulate sums of shape {a.shape} into a film of shape {self.sum.shape}")
        self.sum += a
        self.spp += int(spp)

    def add(self, other: "Film") -> None:
        """Merge another film of the same size (e.g. a disjoint sample range) into this one."""
        if other.sum.shape != self.sum.shape:
            raise ValueError(f"cannot merge a film of shape {other.sum.shape} into one of shape {self.sum.shape}")
        self.accumulate(other.sum, other.spp)

    def image(self) -> np.ndarray:
        """Mean radiance per pixel, float32 (H, W, 3)."""
        if self.spp <= 0:
            raise ValueError("film has no samples yet (spp == 0)")
        return (self.sum / self.spp).astype(np.float32)

    def save(self, path: str | os.PathLike) -> None:
        """Write sums and sample count to an ``.npz`` file (atomically)."""
        def write(f: BinaryIO) -> None:
            np.savez(f, sum=self.sum, spp=np.int64(self.spp), version=np.int64(FILM_FORMAT_VERSION))

        atomic_write(path, write)

    @classmethod
    def load(cls, path: str | os.PathLike) -> "Film":
        """Read a film written by :meth:`save`."""
        with np.load(path, allow_pickle=False) as data:
            missing = {"sum", "spp", "version"} - set(data.files)
            if missing:
                raise ValueError(f"{path}: not a film file (missing {sorted(missing)})")
            if int(data["version"]) != FILM_FORMAT_VERSION:
                raise ValueError(f"{path}: film format version {int(data['version'])}, expected {FILM_FORMAT_VERSION}")
            try:
                return cls(data["sum"], int(data["spp"]))
            except ValueError as exc:
                raise ValueError(f"{path}: {exc}") from None


# ---------------------------------------------------------------------------------------------
# Tone maps


# ---------------------------------------------------------------------------------------------
# Image files


