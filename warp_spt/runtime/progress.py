"""A progress bar for renders: tqdm, counted in samples, usable from the CLI, Python and Jupyter."""


from __future__ import annotations

import sys
import warnings
from typing import Callable, TextIO


class ProgressBar:
    """Adapts the renderer's ``(done_units, total_units)`` callback to a tqdm bar counted in samples.

    Counting samples (pixels x spp) makes tqdm show the rate as samples/s and an ETA. The bar is a
    widget in Jupyter when ipywidgets is installed, text on stderr elsewhere (:func:`bar_class`);
    ``delay`` keeps quick renders silent.
    """

    def __init__(self, total_samples: int, *, file: TextIO | None = None, delay: float = 0.5):
        self.total_samples = int(total_samples)
        self._file = file
        self._delay = delay
        self._bar = None

    def __call__(self, done: int, total: int) -> None:
        if self._bar is None:
            tqdm = bar_class()
            file = self._file or sys.stderr
            # Redrawing is for terminals and notebooks (a widget, or text in a Jupyter kernel's stream);
            # into a log file, a line every 15 s is plenty.
            live = (_is_widget(tqdm) or type(file).__module__.startswith("ipykernel")
                    or getattr(file, "isatty", lambda: False)())
            self._bar = tqdm(total=self.total_samples, unit="sample", unit_scale=True, desc="rendering",
                             file=file, delay=self._delay, dynamic_ncols=True,
                             mininterval=0.1 if live else 15.0)
        target = self.total_samples if total <= 0 else round(self.total_samples * min(done, total) / total)
        if target > self._bar.n:
            self._bar.update(target - self._bar.n)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.close()


def bar_class() -> type:
    """tqdm.auto's choice of bar class (a widget in a Jupyter kernel, text elsewhere), made quietly.

    In a Jupyter kernel without ipywidgets, tqdm.auto falls back to its text bar but warns first
    (``TqdmWarning: IProgress not found``); the text bar is a fine progress display there, so that
    one warning is silenced (the ``notebook`` extra installs ipywidgets for the widget). Imported
    lazily: tqdm.auto probes for Jupyter when it is imported.
    """
    from tqdm.std import TqdmWarning

    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="IProgress not found", category=TqdmWarning)
        from tqdm.auto import tqdm
    return tqdm


def _is_widget(cls: type) -> bool:
    return any(c.__module__ == "tqdm.notebook" for c in cls.__mro__)


def progress_reporter(progress: bool | ProgressFn, total: int) -> Callable[[int | None], None]:
    """A progress sink for ``total`` units: a function taking increments (None closes it).

    ``progress`` is False/None (a no-op), True (a tqdm bar) or a callable ``(done, total)``, which is
    called with the running sum on the thread that reports.
    """
    if progress is False or progress is None:
        return lambda inc: None
    bar = None
    if not callable(progress):
        bar = progress = ProgressBar(total, delay=0.0)
    state = {"done": 0}

    def report(inc: int | None) -> None:
        if inc is None:
            if bar is not None:
                bar.close()
        elif inc:
            state["done"] += inc
            progress(state["done"], total)
    return report


ProgressFn = Callable[[int, int], None]
