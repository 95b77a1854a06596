"""Rendering: settings in, a result out, for every way of rendering.

``settings`` (RenderSettings, their validation), ``schedule`` (the one pass schedule that makes
images bit-identical over threads, tiles and machines), ``film`` (float64 sums), ``result``
(RenderResult, the one definition of relative error), ``tiles`` (render_scene on all cores),
``progressive`` (passes, budgets, error estimates, adaptive sampling), ``convergence`` (the error
report), ``aux_buffers`` and ``denoise`` (albedo/normal and Open Image Denoise).
"""
