"""Efficiency-aware Russian roulette and splitting (after Rath, Grittmann, Herholz, Weier and
Slusallek 2022, "EARS: Efficiency-Aware Russian Roulette and Splitting"), on top of ``nee``.

Every bounce is ``nee``'s (light sample, MIS, the BSDF's continuation; its throughput roulette is
off). After a bounce whose path goes on, the continuation is rouletted or split by a factor ``q``
learnt per region of the scene instead of read off the throughput alone:

    q = (T / P) * sqrt(M2 * C / (V * Cx)),   clamped to [q_min, q_max]

* ``T``: the path's throughput after the bounce (channel mean, earlier roulette and splits
  included); ``P``: the pixel's estimate with ``relative`` (the paper's relative error), else 1
  (absolute error, the default: what the benchmarks measure, and measured better there);
* ``M2``: the second moment of ``Lx``, the radiance (channel mean) the continuation gathers per
  unit throughput, learnt per cell of a ``grid``^3 grid over the scene's box and per bounce, and
  floored at ``global_floor`` x the bounce's mean over the whole scene (a cell whose few training
  paths missed a rare bright path, a caustic, would otherwise roulette it hard: without the floor
  the caustics scene's MSE was 4x ``nee``'s);
* ``Cx``: the rays the continuation traces (the same cell and bounce); ``C``: the rays of one
  camera sample; ``V``: the variance per sample of the pixel means, relative (divided by
  ``P``^2, averaged over the image) or absolute, measured from two halves of the training samples.

Derivation (the paper's Sec. 4 in its simplest form): with q continuations the pixel estimator's
variance is about ``V0 + (T/P)^2 M2 / q`` and its cost ``C0 + q Cx``; the product is least at
``q^2 = (T/P)^2 M2 C0 / (V0 Cx)``, with ``V0``, ``C0`` taken as the whole sample's ``V`` and ``C``.

The decision draws one number, the bounce's ``OFF_ROULETTE`` dimension (``nee`` uses it only with
its own roulette, which ``ears`` turns off): ``n = floor(q) + (u < frac(q))`` continuations
(stochastic rounding). ``q < 1`` is roulette: the path survives with probability ``q`` and its
throughput is divided by ``q``. ``n > 1`` is splitting: the throughput is divided by ``n`` (the
mean of n independent continuations, unbiased whatever n) and ``n - 1`` copies go on a per-thread
stack of ``stack`` pending continuations (n is capped by the stack's free room, before the
division: still unbiased). Each copy continues with the sampler restarted under a seed of its own
(``split_seed``: the render's seed, hashed with the number of copies made so far in this camera
sample), so its numbers are independent of its siblings' and the image is a function of the seed.

Training. The first ``spp // train_fraction`` samples per pixel (``spp // 4``; none below 8 spp), in two halves, are plain
``nee`` and record, per vertex, fixed-point sums of Lx^2 and of the rays after it, per (bounce,
cell); each worker records into its own arrays, summed on the host (integer sums: exact in any
order). The host then turns them into ``s = sqrt(M2 C / (V Cx))`` per (bounce, cell) (-1: too few
records, no decision) and ``1 / P`` per pixel (the training image, 3x3 box-filtered, floored at
``p_floor`` x its mean); ``V`` comes from the two halves' difference (see :func:`learn`); the
remaining samples render with the decisions. Every sample counts with equal weight, so the film
holds exactly the requested spp. As ``guided``, it renders whole images through the tile renderer
only. Differences from the paper: a fixed grid, not an adaptive octree; one training stage, not
iterations that re-learn with the decisions on; the ``q`` clamp is [0.2, 10], not [0.05, 20]
(0.05 was as good on the indirect room, worse on the caustics).

Parameters (``PARAMS``, set by name in ``RenderSettings.integrator_options``; the names above in
lower case): ``relative``, ``q_min``, ``q_max``, ``train_fraction``, ``grid``, ``min_records``,
``global_floor``, ``v_scale``, ``p_floor``, ``max_records``, ``stack``.
"""

from __future__ import annotations

from typing import Any, Mapping

import numpy as np
import warp as wp

