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
"""

from __future__ import annotations

from types import SimpleNamespace

import warp as wp

from warp_spt.core.media.phase import hg, hg_eval, hg_sample  # noqa: F401 (re-exported)
from warp_spt.core.media.registry import KINDS
from warp_spt.core.media.table import Media, media_features  # noqa: F401 (re-exported)
from warp_spt.core.media.upload import upload_media  # noqa: F401 (re-exported)
from warp_spt.scene.media import MEDIUM_KINDS
from warp_spt.core.sampling import hash_u32

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


def make_media(features) -> SimpleNamespace:
    """The trackers (module docs) for ``features.media``'s kinds (one kind: called directly; two: a
    test of the medium's kind)."""
    kinds = [k for k in MEDIUM_KINDS if k in features.media]
    made = [KINDS[k].make(features) for k in kinds]
    emits = "emission" in features.media
    if len(kinds) == 1:
        coefficients, segment = made[0].coefficients, made[0].segment
    else:
        first, second = made
        which = MEDIUM_KINDS.index(kinds[1])

        @wp.func
        def coefficients(media: Media, m: int, x: wp.vec3):
            if media.kind[m] == wp.static(which):
                return second.coefficients(media, m, x)
            return first.coefficients(media, m, x)

        @wp.func
        def segment(media: Media, m: int, o: wp.vec3, d: wp.vec3, t: float, t_max: float):
            if media.kind[m] == wp.static(which):
                return second.segment(media, m, o, d, t, t_max)
            return first.segment(media, m, o, d, t, t_max)

    @wp.func
    def free_flight(media: Media, m: int, o: wp.vec3, d: wp.vec3, t_max: float, hero: int, beta: wp.vec3,
                    w: wp.vec3, rng: wp.uint32):
        t = float(0.0)
        b = beta
        mis = w
        emitted = wp.vec3(0.0, 0.0, 0.0)
        r = rng
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
                    return EVENT_ABSORB, t_end, wp.vec3(0.0, 0.0, 0.0), mis, emitted, r
                b = wp.cw_mul(b, g) / s
                mis = wp.cw_mul(mis, g) / s
                t = t_end
                if t >= t_max:
                    return EVENT_SURFACE, t_max, b, mis, emitted, r
                t_end, maj = segment(media, m, o, d, t, t_max)
                continue
            t += dt
            tm = exp3(maj, dt)
            sa, ss = coefficients(media, m, o + d * t)
            sn = wp.max(maj - sa - ss, wp.vec3(0.0, 0.0, 0.0))
            if wp.static(emits):
                emitted += wp.cw_mul(b, wp.cw_mul(wp.cw_mul(tm, sa), media.emission[m])) / avg3(
                    wp.cw_mul(mis, wp.cw_mul(tm, maj)))
            u2, r = next_u(r)
            x = u2 * maj[hero]
            g = wp.cw_mul(tm, sn)
            event = int(-1)
            if x < sa[hero]:
                return EVENT_ABSORB, t, wp.vec3(0.0, 0.0, 0.0), mis, emitted, r
            if x < sa[hero] + ss[hero]:
                g = wp.cw_mul(tm, ss)
                event = EVENT_SCATTER
            s = avg3(wp.cw_mul(mis, g))
            if s <= 0.0:
                return EVENT_ABSORB, t, wp.vec3(0.0, 0.0, 0.0), mis, emitted, r
            b = wp.cw_mul(b, g) / s
            mis = wp.cw_mul(mis, g) / s
            if event == EVENT_SCATTER:
                return EVENT_SCATTER, t, b, mis, emitted, r
        return EVENT_ABSORB, t, wp.vec3(0.0, 0.0, 0.0), mis, emitted, r

    @wp.func
    def transmittance(media: Media, m: int, o: wp.vec3, d: wp.vec3, t_max: float, rng: wp.uint32):
        t = float(0.0)
        T = wp.vec3(1.0, 1.0, 1.0)
        r = rng
        t_end, maj = segment(media, m, o, d, t, t_max)
        for step in range(_MAX_STEPS):
            dt, r = hero_step(maj, r)
            if t + dt >= t_end:
                tm = exp3(maj, t_end - t)
                T = wp.cw_mul(T, tm) / avg3(tm)
                t = t_end
                if t >= t_max:
                    return T, r
                t_end, maj = segment(media, m, o, d, t, t_max)
                continue
            t += dt
            tm = exp3(maj, dt)
            pdf = avg3(wp.cw_mul(maj, tm))
            sa, ss = coefficients(media, m, o + d * t)
            T = wp.cw_mul(T, wp.cw_mul(tm, wp.max(maj - sa - ss, wp.vec3(0.0, 0.0, 0.0)))) / pdf
            big = wp.max(wp.max(T[0], T[1]), T[2])
            if big <= 0.0:
                return wp.vec3(0.0, 0.0, 0.0), r
            if big < _ROULETTE_BELOW:
                u, r = next_u(r)
                if u < 0.5:
                    return wp.vec3(0.0, 0.0, 0.0), r
                T = T * 2.0
        return wp.vec3(0.0, 0.0, 0.0), r

    return SimpleNamespace(free_flight=free_flight, transmittance=transmittance)


__all__ = ["Media", "make_media", "media_features", "upload_media", "hg", "hg_eval", "hg_sample", "next_u",
           "EVENT_SURFACE", "EVENT_SCATTER", "EVENT_ABSORB"]
