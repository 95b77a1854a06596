"""The Jupyter host: an anywidget running the same front end (``static/viewer.js``) as the page.

    from warp_spt.viewer import Viewer
    viewer = Viewer(scene)          # or Viewer(objs=["model.obj"], up="y"); the demo with no arguments
    viewer                          # the live view; drag, scroll, double-click, change settings
    viewer.camera                   # the current warp_spt.Camera, for warp_spt.render(...)

Messages travel as the widget's custom messages (JSON plus binary buffers), the same protocol the
browser page speaks over its WebSocket. The render thread sends frames while the kernel is idle
or busy; what the page sends is handled whenever the kernel is idle. Needs the ``view`` extra
(anywidget, ipywidgets).
"""

from __future__ import annotations

from pathlib import Path
from typing import Sequence

import anywidget

from .session import open_session

STATIC = Path(__file__).resolve().parent / "static"


class Viewer(anywidget.AnyWidget):
    """A live, navigable view of a scene in a notebook; see the module docstring.

    Arguments as :func:`warp_spt.viewer.server.serve`: a :class:`warp_spt.Scene` (or ``objs`` /
    ``mtls`` files), a starting :class:`warp_spt.Camera`, ``up``, and
    :class:`~warp_spt.viewer.session.ViewSettings` fields (``width``, ``height``, ``integrator``...).
    """

    _esm = STATIC / "viewer.js"

    def __init__(self, scene=None, camera=None, *, objs: Sequence[str] = (), mtls: Sequence[str] = (),
                 up: str | None = None, **settings):
        super().__init__()
        self.session = open_session(scene, camera, objs=objs, mtls=mtls, up=up, **settings)
        self.session.add_listener(self._to_page)
        self.on_msg(self._from_page)

    def _to_page(self, message: dict, buffers: list) -> None:
        if self.comm is not None:             # closed widgets have no comm
            self.send(message, buffers=[memoryview(b) for b in buffers])

    def _from_page(self, _widget, content: dict, buffers) -> None:
        self.session.handle(content, buffers, reply=self._to_page)

    @property
    def camera(self):
        """The current view as a :class:`warp_spt.Camera`."""
        return self.session.camera

    def result(self):
        """The refined image so far (:meth:`Session.result`): a :class:`warp_spt.RenderResult`."""
        return self.session.result()

    def wait_for(self, spp: int = 1, timeout: float = 60.0):
        """Block until the view has ``spp`` samples per pixel; returns :meth:`result`."""
        return self.session.wait_for(spp, timeout)

    def command_line(self, width: int | None = None, height: int | None = None, spp: int = 64,
                     out: str = "view.png") -> str:
        """The ``warp-spt`` command rendering this view (:meth:`Session.command_line`)."""
        return self.session.command_line(width, height, spp, out)

    def save(self, path) -> None:
        """Write the refined image (:meth:`Session.save`)."""
        self.session.save(path)

    def close(self) -> None:
        """Stop rendering and close the widget."""
        self.session.close()
        super().close()