from warp_spt.device.structs import Features, Geometry, Materials, Textures
from warp_spt.emitters import Lights
from warp_spt.integrators.common import (
    FAST_KERNEL_OPTIONS,
    FULL_STRIDE,
    CameraParams,
    Integrator,
    Param,
    PathState,
    RenderParams,
    add_to_pixel,
    finite3,
)
from warp_spt.integrators.guided.tree import box_of
from warp_spt.integrators.nee import VertexHooks, make_path_step
from warp_spt.integrators.passes import run_pass
from warp_spt.samplers import Sampler
from warp_spt.samplers.sobol import mix32
from warp_spt.scene.limits import MAX_SPP

STRIDE = FULL_STRIDE

PARAMS = (
    Param("relative", False, "EARS's relative error (factors scaled by the pixel's estimate, as the paper); "
          "False: absolute error (measured better on the benchmarks)", bool),
    Param("q_min", 0.2, "the factor's lower clamp (strongest roulette)", float, 0.0, 1.0, low_open=True),
    Param("q_max", 10.0, "the factor's upper clamp (most splits; the stack caps them too)", float, 1.0, 1e3),
    Param("train_fraction", 4, "the first spp // train_fraction samples train (plain nee)", int, 1, MAX_SPP),
    Param("grid", 16, "cells per axis of the learnt grid over the scene's box", int, 1, 64),
    Param("min_records", 32, "records a (bounce, cell) needs before it decides", int, 1, 1 << 30),
    Param("global_floor", 1.0, "floor of a cell's learnt second moment, a fraction of its bounce's mean over "
          "the scene", float, 0.0, 1e6),
    Param("v_scale", 1.0, "the pixel variance the factors are computed with, over the measured one", float, 0.0,
          1e6, low_open=True),
    Param("p_floor", 0.05, "relative error: pixel estimates floored at this fraction of the image's mean", float,
          0.0, 1e6, low_open=True),
    Param("max_records", 16, "vertices of one training path that record", int, 1, 256),
    Param("stack", 8, "pending split continuations per camera sample", int, 1, 64),
)
LX_MAX = 1.0e3            # one record's cap on Lx (fixed point)
S2 = 65536.0              # 2**16 per unit of Lx^2
S2_W = wp.constant(S2)
LX_MAX_W = wp.constant(LX_MAX)
_SPLIT_SALT = wp.constant(wp.uint32(0x5E1175A7))


@wp.struct
class EarsTable:
    """What the decisions read: the grid (box ``lo``, cells per unit ``scale``, ``res`` per axis),
    ``s`` per (bounce, cell) (-1: no decision), ``pix_inv`` = 1 / P per pixel; ``on`` 0: no decisions."""

    lo: wp.vec3
    scale: wp.vec3
    res: int
    s: wp.array(dtype=wp.float32)
    pix_inv: wp.array(dtype=wp.float32)
    q_min: float
    q_max: float
    on: int


@wp.struct
class EarsRecord:
    """One worker's training sums per (bounce, cell) (fixed point) and its scratch: recording
    vertices and the split stack per thread."""

    on: int
    count: wp.array(dtype=wp.int64)
    m2: wp.array(dtype=wp.int64)
    cost: wp.array(dtype=wp.int64)
    slot_k: wp.array2d(dtype=wp.int32)
    slot_v: wp.array2d(dtype=wp.vec3)
    stack: wp.array2d(dtype=PathState)


@wp.func
def cell_index(tab: EarsTable, p: wp.vec3, depth: int) -> int:
    """The (bounce, cell) entry of a vertex at ``p`` after ``depth`` hits."""
    r = tab.res
    x = wp.clamp(int((p[0] - tab.lo[0]) * tab.scale[0]), 0, r - 1)
    y = wp.clamp(int((p[1] - tab.lo[1]) * tab.scale[1]), 0, r - 1)
    z = wp.clamp(int((p[2] - tab.lo[2]) * tab.scale[2]), 0, r - 1)
    return (depth - 1) * r * r * r + (z * r + y) * r + x


@wp.func
def split_seed(seed: wp.uint32, copies: int) -> wp.uint32:
    """The seed of the ``copies``-th split copy of a camera sample (Sobol's 32-bit mix)."""
    return mix32(mix32(seed ^ _SPLIT_SALT) + wp.uint32(copies))


