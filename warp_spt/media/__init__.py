"""Participating media on the device: the media table, the medium kinds and the two trackers.

``make_media(features)`` builds, for the medium kinds a scene uses (``Features.media``):

* ``free_flight(media, m, o, d, t_max, hero, beta, w, rng)``: delta tracking from ``o`` along ``d``
  up to ``t_max`` (the next surface) through medium row ``m``, pbrt-v4's hero-wavelength scheme with
  the RGB channels as wavelengths: tentative collisions are drawn against the majorant of channel
  ``hero`` (drawn uniformly once per path), and absorption, scattering or a null collision chosen
  with that channel's probabilities. Each decision's density in every channel multiplies the path's
  spectral MIS state ``w`` (the path's densities per channel over their mean), and the throughput
  ``beta`` by the same factor over the mean: ``beta`` stays the path's contribution over the mean of
  its three channels' densities, the one-sample balance heuristic over which channel led, unbiased
  in every channel and at most 3 times a grey medium's weight. Emission is collected at every
  tentative collision. Returns (event, t, beta, w, emitted, rng): event ``EVENT_SURFACE`` (reached
  ``t_max``), ``EVENT_SCATTER`` (at ``t``) or ``EVENT_ABSORB`` (the path ends).
* ``transmittance(media, m, o, d, t_max, rng) -> (T, rng)``: ratio tracking: an unbiased estimate
  of exp(-integral of sigma_t) per channel, each tentative collision drawn from the three channels'
  majorants mixed (a channel chosen uniformly per step) and weighted by that mixture's density, with
  Russian roulette once the estimate is small.

A flight through a homogeneous medium with majorant 1 never meets a null collision: it is
pbrt-v4's hero-wavelength delta tracking with the RGB channels as wavelengths.

``make_media(features, diff=True)`` builds the same two trackers for path replay (docs/volumes.md,
Gradients): each also carries forward-mode derivatives with respect to the medium row's uploaded
``sigma_a`` and ``sigma_s`` (per channel: a channel's estimate depends on that channel's
coefficients alone), the decisions' densities held fixed (detached sampling). The majorant moves
with the coefficients (``majorant`` x sigma_t, per majorant cell for a grid), so the null-collision
integrand stays a valid one for every parameter value, majorant 1 included. ``free_flight`` then
returns a :class:`FlightDeriv` more; ``transmittance`` the derivative of its estimate with respect
to sigma_t (sigma_a and sigma_s alike) more.
"""

from __future__ import annotations

from types import SimpleNamespace

import warp as wp

from warp_spt.device.adjoint import zero_adjoint
from warp_spt.media.phase import hg, hg_eval, hg_sample  # noqa: F401 (re-exported)
from warp_spt.media.registry import KINDS, declare  # noqa: F401 (re-exported)
from warp_spt.device.media_table import Media
from warp_spt.media.upload import upload_media  # noqa: F401 (re-exported)
from warp_spt.scene.media import MEDIUM_KINDS
from warp_spt.device.sampling import hash_u32

EVENT_SURFACE = wp.constant(0)
EVENT_SCATTER = wp.constant(1)
EVENT_ABSORB = wp.constant(2)
_INF = wp.constant(1.0e30)
_ROULETTE_BELOW = wp.constant(0.1)
_PCG_MUL = wp.constant(wp.uint32(747796405))
_PCG_INC = wp.constant(wp.uint32(2891336453))      # ratio tracking's estimate below this: survive with p = 1/2


@wp.func
def next_u(state: wp.uint32):
    """(uniform in [0, 1), next state): the trackers' PCG stream (they draw unboundedly many)."""
    s = state * _PCG_MUL + _PCG_INC
    return float(hash_u32(s) >> wp.uint32(8)) * (1.0 / 16777216.0), s


@wp.func
def avg3(v: wp.vec3) -> float:
    return (v[0] + v[1] + v[2]) * (1.0 / 3.0)


