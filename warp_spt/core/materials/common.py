"""What every material kind shares: the sampled-direction record, the lobe-choice score, colour lookup.

A material kind is a module ``warp_spt.core.materials.<name>`` (named in
``warp_spt.scene.material_schema.MATERIAL_KINDS``) with ``make(features, color) -> SimpleNamespace``
of four Warp functions, which read the material's row ``sf.mat`` of the table:

* ``sample(m: Materials, t: Textures, sf: Surface, d: vec3, u_lobe: float, u_dir: vec2,
  u_fresnel: float) -> BsdfSample``: choose a lobe, sample a direction (``d`` the incoming ray);
* ``eval(m, t, sf, wi: vec3) -> vec3``: f(wi) cos of the lobes that have a density;
* ``pdf(m, sf, wi: vec3) -> float``: the solid-angle density of ``sample`` producing ``wi`` through them;
* ``has_density(m, sf) -> bool``: some lobe has a density, so light sampling and MIS apply here
  (the integrator, ``warp_spt.integrators.nee``, and the denoiser's albedo pass ask this).

``color(t, tex, const, sf) -> vec3`` (from :func:`make_color`) reads a colour column with its texture
slot. The kind's code may drop what the scene does not use with ``wp.static(features.<flag>)``.
"""

from __future__ import annotations

from types import SimpleNamespace

import warp as wp

from warp_spt.core.device_scene import Features, Materials, Textures
from warp_spt.core.proctex import make_dispatch, seed_checker
from warp_spt.core.surface import Surface
from warp_spt.core.textures import sample_texture
from warp_spt.scene.model import SLOT_EMISSION, TEX_CHECKER, TEX_PROC_BASE


@wp.func
def lobe_weight(p: float) -> float:
    """1 in value; in the adjoint, d/dp = 1/p (the score of a discrete choice made with probability p).

    Multiplying a lobe's weight by ``lobe_weight(prob of that lobe)`` leaves every image bit-identical
    and makes the differentiable kernel's derivative in ``Roughness`` correct in expectation: the
    choice ``u < Roughness`` is a step for common random numbers, so its pathwise derivative is 0,
    and the score term p'/p restores d E[L] / d Roughness (warp_spt.diff.gradients, tests/test_gradients.py).
    """
    return 1.0


@wp.func_grad(lobe_weight)
def _adj_lobe_weight(p: float, adj_ret: float):
    wp.adjoint[p] += adj_ret / p


@wp.struct
class BsdfSample:
    """One sampled direction. ``weight`` = f cos / pdf (the throughput factor); ``pdf`` is the
    solid-angle density of the whole mixture for that direction (0 when ``singular``)."""

    dir: wp.vec3
    weight: wp.vec3
    pdf: float
    singular: int      # 1: mirror/glass lobe, no density: no MIS for what it hits
    alive: int         # 0: absorbed (below the surface)
    through: int       # 1: the ray passes through the surface (refraction)


def make_color(features: Features) -> SimpleNamespace:
    """``color`` and ``emission`` as Warp functions for the colour sources these features use
    (textures, the checker, the procedural textures of Features.procedural)."""

    proc = make_dispatch(features.procedural)

    @wp.func
    def color(t: Textures, tex: int, const: wp.vec3, sf: Surface) -> wp.vec3:
        """A material colour: texture slot ``tex`` at the surface point if it has one, else ``const``."""
        if wp.static(features.textures):
            if tex >= 0:
                return sample_texture(t.texels, t.tiles, tex, sf.uv, t.bilinear)
        if wp.static(features.checker):
            if tex == TEX_CHECKER:
                return seed_checker(sf.uv, sf.p, sf.ns)
        if wp.static(len(features.procedural) > 0):
            if tex <= TEX_PROC_BASE:
                return proc(t.proc_kind, t.proc_params, TEX_PROC_BASE - tex, sf.uv, sf.p, sf.ns)
        return const

    @wp.func
    def emission(m: Materials, t: Textures, sf: Surface) -> wp.vec3:
        """Emitted radiance, the same on both faces (the seed's emitters are two-sided)."""
        return color(t, m.tex[sf.mat][wp.static(SLOT_EMISSION)], m.emission[sf.mat], sf)

    return SimpleNamespace(color=color, emission=emission)