@wp.func
def mean3(v: wp.vec3) -> float:
    return (v[0] + v[1] + v[2]) / 3.0


@wp.struct
class EarsAux:
    """The ears vertex's data (``VertexHooks.Aux``): the decisions' table and this pixel's 1 / P."""

    tab: EarsTable
    pix_inv: float


@wp.func
def no_split() -> int:
    return 0


@wp.func
def finish(p: PathState, n: int):
    return p, n


def make(features: Features, sampler: Sampler, differentiable: bool = False):
    """``step(geo, mats, tex, lights, rp, path, aux) -> (path, n)``: ``nee``'s bounce whose
    continuation hook is the decision: ``n`` continuations (0: the path ended, by roulette or
    otherwise; 1: it goes on; more: the caller splits it, dividing the throughput by the n it can hold)."""
    if differentiable:
        raise ValueError("the ears integrator has no differentiable kernel")

    @wp.func
    def decide(aux: EarsAux, out: int, path: PathState, rp: RenderParams, dim: int):
        """The continuation (``VertexHooks.leave``, in place of nee's roulette): q from the learnt
        table, rounded stochastically with the bounce's roulette dimension ``dim``."""
        p = path
        if p.alive == 0:
            return p, int(0)
        n = int(1)
        if aux.tab.on != 0:
            s = aux.tab.s[cell_index(aux.tab, p.o, p.depth)]
            if s >= 0.0:
                q = wp.clamp(mean3(p.throughput) * aux.pix_inv * s, aux.tab.q_min, aux.tab.q_max)
                u, st = sampler.next_1d(p.sampler, dim)
                p.sampler = st
                fq = wp.floor(q)
                n = int(fq)
                if u < q - fq:
                    n += 1
                if q < 1.0:
                    if n == 0:
                        p.alive = 0
                    else:
                        p.throughput = p.throughput / q
        return p, n

    hooks = VertexHooks(Aux=EarsAux, new_out=no_split, finish=finish, leave=decide)
    return make_path_step(features, sampler, light_sampling=True, hooks=hooks)


def make_kernel(step, start_path):
    """The ears fast kernel: ``common.make_kernel``'s inputs, then the table and the record. Each
    camera sample runs its path and every split copy (from the stack) to the end; the sum of their
    radiance is the sample. Training (``rec.on``) records each vertex's (bounce, cell), throughput,
    radiance so far and rays so far, then, at the path's end, what came after it."""

    @wp.kernel(enable_backward=False, module="unique", module_options=FAST_KERNEL_OPTIONS)
    def trace(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, cam: CameraParams,
              rp: RenderParams, film: wp.array(dtype=wp.vec3d), counters: wp.array2d(dtype=wp.int64),
              work: wp.array(dtype=wp.vec3i), tab: EarsTable, rec: EarsRecord):
        tid = wp.tid()
        pix = rp.pixel_start + tid
        acc = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0))
        bad = int(0)
        rays = int(0)
        aux = EarsAux()
        aux.tab = tab
        aux.pix_inv = float(1.0)
        if tab.on != 0:
            aux.pix_inv = tab.pix_inv[pix]
        for j in range(rp.sample_count):
            index = rp.sample_start + j
            path = start_path(cam, pix, rp.width, rp.seed, index)
            L = wp.vec3(0.0, 0.0, 0.0)
            top = int(0)
            copies = int(0)
            nrec = int(0)
            more = int(1)
            while more != 0:
                while path.alive != 0:
                    path, n = step(geo, mats, tex, lights, rp, path, aux)
                    if rec.on != 0 and path.alive != 0 and nrec < rec.slot_k.shape[1]:
                        t = mean3(path.throughput)
                        if t > 0.0:
                            rec.slot_k[tid, nrec] = cell_index(tab, path.o, path.depth)
                            rec.slot_v[tid, nrec] = wp.vec3(t, mean3(path.radiance), float(path.rays))
                            nrec += 1
                    if n > 1:
                        n = wp.min(n, 1 + rec.stack.shape[1] - top)
                        if n > 1:
                            path.throughput = path.throughput / float(n)
                            for c in range(n - 1):
                                child = path
                                child.radiance = wp.vec3(0.0, 0.0, 0.0)
                                child.rays = 0
                                child.sampler = start_path(cam, pix, rp.width, split_seed(rp.seed, copies),
                                                           index).sampler
                                copies += 1
                                rec.stack[tid, top] = child
                                top += 1
                L += path.radiance
                rays += path.rays
                if top > 0:
                    top -= 1
                    path = rec.stack[tid, top]
                else:
                    more = 0
            if finite3(L):
                acc += wp.vec3d(wp.float64(L[0]), wp.float64(L[1]), wp.float64(L[2]))
                if rec.on != 0:
                    total = mean3(L)
                    for i in range(nrec):
                        k = rec.slot_k[tid, i]
                        v = rec.slot_v[tid, i]
                        lx = wp.min((total - v[1]) / v[0], LX_MAX_W)
                        wp.atomic_add(rec.count, k, wp.int64(1))
                        wp.atomic_add(rec.m2, k, wp.int64(lx * lx * S2_W))
                        wp.atomic_add(rec.cost, k, wp.int64(path.rays - int(v[2])))
            else:
                bad += 1
        add_to_pixel(film, counters, pix, acc, rays, bad)

    return trace