@wp.func
def exp3(sigma: wp.vec3, t: float) -> wp.vec3:
    """exp(-sigma t) per channel; a zero sigma is 1 even at an infinite t."""
    out = wp.vec3(1.0, 1.0, 1.0)
    for c in range(3):
        if sigma[c] > 0.0:
            out[c] = wp.exp(-sigma[c] * wp.min(t, _INF))
    return out


@wp.func
def hero_step(maj: wp.vec3, rng: wp.uint32):
    """(distance to the next tentative collision, rng): exponential with a channel's majorant, the
    channel drawn uniformly (the mixture spectral MIS weighs against)."""
    u, r = next_u(rng)
    c = wp.min(int(u * 3.0), 2)
    u2, r2 = next_u(r)
    dt = float(_INF)
    if maj[c] > 0.0:
        dt = -wp.log(1.0 - u2) / maj[c]
    return dt, r2


_MAX_STEPS = wp.constant(1 << 20)       # a flight's steps: only a broken majorant grid comes near


@wp.struct
class FlightDeriv:
    """Derivatives of a free flight's results with respect to its medium row's ``sigma_a`` and
    ``sigma_s`` (the uploaded arrays, per channel): of the throughput it returns and of the emission
    it gathered."""

    beta_a: wp.vec3
    beta_s: wp.vec3
    emit_a: wp.vec3
    emit_s: wp.vec3


@wp.func
def ratio3(a: wp.vec3, b: wp.vec3) -> wp.vec3:
    """a / b per channel, 0 where b is 0."""
    out = wp.vec3(0.0, 0.0, 0.0)
    for c in range(3):
        if b[c] > 0.0:
            out[c] = a[c] / b[c]
    return out


def _dispatch(kinds: list[tuple[int, SimpleNamespace]]) -> SimpleNamespace:
    """``coefficients`` and ``segment`` of ``kinds`` [(index, functions)]: the first's where the medium
    row's ``kind`` is its index, else the rest's; one kind alone is called directly, and the last takes
    every row that reaches it (the rows hold only the features' kinds)."""
    index, first = kinds[0]
    if len(kinds) == 1:
        return first
    rest = _dispatch(kinds[1:])

    @wp.func
    def coefficients(media: Media, m: int, x: wp.vec3):
        if media.kind[m] == index:
            return first.coefficients(media, m, x)
        return rest.coefficients(media, m, x)

    @wp.func
    def segment(media: Media, m: int, o: wp.vec3, d: wp.vec3, t: float, t_max: float):
        if media.kind[m] == index:
            return first.segment(media, m, o, d, t, t_max)
        return rest.segment(media, m, o, d, t, t_max)

    return SimpleNamespace(coefficients=coefficients, segment=segment)


