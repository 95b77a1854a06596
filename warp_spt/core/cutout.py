"""Cut-outs: surfaces with holes (a leaf's outline from its texture's alpha, ``map_d``, glTF's MASK).

Where a material's opacity (``opacity`` times its map's alpha) is below its ``alpha_cutoff``, the
surface is not there: closest-hit queries step through such points to the next surface, and shadow
rays pass them, so a leaf is seen through a leaf and casts a leaf-shaped shadow. Only scenes whose
material kinds declare ``"cutout"`` (``Features.needs``) compile this; the others get the plain
queries of ``core.geometry`` unchanged.

A ray crosses at most ``MAX_LAYERS`` holes (unrolled, so the tape differentiates it too); the
(MAX_LAYERS + 1)-th hole counts as a surface. A hole continues the ray from just behind the surface,
along the same direction, and the hit it reports keeps its distance from the original origin.
"""

from __future__ import annotations

from types import SimpleNamespace

import warp as wp

from warp_spt.core.geometry import KIND_MISS, NO_HIT, Hit, make_closest_hit, make_occluded
from warp_spt.core.materials import make_materials
from warp_spt.core.structs import Features, Geometry, Materials, Textures
from warp_spt.core.surface import Surface, make_surface, offset_origin
from warp_spt.scene.material_schema import COLUMN

MAX_LAYERS = 8
SLOT_OPACITY, CH_OPACITY = COLUMN["opacity"].slot, COLUMN["opacity"].channel


def make_hit(features: Features, differentiable: bool = False):
    """``hit(geo, mats, tex, o, d) -> Hit``: the closest surface that is there (``make_visibility``;
    ``differentiable``: the tape's re-intersected hits, ``geometry.make_closest_hit``)."""
    return _visibility(features, make_closest_hit(features, differentiable=differentiable), None).hit


def make_blocked(features: Features):
    """``blocked(geo, mats, tex, o, d, t_max) -> bool``: a surface that is there lies on the ray before
    ``t_max`` (a shadow ray; ``make_visibility``)."""
    return _visibility(features, make_closest_hit(features), make_occluded(features)).blocked


def _visibility(features: Features, closest_hit, occluded) -> SimpleNamespace:
    """The two queries over ``core.geometry``'s (the materials and surface only where cut-outs are)."""
    if not features.needs("cutout"):
        return make_visibility(features, closest_hit, occluded, None, None)
    return make_visibility(features, closest_hit, occluded, make_surface(features), make_materials(features))


def make_visibility(features: Features, closest_hit, occluded, surface_at, mat) -> SimpleNamespace:
    """``hit(geo, mats, tex, o, d) -> Hit`` and ``blocked(geo, mats, tex, o, d, t_max) -> bool``: the
    closest surface that is there and whether any is, over ``closest_hit``/``occluded`` (from
    ``core.geometry``); ``surface_at`` and ``mat`` (``make_materials``) read the opacity."""
    if not features.needs("cutout"):

        @wp.func
        def hit(geo: Geometry, mats: Materials, tex: Textures, o: wp.vec3, d: wp.vec3) -> Hit:
            return closest_hit(geo, o, d, NO_HIT)

        @wp.func
        def blocked(geo: Geometry, mats: Materials, tex: Textures, o: wp.vec3, d: wp.vec3, t_max: float) -> bool:
            return occluded(geo, o, d, t_max)

        return SimpleNamespace(hit=hit, blocked=blocked)

    @wp.func
    def solid(mats: Materials, tex: Textures, sf: Surface) -> bool:
        k = sf.mat
        a = mat.scalar(tex, mats.tex[k][wp.static(SLOT_OPACITY)], wp.static(CH_OPACITY), mats.opacity[k], sf)
        return a >= mats.alpha_cutoff[k]

    @wp.func
    def hit(geo: Geometry, mats: Materials, tex: Textures, o: wp.vec3, d: wp.vec3) -> Hit:
        h = closest_hit(geo, o, d, NO_HIT)
        start = o
        travelled = float(0.0)
        done = int(0)
        for _layer in range(wp.static(MAX_LAYERS)):
            if done == 0:
                if h.kind == KIND_MISS:
                    done = 1
                else:
                    sf = surface_at(geo, h, start, d)
                    if solid(mats, tex, sf):
                        done = 1
                    else:
                        nxt = offset_origin(sf.p, sf.ng, 1, geo.extent)
                        travelled = travelled + wp.dot(nxt - start, d)
                        start = nxt
                        h = closest_hit(geo, start, d, NO_HIT)
        out = h
        if h.kind != KIND_MISS:
            out.t = h.t + travelled
        return out

    @wp.func
    def blocked(geo: Geometry, mats: Materials, tex: Textures, o: wp.vec3, d: wp.vec3, t_max: float) -> bool:
        start = o
        left = t_max
        for _layer in range(wp.static(MAX_LAYERS + 1)):
            if left <= 0.0:
                return False
            h = closest_hit(geo, start, d, left)
            if h.kind == KIND_MISS:
                return False
            sf = surface_at(geo, h, start, d)
            if solid(mats, tex, sf):
                return True
            nxt = offset_origin(sf.p, sf.ng, 1, geo.extent)
            left = left - wp.dot(nxt - start, d)
            start = nxt
        return True

    return SimpleNamespace(hit=hit, blocked=blocked)
