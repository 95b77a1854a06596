"""What every light kind shares: the record a kind registers (:class:`LightKind`), the sample it
returns (:class:`LightSample`), and host helpers for building its part of the light table.

A kind is one module of this package (``triangle``, ``sphere``, ``sky``) exporting ``KIND``, a
:class:`LightKind`; ``registry.KINDS`` lists them, and that order is the order of their entries in
the light table (``table``) and of their fields in the device struct ``table.Lights``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
import warp as wp

from warp_spt.device.structs import Features
from warp_spt.accel.ray_queries import Hit
from warp_spt.accel.surface import offset_eps
from warp_spt.device.textures import checker_np, sample_texture_np
from warp_spt.scene.model import SLOT_EMISSION, TEX_CHECKER, TEX_PROC_BASE, Scene
from warp_spt.scene.sky import Sky


# the hit kind of a sample of a light no ray can meet (``punctual``: sun, point, spot): MIS weight 1
KIND_PUNCTUAL = wp.constant(-2)


@wp.struct
class LightSample:
    """A sampled light direction: incident radiance, density (solid angle, choice included), and
    how far a shadow ray must stay clear (just short of the emitter)."""

    dir: wp.vec3
    li: wp.vec3
    pdf: float
    t_max: float
    h: Hit            # the point on the emitter (kind KIND_MISS: an infinite light), where ``le`` looks



@wp.func
def sample_at(h: Hit, pl: wp.vec3, x: wp.vec3, spherical: bool, sel_solid: float, omega: float, sel_area: float,
              area2: float, extent: float) -> LightSample:
    """The sample of point ``pl`` of an emitting triangle (``h``: its hit, but for ``t``) seen from
    ``x``, drawn by solid angle (density ``sel_solid / omega``) or by area (``sel_area`` per twice the
    area ``area2``, turned into solid angle): ``sel_*`` are the choice probabilities, the
    triangle's and any part's within it. Density 0 where the point is x itself or seen edge-on."""
    ls = LightSample()
    ls.pdf = 0.0
    dist = wp.length(pl - x)
    if dist <= 0.0:
        return ls
    ls.dir = (pl - x) / dist
    cos_l = wp.abs(wp.dot(h.normal, ls.dir))
    if cos_l < 1.0e-7:
        return ls
    ls.h = h
    ls.h.t = dist
    if spherical:
        ls.pdf = sel_solid / omega
    else:
        ls.pdf = sel_area / (0.5 * area2) * dist * dist / cos_l
    ls.t_max = dist - offset_eps(pl, extent) / wp.max(cos_l, 0.05)
    return ls

@dataclass(frozen=True)
class Weighed:
    """A kind's entries in the light table: their choice weights (float64, all > 0) and whatever its
    ``upload`` needs to describe them on the device."""

    weights: np.ndarray
    payload: Any = None


@dataclass(frozen=True)
class LightKind:
    """One kind of light, as registered in ``registry.KINDS``.

    * ``name``: its field in ``table.Lights`` (``lights.<name>``), of type ``data``, a wp.struct
      (its entries in the table are ``lights.first[i]``, ``lights.count[i]``, i its place in KINDS).
    * ``hit_kind``: the ``geometry`` hit kind it is found as (KIND_MISS for an infinite light).
    * ``area``: an area light, whose radiance is the emission of the surface it is (the materials'
      ``emission`` at ``surface_at``, shared by all area kinds); otherwise an infinite light, which
      gives ``le(lights, d)`` itself and is seen by every ray that misses the scene (its ``le`` is
      compiled in whatever the features: a dark one is black).
    * ``declare(scene, used, base) -> names`` (host, once per scene): what the kind needs from a scene
      (``Features.lights``): its own name where the scene gives it entries in the light table, and
      "NAME.PATH" for a code path of its own (``used``: the material rows the scene's geometry uses;
      ``base``: the scene's other features). ``declare_sky(sky) -> names``: the same from the sky of
      a render (the infinite lights). The upload and the render set-up ask every kind in turn.
    * ``sampled(features)``: its sampling code is compiled in (it can be in the table): by default
      where the features name it (``Features.lit``).
    * ``weigh(scene, sky) -> Weighed`` (host): its entries and their weights (``cache``: they do not
      depend on the sky and are computed once per scene).
    * ``upload(payload, prob, scene, sky, up, device) -> data`` (host): its device data, with
      ``prob`` its entries' choice probabilities (float64) and ``up`` the sky's up axis.
    * ``make(Lights, features) -> namespace`` (device) with ``sample_li(geo, lights, k, prob, x, u)
      -> LightSample`` (entry ``k`` of its own, chosen with probability ``prob``: point, direction,
      density, shadow-ray length) and ``pdf_li``: ``(geo, lights, h, o, d) -> float`` for an area
      light (the density with which sampling from ``o`` would give the hit ``h``), ``(lights, d)``
      for an infinite one, which also gives ``le(lights, d) -> vec3``. Densities include the choice.
    * ``present(features)``: its code is compiled in at all (an infinite light that these features
      lack is not even looked at by rays that miss; its ``le`` is then no part of the kernel).
    * ``params``: the field of ``data`` holding its differentiable parameters, an array whose rows
      ``diff.params`` names (e.g. the sky's colours), or None; ``pathwise``: those of its parameter
      fields that move directions (a light's position), whose derivative needs a pathwise kernel
      (the tape or ``diff.replay_pathwise``).
    * ``delta``: no ray can meet it (its samples have hit kind KIND_PUNCTUAL, its ``hit_kind``): the
      dispatch's ``le`` asks its ``radiance(lights, ls, x)``, and neither a miss nor a hit counts it.
      Several delta kinds may be compiled in: the dispatch then tells their samples apart by the
      sample's ``h.face``, which it sets (a delta kind's ``sample_li`` must not need it).
    """

    name: str
    data: Any
    hit_kind: int
    area: bool
    weigh: Callable[[Scene, Sky], Weighed]
    upload: Callable[..., Any]
    make: Callable[..., Any]
    declare: Callable[..., frozenset] = lambda scene, used, base: frozenset()
    declare_sky: Callable[[Sky], frozenset] = lambda sky: frozenset()
    sampled: Callable[[Features], bool] | None = None
    cache: bool = True
    params: str | None = None
    present: Callable[[Features], bool] = lambda features: True
    delta: bool = False
    pathwise: frozenset = frozenset()

    def __post_init__(self):
        if self.sampled is None:
            object.__setattr__(self, "sampled", lambda features: features.lit(self.name))


def device_array(x, dtype, np_dtype, device: str) -> wp.array:
    """``x`` on the device (one zero element if empty: Warp structs need an array)."""
    return wp.array(np.ascontiguousarray(x if len(x) else np.zeros(1), dtype=np_dtype), dtype=dtype, device=device)


def mean_emission(scene: Scene, mat: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Mean over the RGB channels of each item's emission, at uv points (items, points, 2): the
    radiance part of an area light's choice weight."""
    mt = scene.materials
    out = mt.emission[mat].astype(np.float64).mean(axis=1)
    tex = mt.tex[mat, SLOT_EMISSION]
    for k in np.unique(tex[tex != -1]):
        sel = tex == k
        if k <= TEX_PROC_BASE:     # procedural: not known on the host; sampled by area (still unbiased)
            out[sel] = 1.0
            continue
        pts = uv[sel].reshape(-1, 2)
        vals = checker_np(pts) if k == TEX_CHECKER else sample_texture_np(scene.textures[k], pts)
        out[sel] = vals.reshape(sel.sum(), -1, 3).mean(axis=(1, 2))
    return out


def emitting_rows(scene: Scene) -> np.ndarray:
    """Per material row: it emits (a colour or an emission texture, procedural ones included)."""
    mt = scene.materials
    tex = mt.tex[:, SLOT_EMISSION]
    return (mt.emission > 0).any(axis=1) | (tex >= 0) | (tex <= TEX_PROC_BASE)
