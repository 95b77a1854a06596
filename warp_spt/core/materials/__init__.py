"""Material kinds: a registry of material models, dispatched at compile time on the kinds a scene uses.

Each kind is one module ``warp_spt.core.materials.<name>`` whose ``make(features, color)`` returns its
Warp functions (the interface: ``warp_spt.core.materials.common``); ``MATERIAL_KINDS`` in
``warp_spt.scene.material_schema`` registers it by name, and the material table's ``kind`` column
holds each row's index into that tuple. Today there is one kind, ``seed`` (the seed's model).

:func:`make_materials` builds the functions for ``features.material_kinds``, the kinds the scene uses:
with one kind they are that kind's own functions (the generated code is the kind's, no test of the
``kind`` column); with several, each function tests ``m.kind[sf.mat]`` against the kinds in turn,
a chain of closures (as ``proctex.make_dispatch``), and calls that kind's function.
"""

from __future__ import annotations

import importlib
from types import SimpleNamespace

import warp as wp

from warp_spt.core.device_scene import Features, Materials, Textures
from warp_spt.core.materials.common import BsdfSample, lobe_weight, make_color
from warp_spt.core.surface import Surface
from warp_spt.scene.material_schema import MATERIAL_KINDS

__all__ = ["KINDS", "BsdfSample", "lobe_weight", "make_materials"]

# name -> module, in MATERIAL_KINDS order (a kind's index is its value in the ``kind`` column)
KINDS = {name: importlib.import_module(f"{__name__}.{name}") for name in MATERIAL_KINDS}


def make_materials(features: Features) -> SimpleNamespace:
    """``color``, ``emission``, ``sample``, ``eval``, ``pdf``, ``has_density`` as Warp functions for
    these features (see the module docs)."""
    base = make_color(features)
    kinds = [(MATERIAL_KINDS.index(name), KINDS[name].make(features, base.color))
             for name in features.material_kinds]
    k = _dispatch(kinds)
    return SimpleNamespace(color=base.color, emission=base.emission, sample=k.sample, eval=k.eval, pdf=k.pdf,
                           has_density=k.has_density)


def _dispatch(kinds: list[tuple[int, SimpleNamespace]]) -> SimpleNamespace:
    """The functions of ``kinds`` [(index, functions)]: the first's where ``m.kind[sf.mat]`` is its
    index, else the rest's; the last kind takes every row that reaches it (rows hold only used kinds)."""
    index, first = kinds[0]
    if len(kinds) == 1:
        return first
    rest = _dispatch(kinds[1:])

    @wp.func
    def sample(m: Materials, t: Textures, sf: Surface, d: wp.vec3, u_lobe: float, u_dir: wp.vec2,
               u_fresnel: float) -> BsdfSample:
        if m.kind[sf.mat] == index:
            return first.sample(m, t, sf, d, u_lobe, u_dir, u_fresnel)
        return rest.sample(m, t, sf, d, u_lobe, u_dir, u_fresnel)

    @wp.func
    def eval(m: Materials, t: Textures, sf: Surface, wi: wp.vec3) -> wp.vec3:
        if m.kind[sf.mat] == index:
            return first.eval(m, t, sf, wi)
        return rest.eval(m, t, sf, wi)

    @wp.func
    def pdf(m: Materials, sf: Surface, wi: wp.vec3) -> float:
        if m.kind[sf.mat] == index:
            return first.pdf(m, sf, wi)
        return rest.pdf(m, sf, wi)

    @wp.func
    def has_density(m: Materials, sf: Surface) -> bool:
        if m.kind[sf.mat] == index:
            return first.has_density(m, sf)
        return rest.has_density(m, sf)

    return SimpleNamespace(sample=sample, eval=eval, pdf=pdf, has_density=has_density)
