"""The lights as the integrators see them: one interface over the kinds a scene uses, dispatched
statically (``wp.static`` choices and a chain of closures, one per kind, as ``proctex.make_dispatch``:
a kind the features do not use compiles no code).

``make_lights(features, surface_at, emission)`` returns

* ``sample_li(geo, lights, x, u_pick, u) -> LightSample``: choose a light with ``u_pick`` and a point
  on it with ``u``, as seen from ``x``: point, direction, density (solid angle, choice included) and
  shadow-ray length, no radiance (the geometric half, without adjoint in path replay);
* ``le(geo, m, t, lights, ls, x) -> vec3``: the radiance arriving at ``x`` from the sampled point
  (an area light: the emission of its surface; an infinite light: its own ``le``);
* ``sample(...)``: both, the radiance in ``ls.li``;
* ``pdf_li(geo, lights, h, o, d) -> float``: the density with which ``sample_li`` from ``o`` would
  have given the hit ``h`` along ``d`` (0 for a surface that is not in the table);
* ``le_miss(lights, d)`` and ``pdf_miss(lights, d)``: the radiance of the infinite lights seen by a
  ray that misses the scene along ``d``, and the density with which ``sample_li`` gives ``d``;
* ``le_escaped(lights, d, depth)``: ``le_miss`` for a path's ray after ``depth`` hits (a camera ray
  sees an environment's background instead, where one is set);
* ``mis_li(ls, w) -> float``: the MIS weight of light sample ``ls`` given ``w``, its weight against
  the other technique (the BSDF, the phase function, a guide): 1 for a delta light's sample, which
  no sampled direction can meet, else ``w``. Every integrator that weighs light samples calls it.

(No ``from __future__ import annotations`` here: the chain's functions are annotated with closure
variables, which Warp must see as objects, not as strings.)
"""

from types import SimpleNamespace

import warp as wp

from warp_spt.device.structs import Features, Geometry, Materials, Textures
from warp_spt.accel.ray_queries import KIND_MISS, Hit
from warp_spt.emitters.base import KIND_PUNCTUAL, LightSample
from warp_spt.emitters.registry import KINDS
from warp_spt.emitters.table import Lights, pick_entry


def _sample_chain(levels):
    """``sample_entry(geo, lights, e, prob, x, u)``: entry ``e`` sampled by the kind that holds it;
    ``levels`` are (slot in KINDS, sample_li, infinite-light index or -1, delta-light index or -1)."""
    if not levels:
        @wp.func
        def no_light(geo: Geometry, lights: Lights, e: int, prob: float, x: wp.vec3, u: wp.vec2) -> LightSample:
            ls = LightSample()
            ls.pdf = 0.0
            return ls
        return no_light
    slot, sample_li, infinite, delta = levels[0]
    rest = _sample_chain(levels[1:])

    @wp.func(inline=True)
    def sample_entry(geo: Geometry, lights: Lights, e: int, prob: float, x: wp.vec3, u: wp.vec2) -> LightSample:
        k = e - lights.first[slot]
        if k >= 0 and k < lights.count[slot]:
            if wp.static(infinite >= 0):       # several infinite lights: ``le`` must know which one
                ls = sample_li(geo, lights, k, prob, x, u)
                ls.h.index = infinite
                return ls
            if wp.static(delta >= 0):          # several delta kinds: so must their ``radiance``
                ls = sample_li(geo, lights, k, prob, x, u)
                ls.h.face = delta
                return ls
            return sample_li(geo, lights, k, prob, x, u)
        return rest(geo, lights, e, prob, x, u)

    return sample_entry


def _pdf_chain(levels):
    """``pdf_hit(geo, lights, h, o, d)``: the density of the area kind whose hit kind ``h`` is."""
    if not levels:
        @wp.func
        def no_pdf(geo: Geometry, lights: Lights, h: Hit, o: wp.vec3, d: wp.vec3) -> float:
            return 0.0
        return no_pdf
    hit_kind, pdf_li = levels[0]
    rest = _pdf_chain(levels[1:])

    @wp.func(inline=True)
    def pdf_hit(geo: Geometry, lights: Lights, h: Hit, o: wp.vec3, d: wp.vec3) -> float:
        if h.kind == hit_kind:
            return pdf_li(geo, lights, h, o, d)
        return rest(geo, lights, h, o, d)

    return pdf_hit


def _miss_sum(funcs, zero):
    """``f(lights, d)``: the sum of ``funcs`` (the infinite lights' ``le`` or ``pdf_li``); one alone is
    returned as it is, so that the sum adds no operation."""
    if not funcs:
        @wp.func
        def nothing(lights: Lights, d: wp.vec3):
            return zero
        return nothing
    if len(funcs) == 1:
        return funcs[0]
    head = funcs[0]
    rest = _miss_sum(funcs[1:], zero)

    @wp.func(inline=True)
    def total(lights: Lights, d: wp.vec3):
        return head(lights, d) + rest(lights, d)

    return total


