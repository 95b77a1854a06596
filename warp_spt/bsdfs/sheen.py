"""The sheen lobe of KHR_materials_sheen, as Khronos' glTF sample viewer draws it.

Estevez & Kulla's (2017) "Charlie" distribution with their fitted visibility (the sample viewer's
``D_Charlie`` and ``V_Sheen``), alpha = roughness^2, roughness held at or above the table's
``MIN_ROUGHNESS``. That visibility is a fit, not a masking function: below roughness 0.19 the lobe
reflects up to 1.6 times what it receives at grazing angles, so the lobe is divided by max(1,
E_RAW(mu_o), E_RAW(mu_i)) (E_RAW its own albedo): unchanged wherever it conserves energy, reciprocal,
and bounded by 1 everywhere. The tables (scripts/make_sheen_table.py) hold E_RAW and the divided
lobe's albedo ``albedo``, which the pbr kind's layering reads: the rest scaled by
1 - max(colour) albedo(mu_o), as the sample viewer does.
"""

from __future__ import annotations

import warp as wp

from warp_spt.bsdfs import sheen_table

_N = wp.constant(sheen_table.N)
_Table = wp.types.vector(length=sheen_table.N * sheen_table.N, dtype=wp.float32)
_RAW = wp.constant(_Table(*sheen_table.RAW))
_E = wp.constant(_Table(*sheen_table.E))
_MIN_R = wp.constant(sheen_table.MIN_ROUGHNESS)
_LAST = wp.constant(float(sheen_table.N - 1))
_TWO_PI = wp.constant(6.283185307179586)


@wp.func
def held_roughness(r: float) -> float:
    return wp.clamp(r, _MIN_R, 1.0)


@wp.func
def _lookup(table: _Table, mu: float, rough: float) -> float:
    """Bilinear in (sqrt(mu), roughness) over the 32 x 32 nodes (``rough`` held)."""
    x = wp.sqrt(wp.clamp(mu, 0.0, 1.0)) * _LAST
    y = wp.clamp((rough - _MIN_R) / (1.0 - _MIN_R), 0.0, 1.0) * _LAST
    i = wp.min(int(x), _N - 2)
    j = wp.min(int(y), _N - 2)
    fx = x - float(i)
    fy = y - float(j)
    k = i * _N + j
    e0 = table[k] * (1.0 - fy) + table[k + 1] * fy
    e1 = table[k + _N] * (1.0 - fy) + table[k + _N + 1] * fy
    return e0 * (1.0 - fx) + e1 * fx


@wp.func
def albedo(mu: float, rough: float) -> float:
    """The (divided) lobe's directional albedo with a white colour."""
    return _lookup(_E, mu, rough)


@wp.func
def _fit(x: float, alpha: float) -> float:
    t = (1.0 - alpha) * (1.0 - alpha)
    a = 21.5473 + 3.7772 * t
    b = 3.82987 - 0.50552 * t
    c = 0.19823 - 0.03022 * t
    d = -1.97760 + 0.70367 * t
    e = -4.32054 - 0.53913 * t
    return a / (1.0 + b * wp.pow(x, c)) + d * x + e


@wp.func
def _lambda(mu: float, alpha: float) -> float:
    if mu < 0.5:
        return wp.exp(_fit(mu, alpha))
    return wp.exp(2.0 * _fit(0.5, alpha) - _fit(1.0 - mu, alpha))


@wp.func
def value(wo: wp.vec3, wi: wp.vec3, rough: float) -> float:
    """f cos of the lobe with a white colour, local frame (normal +z), both directions above."""
    if wi[2] <= 0.0 or wo[2] <= 0.0:
        return 0.0
    alpha = rough * rough
    h = wp.normalize(wo + wi)
    d = (2.0 + 1.0 / alpha) * wp.pow(wp.max(1.0 - h[2] * h[2], 0.0), 0.5 / alpha) / _TWO_PI
    v = wp.clamp(1.0 / ((1.0 + _lambda(wo[2], alpha) + _lambda(wi[2], alpha)) * 4.0 * wo[2] * wi[2]), 0.0, 1.0)
    norm = wp.max(1.0, wp.max(_lookup(_RAW, wo[2], rough), _lookup(_RAW, wi[2], rough)))
    return d * v * wi[2] / norm