def _options(options: Mapping[str, Any] | None) -> dict[str, Any]:
    """Every option's value: ``options`` (partial, or None) checked, the defaults (``PARAMS``) for the rest."""
    return INTEGRATOR.options(options)


def schedule(spp: int, options: Mapping[str, Any] | None = None) -> tuple[int, int, int]:
    """(first training half, second training half, deciding samples) per pixel: the first
    ``spp // train_fraction`` samples train, in two halves (aligned blocks of the sequence when
    ``spp`` is a power of two); below ``2 * train_fraction`` spp nothing trains: plain ``nee``."""
    train = spp // _options(options)["train_fraction"]
    if train < 2:
        return 0, 0, spp
    return train // 2, train - train // 2, spp - train


def _table(b, s: np.ndarray, pix_inv: np.ndarray, on: bool) -> EarsTable:
    lo, hi = box_of(b.dev.scene.bounds)
    grid = b.options["grid"]
    t = EarsTable()
    t.lo = wp.vec3(*lo.astype(np.float32))
    t.scale = wp.vec3(*(grid / (hi - lo)).astype(np.float32))
    t.res = grid
    t.s = wp.array(s.astype(np.float32), dtype=wp.float32, device=b.dev.device)
    t.pix_inv = wp.array(pix_inv.astype(np.float32), dtype=wp.float32, device=b.dev.device)
    t.q_min, t.q_max = b.options["q_min"], b.options["q_max"]
    t.on = int(on)
    return t


def _record(entries: int, on: bool, threads: int, device, opt: dict) -> EarsRecord:
    """A worker's record; its slot and stack widths are the ``max_records`` and ``stack`` options
    (the kernel reads them off the arrays' shapes)."""
    r = EarsRecord()
    r.on = int(on)
    r.count, r.m2, r.cost = (wp.zeros(entries if on else 1, dtype=wp.int64, device=device) for _ in range(3))
    r.slot_k = wp.zeros((threads if on else 1, opt["max_records"]), dtype=wp.int32, device=device)
    r.slot_v = wp.zeros((threads if on else 1, opt["max_records"]), dtype=wp.vec3, device=device)
    r.stack = wp.zeros((threads, opt["stack"]), dtype=PathState, device=device)
    return r