def _le_chain(levels):
    """``le_of(lights, ls)``: the radiance of the infinite light that gave the sample ``ls``."""
    if len(levels) == 1:
        le = levels[0][1]

        @wp.func(inline=True)
        def only(lights: Lights, ls: LightSample) -> wp.vec3:
            return le(lights, ls.dir)
        return only
    if not levels:
        @wp.func
        def none(lights: Lights, ls: LightSample) -> wp.vec3:
            return wp.vec3(0.0, 0.0, 0.0)
        return none
    index, le = levels[0]
    rest = _le_chain(levels[1:])

    @wp.func(inline=True)
    def le_of(lights: Lights, ls: LightSample) -> wp.vec3:
        if ls.h.index == index:
            return le(lights, ls.dir)
        return rest(lights, ls)

    return le_of


def _delta_chain(levels):
    """``radiance_of(lights, ls, x)``: the radiance of the delta kind that gave the sample ``ls``
    (``levels``: (index, radiance); one kind alone is called as it is, without the test)."""
    index, radiance = levels[0]
    if len(levels) == 1:
        return radiance
    rest = _delta_chain(levels[1:])

    @wp.func(inline=True)
    def radiance_of(lights: Lights, ls: LightSample, x: wp.vec3) -> wp.vec3:
        if ls.h.face == index:
            return radiance(lights, ls, x)
        return rest(lights, ls, x)

    return radiance_of


def _escaped(seen, miss_le):
    """``le_escaped(lights, d, depth)``: what a ray that misses the scene along ``d`` after ``depth``
    hits receives: ``le_miss``, except that a camera ray (depth 0) sees what an infinite kind's
    ``seen`` says (an environment's background). Without such a kind it is ``le_miss`` itself."""
    if not seen:
        @wp.func(inline=True)
        def plain(lights: Lights, d: wp.vec3, depth: int) -> wp.vec3:
            return miss_le(lights, d)
        return plain
    view = seen[0]

    @wp.func(inline=True)
    def escaped(lights: Lights, d: wp.vec3, depth: int) -> wp.vec3:
        le = miss_le(lights, d)
        if depth == 0:
            return view(lights, d, le)
        return le

    return escaped


def _entries(slots):
    """``entries(lights)``: how many table entries the kinds at ``slots`` (in KINDS) hold."""
    slot = slots[0]
    if len(slots) == 1:
        @wp.func(inline=True)
        def one(lights: Lights) -> int:
            return lights.count[slot]
        return one
    rest = _entries(slots[1:])

    @wp.func(inline=True)
    def total(lights: Lights) -> int:
        return lights.count[slot] + rest(lights)

    return total


def _place(i: int, group: list[int]) -> int:
    """Kind ``i``'s index in ``group`` (the infinite or the delta kinds) where the group has several
    (its samples must say which one gave them), else -1 (no tag: one kind's code is as it was)."""
    return group.index(i) if len(group) > 1 and i in group else -1