def make_media(features, diff: bool = False) -> SimpleNamespace:
    """The trackers (module docs) for ``features.media``'s kinds (dispatched on the medium row's kind,
    ``_dispatch``); ``diff``: with their derivatives, for path replay (module docs)."""
    kind = _dispatch([(i, KINDS[k].make(features)) for i, k in enumerate(MEDIUM_KINDS) if k in features.media])
    coefficients, segment = kind.coefficients, kind.segment
    emits = "emission" in features.media

    # free_flight and transmittance (and volpath's shadow_path) are called, not inlined: inlined at each
    # call site, NVRTC optimised one function of several thousand lines and the media kernel's CUDA
    # compile ran past an hour on 2 cores; called, it takes 35 CPU s (sm_75, every medium kind,
    # pass-through boundaries), and the CPU renders the same bits at the same speed (volpath, a chromatic
    # fog on the demo, 64x64 x 8 spp: 0.151-0.160 s inlined against 0.152-0.159 s called, CPU s, medians
    # of three alternated runs of 9)
    @wp.func(inline=False)
    def free_flight(media: Media, m: int, o: wp.vec3, d: wp.vec3, t_max: float, hero: int, beta: wp.vec3,
                    w: wp.vec3, rng: wp.uint32):
        t = float(0.0)
        b = beta
        mis = w
        emitted = wp.vec3(0.0, 0.0, 0.0)
        r = rng
        zero = wp.vec3(0.0, 0.0, 0.0)
        dv = FlightDeriv()
        sig = wp.vec3(0.0, 0.0, 0.0)
        if wp.static(diff):
            sig = media.sigma_a[m] + media.sigma_s[m]
        t_end, maj = segment(media, m, o, d, t, t_max)
        for step in range(_MAX_STEPS):
            u, r = next_u(r)
            dt = float(_INF)
            if maj[hero] > 0.0:
                dt = -wp.log(1.0 - u) / maj[hero]
            if t + dt >= t_end:
                g = exp3(maj, t_end - t)             # no collision in this segment: its probability
                s = avg3(wp.cw_mul(mis, g))
                if s <= 0.0:
                    if wp.static(diff):
                        return EVENT_ABSORB, t_end, zero, mis, emitted, r, FlightDeriv()
                    else:
                        return EVENT_ABSORB, t_end, zero, mis, emitted, r
                if wp.static(diff):
                    # d g / d sigma = -(length) d maj / d sigma g, with d maj / d sigma = maj / sigma_t
                    dg = wp.cw_mul(ratio3(maj, sig), g) * (-(t_end - t))
                    dv.beta_a = (wp.cw_mul(dv.beta_a, g) + wp.cw_mul(b, dg)) / s
                    dv.beta_s = (wp.cw_mul(dv.beta_s, g) + wp.cw_mul(b, dg)) / s
                b = wp.cw_mul(b, g) / s
                mis = wp.cw_mul(mis, g) / s
                t = t_end
                if t >= t_max:
                    if wp.static(diff):
                        return EVENT_SURFACE, t_max, b, mis, emitted, r, dv
                    else:
                        return EVENT_SURFACE, t_max, b, mis, emitted, r
                t_end, maj = segment(media, m, o, d, t, t_max)
                continue
            t += dt
            tm = exp3(maj, dt)
            sa, ss = coefficients(media, m, o + d * t)
            sn = wp.max(maj - sa - ss, wp.vec3(0.0, 0.0, 0.0))
            km = zero                 # d maj / d sigma (sigma_a and sigma_s alike)
            rho = zero                # d sigma_a(x) / d sigma_a = d sigma_s(x) / d sigma_s: the density
            dtm = zero
            if wp.static(diff):
                km = ratio3(maj, sig)
                rho = ratio3(sa + ss, sig)
                dtm = wp.cw_mul(km, tm) * (-dt)
            if wp.static(emits):
                pdf_e = avg3(wp.cw_mul(mis, wp.cw_mul(tm, maj)))
                le = media.emission[m]
                emitted += wp.cw_mul(b, wp.cw_mul(wp.cw_mul(tm, sa), le)) / pdf_e
                if wp.static(diff):
                    e_a = wp.cw_mul(wp.cw_mul(dv.beta_a, tm) + wp.cw_mul(b, dtm), sa) + wp.cw_mul(b, wp.cw_mul(tm, rho))
                    e_s = wp.cw_mul(wp.cw_mul(dv.beta_s, tm) + wp.cw_mul(b, dtm), sa)
                    dv.emit_a = dv.emit_a + wp.cw_mul(e_a, le) / pdf_e
                    dv.emit_s = dv.emit_s + wp.cw_mul(e_s, le) / pdf_e
            u2, r = next_u(r)
            x = u2 * maj[hero]
            g = wp.cw_mul(tm, sn)
            event = int(-1)
            if x < sa[hero]:
                if wp.static(diff):
                    return EVENT_ABSORB, t, zero, mis, emitted, r, dv
                else:
                    return EVENT_ABSORB, t, zero, mis, emitted, r
            if x < sa[hero] + ss[hero]:
                g = wp.cw_mul(tm, ss)
                event = EVENT_SCATTER
            s = avg3(wp.cw_mul(mis, g))
            if s <= 0.0:
                if wp.static(diff):
                    return EVENT_ABSORB, t, zero, mis, emitted, r, dv
                else:
                    return EVENT_ABSORB, t, zero, mis, emitted, r
            if wp.static(diff):
                dg_a = wp.cw_mul(dtm, sn) + wp.cw_mul(tm, km - rho)      # a null collision: g = tm sn
                dg_s = dg_a
                if event == EVENT_SCATTER:                                # g = tm ss
                    dg_a = wp.cw_mul(dtm, ss)
                    dg_s = dg_a + wp.cw_mul(tm, rho)
                dv.beta_a = (wp.cw_mul(dv.beta_a, g) + wp.cw_mul(b, dg_a)) / s
                dv.beta_s = (wp.cw_mul(dv.beta_s, g) + wp.cw_mul(b, dg_s)) / s
            b = wp.cw_mul(b, g) / s
            mis = wp.cw_mul(mis, g) / s
            if event == EVENT_SCATTER:
                if wp.static(diff):
                    return EVENT_SCATTER, t, b, mis, emitted, r, dv
                else:
                    return EVENT_SCATTER, t, b, mis, emitted, r
        if wp.static(diff):
            return EVENT_ABSORB, t, zero, mis, emitted, r, dv
        else:
            return EVENT_ABSORB, t, zero, mis, emitted, r

    @wp.func(inline=False)
    def transmittance(media: Media, m: int, o: wp.vec3, d: wp.vec3, t_max: float, rng: wp.uint32):
        t = float(0.0)
        T = wp.vec3(1.0, 1.0, 1.0)
        zero = wp.vec3(0.0, 0.0, 0.0)
        dT = zero                  # d T / d sigma_t (sigma_a and sigma_s alike)
        sig = zero
        if wp.static(diff):
            sig = media.sigma_a[m] + media.sigma_s[m]
        r = rng
        t_end, maj = segment(media, m, o, d, t, t_max)
        for step in range(_MAX_STEPS):
            dt, r = hero_step(maj, r)
            if t + dt >= t_end:
                tm = exp3(maj, t_end - t)
                if wp.static(diff):
                    dtm = wp.cw_mul(ratio3(maj, sig), tm) * (-(t_end - t))
                    dT = (wp.cw_mul(dT, tm) + wp.cw_mul(T, dtm)) / avg3(tm)
                T = wp.cw_mul(T, tm) / avg3(tm)
                t = t_end
                if t >= t_max:
                    if wp.static(diff):
                        return T, r, dT
                    else:
                        return T, r
                t_end, maj = segment(media, m, o, d, t, t_max)
                continue
            t += dt
            tm = exp3(maj, dt)
            pdf = avg3(wp.cw_mul(maj, tm))
            sa, ss = coefficients(media, m, o + d * t)
            sn = wp.max(maj - sa - ss, zero)
            if wp.static(diff):
                km = ratio3(maj, sig)
                dsn = km - ratio3(sa + ss, sig)
                dtm = wp.cw_mul(km, tm) * (-dt)
                dT = (wp.cw_mul(dT, wp.cw_mul(tm, sn)) + wp.cw_mul(T, wp.cw_mul(dtm, sn) + wp.cw_mul(tm, dsn))) / pdf
            T = wp.cw_mul(T, wp.cw_mul(tm, sn)) / pdf
            big = wp.max(wp.max(T[0], T[1]), T[2])
            if big <= 0.0:
                if wp.static(diff):
                    return zero, r, zero
                else:
                    return zero, r
            if big < _ROULETTE_BELOW:
                u, r = next_u(r)
                if u < 0.5:
                    if wp.static(diff):
                        return zero, r, zero
                    else:
                        return zero, r
                T = T * 2.0
                if wp.static(diff):
                    dT = dT * 2.0
        if wp.static(diff):
            return zero, r, zero
        else:
            return zero, r

    if diff:      # their loops are no derivative of Warp's: callers attach the derivatives they return
        zero_adjoint(free_flight, (int, float, wp.vec3, wp.vec3, wp.vec3, wp.uint32, FlightDeriv))
        zero_adjoint(transmittance, (wp.vec3, wp.uint32, wp.vec3))

    return SimpleNamespace(free_flight=free_flight, transmittance=transmittance)


__all__ = ["Media", "FlightDeriv", "ratio3", "make_media", "declare", "upload_media", "hg", "hg_eval", "hg_sample", "next_u",
           "EVENT_SURFACE", "EVENT_SCATTER", "EVENT_ABSORB"]
