"""A live view for Jupyter: the image updating pass by pass, with the estimated error falling.

    from warp_spt.notebook import render_live
    result = render_live(scene, camera, width=256, height=256, time_budget=20)

Stop it with Jupyter's interrupt button (or Ctrl-C in a console): the render returns what it has
accumulated (``result.stats.stopped_by == "interrupt"``) instead of losing it. (A stop *button*
widget cannot work here: a busy kernel does not handle widget events until the cell finishes.)
Needs IPython (installed with Jupyter; extra ``[notebook]``); outside IPython it prints one line
per pass instead.
"""

from __future__ import annotations

import io
import math

import numpy as np

from warp_spt.rendering.progressive import render_progressive
from warp_spt.rendering.result import RenderResult


def _png(image: np.ndarray, tonemap: str, zoom: int) -> bytes:
    from PIL import Image

    from warp_spt.images.files import to_display

    img8 = to_display(image, tonemap)
    pil = Image.fromarray(img8)
    if zoom > 1:
        pil = pil.resize((pil.width * zoom, pil.height * zoom), Image.NEAREST)
    buf = io.BytesIO()
    pil.save(buf, format="PNG")
    return buf.getvalue()


def status_line(res: RenderResult) -> str:
    """'pass 3: 26 spp, 1.2 s, estimated relative error 4.1%' for a result."""
    lo, hi = int(res.spp.min()), int(res.spp.max())
    spp = f"{lo} spp" if lo == hi else f"{lo}..{hi} spp"
    err = "n/a" if not math.isfinite(res.relative_error) else f"{100 * res.relative_error:.2f}%"
    return (f"pass {res.stats.passes}: {spp}, {res.stats.seconds:.1f} s, estimated relative error {err}"
            + ("" if res.stats.stopped_by in ("spp",) else f" (stopped by {res.stats.stopped_by})"))


class LiveView:
    """Displays a result and updates it in place (IPython display ids); prints outside IPython."""

    def __init__(self, tonemap: str = "srgb", zoom: int = 1):
        self.tonemap, self.zoom = tonemap, zoom
        self._image = self._text = None
        try:
            from IPython import get_ipython
            self._ipython = get_ipython() is not None
        except ImportError:
            self._ipython = False

    def __call__(self, res: RenderResult) -> None:
        line = status_line(res)
        if not self._ipython:
            print(line)
            return
        from IPython.display import Image as IPImage
        from IPython.display import display

        img = IPImage(data=_png(res.image, self.tonemap, self.zoom), format="png")
        if self._image is None:
            self._image = display(img, display_id=True)
            self._text = display({"text/plain": line}, raw=True, display_id=True)
        else:
            self._image.update(img)
            self._text.update({"text/plain": line}, raw=True)


def render_live(scene, camera=None, *, tonemap: str = "srgb", zoom: int = 1, **kw) -> RenderResult:
    """:func:`warp_spt.rendering.progressive.render_progressive` with a live view; an interrupt keeps the partial image.

    Keyword arguments are render_progressive's (``time_budget``, ``target_error``, ``adaptive``, ...).
    """
    view = LiveView(tonemap, zoom)
    user = kw.pop("on_pass", None)

    def on_pass(res: RenderResult):
        view(res)
        return user(res) if user is not None else None

    res = render_progressive(scene, camera, on_pass=on_pass, keep_partial=True, **kw)
    view(res)
    return res