def make_lights(features: Features, surface_at, emission) -> SimpleNamespace:
    """The interface above for the kinds these features use (``surface_at`` and ``emission``: the
    integrator's surface and the materials' emission, which area lights radiate)."""
    made = [k.make(Lights, features) for k in KINDS]
    infinite = [i for i, k in enumerate(KINDS) if not k.area and not k.delta and k.present(features)]
    sampled = [(i, k, made[i]) for i, k in enumerate(KINDS) if k.sampled(features) and k.present(features)]
    # lights no ray meets (``punctual``): their samples share one hit kind, so with several such kinds
    # each sample is tagged with its kind's place among them, as an infinite light's is
    deltas = [i for i, k, f in sampled if k.delta]
    sample_entry = _sample_chain([(i, f.sample_li, _place(i, infinite), _place(i, deltas)) for i, k, f in sampled])
    pdf_hit = _pdf_chain([(k.hit_kind, f.pdf_li) for i, k, f in sampled if k.area])
    miss_pdf = _miss_sum([f.pdf_li for i, k, f in sampled if not k.area and not k.delta], 0.0)
    delta_radiance = _delta_chain([(n, made[i].radiance) for n, i in enumerate(deltas)]) if deltas else None
    miss_le = _miss_sum([made[i].le for i in infinite], wp.vec3(0.0, 0.0, 0.0))
    sample_le = _le_chain([(n, made[i].le) for n, i in enumerate(infinite)])
    le_escaped = _escaped([made[i].seen for i in infinite if hasattr(made[i], "seen")], miss_le)
    # Several infinite lights in the table (a map and a sky) overlap in every direction, and a ray that
    # misses meets them all (le_miss, weighed against pdf_miss by the BSDF's MIS): their samples are
    # then one technique, the mixture, with the summed radiance and the summed density, or the light
    # sample's weight would miss the other lights' density and the estimate be low. With one infinite
    # entry (every scene before) the kind's own density and radiance stay, bit for bit.
    sampled_infinite = [i for i, k, f in sampled if not k.area and not k.delta]
    mixed = len(sampled_infinite) > 1
    infinite_entries = _entries(sampled_infinite) if mixed else None

    @wp.func
    def sample_li(geo: Geometry, lights: Lights, x: wp.vec3, u_pick: float, u: wp.vec2) -> LightSample:
        """``sample`` without the radiance: the direction, density, shadow-ray length and point."""
        if lights.num_entries == 0:
            ls = LightSample()
            ls.pdf = 0.0
            return ls
        e = pick_entry(lights, u_pick)
        ls = sample_entry(geo, lights, e, lights.entry_prob[e], x, u)
        if wp.static(mixed):
            if ls.h.kind == KIND_MISS and ls.pdf > 0.0 and infinite_entries(lights) > 1:
                ls.pdf = miss_pdf(lights, ls.dir)
        return ls

    @wp.func(inline=True)
    def le(geo: Geometry, m: Materials, t: Textures, lights: Lights, ls: LightSample, x: wp.vec3) -> wp.vec3:
        """The radiance arriving at ``x`` from the sampled point ``ls`` (unoccluded). Inlined: called out
        of line, it copied the four scene structs it takes by value (the fast kernel 5% slower)."""
        if wp.static(delta_radiance is not None):
            if ls.h.kind == KIND_PUNCTUAL:
                return delta_radiance(lights, ls, x)
        if ls.h.kind == KIND_MISS:
            if wp.static(mixed):
                if infinite_entries(lights) > 1:      # the mixture's sample: every infinite light's radiance
                    return miss_le(lights, ls.dir)
            return sample_le(lights, ls)
        return emission(m, t, surface_at(geo, ls.h, x, ls.dir))

    @wp.func
    def sample(geo: Geometry, m: Materials, t: Textures, lights: Lights, x: wp.vec3, u_pick: float,
               u: wp.vec2) -> LightSample:
        """Choose a light with ``u_pick`` and a point on it with ``u``, as seen from ``x``: the
        direction, incident radiance ``li`` (0 where ``pdf`` is 0), density and shadow-ray length."""
        ls = sample_li(geo, lights, x, u_pick, u)
        if ls.pdf > 0.0:
            ls.li = le(geo, m, t, lights, ls, x)
        return ls

    @wp.func
    def pdf_li(geo: Geometry, lights: Lights, h: Hit, o: wp.vec3, d: wp.vec3) -> float:
        """Density with which ``sample_li`` from ``o`` would have produced the hit ``h`` along ``d``."""
        return pdf_hit(geo, lights, h, o, d)

    @wp.func
    def pdf_miss(lights: Lights, d: wp.vec3) -> float:
        """Density with which ``sample_li`` would have chosen the infinite lights in direction ``d``."""
        return miss_pdf(lights, d)

    @wp.func(inline=True)
    def le_miss(lights: Lights, d: wp.vec3) -> wp.vec3:
        """The radiance of the infinite lights (the sky) along ``d``, seen by a ray that misses."""
        return miss_le(lights, d)

    @wp.func(inline=True)
    def mis_li(ls: LightSample, w: float) -> float:
        """The MIS weight of light sample ``ls``: ``w``, or 1 for a delta light (no sampled direction
        meets it, so light sampling is its only technique). Without delta kinds: ``w`` itself."""
        if wp.static(delta_radiance is not None):
            if ls.h.kind == KIND_PUNCTUAL:
                return 1.0
        return w

    return SimpleNamespace(sample_li=sample_li, le=le, sample=sample, pdf_li=pdf_li, pdf_miss=pdf_miss,
                           le_miss=le_miss, le_escaped=le_escaped, mis_li=mis_li)


def detach_lights(light: SimpleNamespace) -> None:
    """Give the geometric half of ``light`` (from :func:`make_lights`: ``sample_li``, ``pdf_li``,
    ``pdf_miss``) zero adjoints. Path replay's own lights only (``warp_spt.diff.prb``): its light samples
    stay put (detached sampling) and its MIS weights carry no derivative, so these adjoints were
    computed and dropped, each after re-running its function's forward code (the spherical triangle
    sampler's several times per vertex, once per nesting level); ``le`` and ``le_miss``, which carry
    the emission and sky gradients, keep their adjoints. The tape, whose camera gradients move the
    shading points, keeps them all."""

    @wp.func_grad(light.sample_li)
    def adj_sample_li(geo: Geometry, lights: Lights, x: wp.vec3, u_pick: float, u: wp.vec2,
                      adj_ret: LightSample):
        pass

    @wp.func_grad(light.pdf_li)
    def adj_pdf_li(geo: Geometry, lights: Lights, h: Hit, o: wp.vec3, d: wp.vec3, adj_ret: float):
        pass

    @wp.func_grad(light.pdf_miss)
    def adj_pdf_miss(lights: Lights, d: wp.vec3, adj_ret: float):
        pass
