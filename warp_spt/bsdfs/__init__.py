"""Material kinds: a registry of material models, dispatched at compile time on the kinds a scene uses.

Each kind is one module ``warp_spt.bsdfs.<name>`` with ``declare`` (host: the lobes and code
paths its rows need) and ``make(features, base)`` (its Warp functions: the contract in
``warp_spt.bsdfs.common``); ``MATERIAL_KINDS`` in ``warp_spt.scene.material_schema``
registers it by name, and the material table's ``kind`` column holds each row's index into that
tuple. Today: ``seed`` (the seed's model) and ``pbr`` (physically based, glTF metallic-roughness).

:func:`declare` turns a scene's used rows into the material part of its ``Features``;
:func:`make_materials` builds the functions for ``features.material_kinds``: with one kind they are
that kind's own functions (the generated code is the kind's, no test of the ``kind`` column); with
several, each function tests ``m.kind[sf.mat]`` against the kinds in turn, a chain of closures (as
``proctex.make_dispatch``), and calls that kind's function.
"""

from __future__ import annotations

import importlib
from types import SimpleNamespace

import numpy as np
import warp as wp

from warp_spt.bsdfs.common import BsdfSample, lobe_weight, make_color, to_local, to_world
from warp_spt.device.structs import Features, Materials, Textures
from warp_spt.accel.surface import Surface
from warp_spt.scene.material_schema import COLUMN, MATERIAL_KINDS
from warp_spt.scene.model import TEX_NONE

__all__ = ["KINDS", "BsdfSample", "declare", "lobe_weight", "make_materials", "to_local", "to_world"]

# name -> module, in MATERIAL_KINDS order (a kind's index is its value in the ``kind`` column)
KINDS = {name: importlib.import_module(f"{__name__}.{name}") for name in MATERIAL_KINDS}


def declare(table, rows: np.ndarray) -> tuple[tuple[str, ...], int, tuple[str, ...]]:
    """(kinds, lobes, flags) of the material ``rows`` a scene uses: the kinds in MATERIAL_KINDS
    order, the union of their declared lobes, and the sorted union of their declared code paths,
    with ``"cutout"`` where some row has holes (the shared opacity columns, ``bsdfs.cutout``)."""
    rows = np.asarray(rows, dtype=np.int64)
    kinds, lobes, flags = [], 0, set()
    slot = COLUMN["opacity"].slot
    if ((table.opacity[rows] < table.alpha_cutoff[rows]).any() or (table.tex[rows, slot] != TEX_NONE).any()):
        flags.add("cutout")
    for index, name in enumerate(MATERIAL_KINDS):
        mine = rows[table.kind[rows] == index]
        if len(mine):
            kl, kf = KINDS[name].declare(table, mine)
            kinds.append(name)
            lobes |= kl
            flags |= kf
    return tuple(kinds), lobes, tuple(sorted(flags))


def make_materials(features: Features) -> SimpleNamespace:
    """``color``, ``scalar``, ``emission`` and the contract's ``shade``, ``sample``, ``eval``, ``pdf``,
    ``albedo``, ``lobes`` as Warp functions for these features (see the module docs)."""
    base = make_color(features)
    kinds = [(MATERIAL_KINDS.index(name), KINDS[name].make(features, base)) for name in features.material_kinds]
    k = _dispatch(kinds)
    return SimpleNamespace(color=base.color, scalar=base.scalar, emission=base.emission, shade=k.shade,
                           sample=k.sample, eval=k.eval, pdf=k.pdf, albedo=k.albedo, lobes=k.lobes)


def _dispatch(kinds: list[tuple[int, SimpleNamespace]]) -> SimpleNamespace:
    """The functions of ``kinds`` [(index, functions)]: the first's where ``m.kind[sf.mat]`` is its
    index, else the rest's; the last kind takes every row that reaches it (rows hold only used kinds)."""
    index, first = kinds[0]
    if len(kinds) == 1:
        return first
    rest = _dispatch(kinds[1:])

    @wp.func
    def shade(m: Materials, t: Textures, sf: Surface) -> Surface:
        if m.kind[sf.mat] == index:
            return first.shade(m, t, sf)
        return rest.shade(m, t, sf)

    @wp.func
    def sample(m: Materials, t: Textures, sf: Surface, u_lobe: float, u_dir: wp.vec2, u_fresnel: float) -> BsdfSample:
        if m.kind[sf.mat] == index:
            return first.sample(m, t, sf, u_lobe, u_dir, u_fresnel)
        return rest.sample(m, t, sf, u_lobe, u_dir, u_fresnel)

    @wp.func
    def eval(m: Materials, t: Textures, sf: Surface, wi: wp.vec3) -> wp.vec3:
        if m.kind[sf.mat] == index:
            return first.eval(m, t, sf, wi)
        return rest.eval(m, t, sf, wi)

    @wp.func
    def pdf(m: Materials, t: Textures, sf: Surface, wi: wp.vec3) -> float:
        if m.kind[sf.mat] == index:
            return first.pdf(m, t, sf, wi)
        return rest.pdf(m, t, sf, wi)

    @wp.func
    def albedo(m: Materials, t: Textures, sf: Surface) -> wp.vec3:
        if m.kind[sf.mat] == index:
            return first.albedo(m, t, sf)
        return rest.albedo(m, t, sf)

    @wp.func
    def lobes(m: Materials, t: Textures, sf: Surface) -> int:
        if m.kind[sf.mat] == index:
            return first.lobes(m, t, sf)
        return rest.lobes(m, t, sf)

    return SimpleNamespace(shade=shade, sample=sample, eval=eval, pdf=pdf, albedo=albedo, lobes=lobes)
