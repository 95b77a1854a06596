"""A progress bar for renders: tqdm, counted in samples, usable from the CLI, Python and Jupyter."""

from __future__ import annotations

import sys
from typing import TextIO


class ProgressBar:
    """Adapts the renderer's ``(done_units, total_units)`` callback to a tqdm bar counted in samples.

    Counting samples (pixels x spp) makes tqdm show the rate as samples/s and an ETA. tqdm.auto
    draws a widget in Jupyter and text on stderr elsewhere; ``delay`` keeps quick renders silent.
    """

    def __init__(self, total_samples: int, *, file: TextIO | None = None, delay: float = 0.5):
        self.total_samples = int(total_samples)
        self._file = file
        self._delay = delay
        self._bar = None

    def __call__(self, done: int, total: int) -> None:
        if self._bar is None:
            from tqdm.auto import tqdm  # lazy: tqdm.auto probes for Jupyter when imported
            file = self._file or sys.stderr
            # Redrawing is for terminals and notebooks; into a log file, a line every 15 s is plenty.
            live = "notebook" in tqdm.__module__ or getattr(file, "isatty", lambda: False)()
            self._bar = tqdm(total=self.total_samples, unit="sample", unit_scale=True, desc="rendering",
                             file=file, delay=self._delay, dynamic_ncols=True,
                             mininterval=0.1 if live else 15.0)
        target = self.total_samples if total <= 0 else round(self.total_samples * min(done, total) / total)
        if target > self._bar.n:
            self._bar.update(target - self._bar.n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()
