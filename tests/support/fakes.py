"""Stand-ins for warp_spt.rendering.tiles, so the CLI's wiring can be tested without rendering."""

from __future__ import annotations

import dataclasses
import types


def fake_renderer(render, dropped_samples: int = 0) -> types.SimpleNamespace:
    """A module with the renderer's CLI surface (RenderSettings, render_scene) around ``render``.

    ``render(scene, camera, **kw)`` receives the settings as keywords plus ``progress``, as the real
    :func:`warp_spt.rendering.tiles.render` does, and returns the image.
    """

    def render_scene(scene, camera, settings, *, progress=False):
        if dataclasses.is_dataclass(settings):      # the real RenderSettings: its fields as keywords
            settings = {f.name: getattr(settings, f.name) for f in dataclasses.fields(settings)}
        image = render(scene, camera, progress=progress, **settings)
        stats = types.SimpleNamespace(dropped_samples=dropped_samples)
        return types.SimpleNamespace(image=image, stats=stats)

    return types.SimpleNamespace(RenderSettings=lambda **kw: kw, render_scene=render_scene, render=render)
