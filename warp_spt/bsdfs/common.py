"""The material contract: what every material kind implements, and what the kinds share.

A material kind is a module ``warp_spt.bsdfs.<name>`` (named in
``warp_spt.scene.material_schema.MATERIAL_KINDS``) with two functions:

* ``declare(table, rows) -> (lobes, flags)``, host-side: for the material table's ``rows`` of this
  kind that a scene uses, the union of the lobe flags (``warp_spt.device.lobes``) they can produce and
  the code paths their kernel functions need (``Features.material_flags``, names prefixed by the kind,
  plus the shared ``"dims.lobe"``, ``"dims.fresnel"``: the random numbers the kind draws per bounce
  besides its direction's two; ``"frame"``, ``"frame.uv"``: a shading frame, following the uv;
  ``"cutout"``: holes). ``Features`` is the union over the scene's kinds.
* ``make(features, base) -> SimpleNamespace`` of Warp functions that read the material's row
  ``sf.mat`` of the table (``base``: :func:`make_color`'s colour look-ups):

  - ``shade(m: Materials, t: Textures, sf: Surface) -> Surface``: the shading point this material
    sees, called once per vertex before the others (normal and bump maps, a shading normal bent so
    that ``wo`` lies above it); the seed's returns ``sf``.
  - ``sample(m, t, sf, u_lobe: float, u_dir: vec2, u_fresnel: float) -> BsdfSample``: choose a lobe
    and a direction ``wi`` for ``sf.wo``;
  - ``eval(m, t, sf, wi: vec3) -> vec3``: f(wo, wi) |cos(ns, wi)| of the lobes that have a density;
  - ``pdf(m, t, sf, wi: vec3) -> float``: the solid-angle density of ``sample`` producing ``wi``;
  - ``albedo(m, t, sf) -> vec3``: the colour the denoiser's albedo pass records, in [0, 1];
  - ``lobes(m, t, sf) -> int``: the lobe flags present at this point; integrators light-sample and
    apply MIS where ``lobes & LOBE_SMOOTH`` (a lobe with a density), and continue a sample whose
    ``flags`` hold ``LOBE_SPECULAR`` as singular (the emitter it hits counts in full).

A kind may work in the local shading frame: :func:`to_local` / :func:`to_world` with the frame that
``surface_at`` built (``Features.needs("frame")``). Integrators read no material column: they see the
contract, the flags and ``Features`` alone.
"""

from __future__ import annotations

from types import SimpleNamespace

import warp as wp

from warp_spt.device.adjoint import zero_adjoint
from warp_spt.device.lobes import LOBE_SPECULAR, LOBE_TRANSMISSION
from warp_spt.device.proctex import make_dispatch, seed_checker
from warp_spt.device.structs import Features, Materials, Textures
from warp_spt.accel.surface import Surface
from warp_spt.device.textures import sample_texture
from warp_spt.scene.model import SLOT_EMISSION, TEX_CHECKER, TEX_NONE, TEX_PROC_BASE


@wp.func
def lobe_weight(p: float) -> float:
    """1 in value; in the adjoint, d/dp = 1/p (the score of a discrete choice made with probability p).

    Multiplying a lobe's weight by ``lobe_weight(prob of that lobe)`` leaves every image bit-identical
    and makes the differentiable kernel's derivative in the choice's probability correct in
    expectation: the choice ``u < p`` is a step for common random numbers, so its pathwise derivative
    is 0, and the score term p'/p restores d E[L] / d p (warp_spt.diff.gradients, tests/diff/test_gradients.py).
    """
    return 1.0


@wp.func_grad(lobe_weight)
def _adj_lobe_weight(p: float, adj_ret: float):
    wp.adjoint[p] += adj_ret / p


@wp.func
def held(x: float) -> float:
    """``x``, through which no derivative flows: a sampling density or choice probability held
    still. Differentiating f/p with the sampled direction and p held still is the derivative of the
    detached-sampling estimator, f'/p, unbiased for every parameter (Zeltner et al. 2021), in path
    replay and on the tape alike."""
    return x


zero_adjoint(held, (float,))


@wp.func
def held_dir(v: wp.vec3) -> wp.vec3:
    """A sampled direction held still (see :func:`held`)."""
    return v


zero_adjoint(held_dir, (wp.vec3,))


@wp.struct
class BsdfSample:
    """One sampled direction. ``weight`` = f cos / pdf (the throughput factor); ``pdf`` is the
    solid-angle density of the whole mixture for that direction (0 when ``singular``); ``flags``
    the lobe that produced it (``device.lobes``), from which ``singular`` (a specular lobe: no MIS for
    what it hits) and ``through`` (a transmission: the new ray starts on the other side) follow."""

    dir: wp.vec3
    weight: wp.vec3
    pdf: float
    singular: int      # 1: a specular (delta) lobe, no density: no MIS for what it hits
    alive: int         # 0: absorbed (below the surface)
    through: int       # 1: the ray passes through the surface (transmission)
    flags: int         # LOBE_* of the sampled lobe


@wp.func
def with_flags(bs: BsdfSample, flags: int) -> BsdfSample:
    """``bs`` with its lobe ``flags`` and the ``singular`` and ``through`` they imply."""
    out = bs
    out.flags = flags
    out.singular = wp.where((flags & LOBE_SPECULAR) != 0, 1, 0)
    out.through = wp.where((flags & LOBE_TRANSMISSION) != 0, 1, 0)
    return out


@wp.func
def to_local(sf: Surface, v: wp.vec3) -> wp.vec3:
    """``v`` in the shading frame: x along ``sf.t``, z along ``sf.ns``, y = z x x (right-handed)."""
    y = wp.cross(sf.ns, sf.t)
    return wp.vec3(wp.dot(v, sf.t), wp.dot(v, y), wp.dot(v, sf.ns))


@wp.func
def to_world(sf: Surface, v: wp.vec3) -> wp.vec3:
    """The inverse of :func:`to_local`."""
    y = wp.cross(sf.ns, sf.t)
    return sf.t * v[0] + y * v[1] + sf.ns * v[2]


def make_color(features: Features) -> SimpleNamespace:
    """``color``, ``texel`` and ``emission`` as Warp functions for the texture sources these features use
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
    def scalar(t: Textures, tex: int, channel: int, const: float, sf: Surface) -> float:
        """A scalar column: ``const`` times channel ``channel`` of its map where it has one (glTF
        multiplies a factor by its texture), else ``const``."""
        if tex == TEX_NONE:
            return const
        return const * color(t, tex, wp.vec3(1.0, 1.0, 1.0), sf)[channel]

    @wp.func
    def emission(m: Materials, t: Textures, sf: Surface) -> wp.vec3:
        """Emitted radiance, the same on both faces (the seed's emitters are two-sided)."""
        return color(t, m.tex[sf.mat][wp.static(SLOT_EMISSION)], m.emission[sf.mat], sf)

    return SimpleNamespace(color=color, scalar=scalar, emission=emission)
