"""Cut-outs: surfaces with holes (a leaf's outline from its texture's alpha, ``map_d``, glTF's MASK).

Where a material's opacity (``opacity`` times its map's alpha) is below its ``alpha_cutoff``, the
surface is not there: closest-hit queries step through such points to the next surface, and shadow
rays pass them, so a leaf is seen through a leaf and casts a leaf-shaped shadow. Only scenes whose
material kinds declare ``"cutout"`` (``Features.needs``) compile this; the others get the plain
queries of ``accel.ray_queries`` unchanged.

A ray crosses at most ``MAX_LAYERS`` holes; the (MAX_LAYERS + 1)-th hole counts as a surface. A hole
continues the ray from just behind the surface, along the same direction, and the hit it reports keeps
its distance from the original origin. The first hit is the plain query's (on the tape, with its
derivatives); the layers behind a hole are one dynamic loop, so the kernel holds the traversal's code
twice, not once per layer (unrolled over 8 layers, the general kernel's CUDA compile ran past 40
CPU-minutes), and derivatives through a hit seen through a hole are not taken (docs/materials.md).
"""

from __future__ import annotations

from types import SimpleNamespace

import warp as wp

from warp_spt.accel.ray_queries import KIND_MISS, NO_HIT, Hit, make_closest_hit, make_occluded
from warp_spt.bsdfs import make_materials
from warp_spt.device.structs import Features, Geometry, Materials, Textures
from warp_spt.accel.surface import Surface, make_surface, offset_origin
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
    """The two queries over ``accel.ray_queries``'s (the materials and surface only where cut-outs are)."""
    if not features.needs("cutout"):
        return make_visibility(features, closest_hit, occluded, None, None)
    return make_visibility(features, closest_hit, occluded, make_surface(features), make_materials(features),
                           make_closest_hit(features))


def make_visibility(features: Features, closest_hit, occluded, surface_at, mat, plain_hit=None) -> SimpleNamespace:
    """``hit(geo, mats, tex, o, d) -> Hit`` and ``blocked(geo, mats, tex, o, d, t_max) -> bool``: the
    closest surface that is there and whether any is, over ``closest_hit``/``occluded`` (from
    ``accel.ray_queries``); ``surface_at`` and ``mat`` (``make_materials``) read the opacity; ``plain_hit``
    (default ``closest_hit``) traces past holes: the tape's re-intersecting query only for the first hit."""
    if plain_hit is None:
        plain_hit = closest_hit
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
    def beyond(geo: Geometry, mats: Materials, tex: Textures, o: wp.vec3, d: wp.vec3, first: Surface) -> Hit:
        """The first solid surface behind the hole ``first`` (a dynamic loop: one traversal's code)."""
        sf = first
        start = o
        travelled = float(0.0)
        h = Hit()
        h.kind = KIND_MISS
        h.t = NO_HIT
        layer = int(0)
        while layer < MAX_LAYERS:
            nxt = offset_origin(sf.p, sf.ng, 1, geo.extent)
            travelled = travelled + wp.dot(nxt - start, d)
            start = nxt
            h = plain_hit(geo, start, d, NO_HIT)
            if h.kind == KIND_MISS:
                return h
            sf = surface_at(geo, h, start, d)
            if solid(mats, tex, sf):
                break
            layer += 1
        h.t = h.t + travelled
        return h

    @wp.func
    def hit(geo: Geometry, mats: Materials, tex: Textures, o: wp.vec3, d: wp.vec3) -> Hit:
        h = closest_hit(geo, o, d, NO_HIT)
        if h.kind == KIND_MISS:
            return h
        sf = surface_at(geo, h, o, d)
        if solid(mats, tex, sf):
            return h
        return beyond(geo, mats, tex, o, d, sf)

    @wp.func
    def blocked(geo: Geometry, mats: Materials, tex: Textures, o: wp.vec3, d: wp.vec3, t_max: float) -> bool:
        start = o
        left = t_max
        layer = int(0)
        while layer <= MAX_LAYERS:
            if left <= 0.0:
                return False
            h = plain_hit(geo, start, d, left)
            if h.kind == KIND_MISS:
                return False
            sf = surface_at(geo, h, start, d)
            if solid(mats, tex, sf):
                return True
            nxt = offset_origin(sf.p, sf.ng, 1, geo.extent)
            left = left - wp.dot(nxt - start, d)
            start = nxt
            layer += 1
        return True

    return SimpleNamespace(hit=hit, blocked=blocked)