def learn(counts, m2, cost, sum_a: np.ndarray, sum_b: np.ndarray, n_a: int, n_b: int, rays: float,
          shape: tuple[int, int], options: Mapping[str, Any] | None = None) -> tuple[np.ndarray, np.ndarray, dict]:
    """The decisions' table from the training sums: ``s`` per (bounce, cell), ``1 / P`` per pixel,
    and the figures they came from. ``sum_a``, ``sum_b``: the (pixels, 3) film sums of the two
    training halves (``n_a``, ``n_b`` samples); ``rays``: closest-hit rays traced in training;
    ``options``: the integrator's (``PARAMS``; the defaults for those not given).

    ``V`` is the variance per sample *of the pixel means*, measured from the two halves' difference,
    ``V = E[(m_a - m_b)^2] n_a n_b / (n_a + n_b)`` (relative: over P^2), not the samples' spread: with
    Sobol' points the pixel means converge faster than the samples' variance says (the indirect room,
    64 spp: 2.5x, the caustics 6x), and the roulette and split copies add independent noise, so
    the samples' spread made the factors too small (roulette lost 2-5x in MSE)."""
    opt = _options(options)
    grid, floor = opt["grid"], opt["global_floor"]
    m_a, m_b = sum_a.mean(axis=1) / n_a, sum_b.mean(axis=1) / n_b
    mean = (m_a * n_a + m_b * n_b) / (n_a + n_b)
    if opt["relative"]:
        img = mean.reshape(shape)
        pad = np.pad(img, 1, mode="edge")
        blur = sum(pad[dy:dy + shape[0], dx:dx + shape[1]] for dy in range(3) for dx in range(3)) / 9
        p = np.maximum(blur.ravel(), opt["p_floor"] * max(float(mean.mean()), 1e-6))
    else:
        p = np.ones_like(mean)
    v = float(np.mean((m_a - m_b) ** 2 / p ** 2)) * n_a * n_b / (n_a + n_b) * opt["v_scale"]
    c = rays / (mean.size * (n_a + n_b))
    counts = counts.astype(np.float64)
    ok = counts >= opt["min_records"]
    m2_mean = np.where(ok, m2 / S2 / np.maximum(counts, 1), 0.0)
    if floor > 0:        # a cell's moment at least global_floor x its bounce's over the whole scene
        per = counts.reshape(-1, grid ** 3)
        glob = (m2.reshape(per.shape) / S2).sum(axis=1) / np.maximum(per.sum(axis=1), 1)
        m2_mean = np.maximum(m2_mean, floor * np.repeat(glob, grid ** 3))
    cx = np.where(ok, np.maximum(cost / np.maximum(counts, 1), 1.0), 1.0)
    s = np.where(ok, np.sqrt(m2_mean * c / (max(v, 1e-12) * cx)), -1.0)
    return s, 1.0 / p, {"V": v, "C": c, "cells": int(ok.sum())}


def render_passes(b, tiles: list[tuple[int, int]], film: wp.array, counters: wp.array2d, threads: int,
                  report, per_launch: int) -> int:
    """``Integrator.render_passes``: the two training halves (plain ``nee``, recording), the table
    learnt on the host, then the remaining samples with the decisions. Returns the launches made.
    The options (``PARAMS``) come from ``b.options``."""
    rs, device, opt = b.settings, b.dev.device, b.options
    if tiles[0][0] != 0 or tiles[-1][1] != b.pixels:
        raise ValueError("the ears integrator learns over the whole image: it cannot render a window of rows")
    n_a, n_b, rest = schedule(rs.spp, opt)
    entries = rs.max_depth * opt["grid"] ** 3
    width = max(hi - lo for lo, hi in tiles)
    table = _table(b, np.zeros(1), np.ones(1), False)
    slots = [_record(entries, n_a > 0, width, device, opt) for _ in range(max(1, threads))]
    start, launches, sum_a = 0, 0, None

    def params(lo: int, first: int, count: int) -> RenderParams:
        rp = b.params(lo, first, count)
        rp.roulette_depth = 0                    # nee's throughput roulette off: ears decides
        return rp

    for k, count in enumerate((n_a, n_b, rest)):
        if count == 0:
            continue
        if k == 2:
            slots = [_record(entries, False, width, device, opt) for _ in range(max(1, threads))]
        launches += run_pass(b, tiles, film, counters, threads, report, per_launch, start, count, slots,
                             lambda rec, table=table: [table, rec], params)
        start += count
        if k == 0:
            sum_a = film.numpy().copy()
        elif k == 1:
            tot = [sum(getattr(r, f).numpy() for r in slots) for f in ("count", "m2", "cost")]
            s, pix_inv, _ = learn(*tot, sum_a, film.numpy() - sum_a, n_a, n_b, float(counters.numpy()[:, 0].sum()),
                                  (b.height, b.width), opt)
            table = _table(b, s, pix_inv, True)
    return launches


INTEGRATOR = Integrator("ears", make, None, STRIDE, tape=False, make_kernel=make_kernel,
                        render_passes=render_passes, params=PARAMS,
                        summary="nee with efficiency-aware roulette and splitting learnt per region (EARS)")
