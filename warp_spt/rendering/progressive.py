"""Progressive rendering with error you can see and control: error estimates, budgets, adaptive sampling.

:func:`render_progressive` renders in passes and returns a :class:`warp_spt.rendering.result.RenderResult`
(the one result type; ``ProgressiveResult`` is another name for it): the image, a per-pixel
standard-error map, the per-pixel sample counts, the batch sums and stats. It stops at a sample count, a
time budget or a target relative error, whichever comes first, and can spend later passes only where
the estimated error is high (``adaptive=True``).

How the error is estimated (docs/error.md has the full argument). Each pixel's samples are split
into ``batches`` (default 8) groups with *independent* random streams: batch b uses seed
``batch_seed(seed, b)`` and its own sample indices 0, 1, 2, ... The film keeps one float64 sum per
batch and pixel (the "batch buffers"; two of them would be the classic half-buffers). The
between-batch spread gives an unbiased estimate of the variance of the pixel mean whatever the
sampler does *within* a batch: a low-discrepancy sampler makes a batch's samples correlated, but
batches with independent scrambles are independent, so the estimate stays honest. We chose batch
buffers over float64 sums of squares because (1) sums of squares over-state the error of correlated
(stratified, Sobol') samples, (2) they need a kernel change, which batch buffers do not, and (3) the
two halves of the batches serve adaptive sampling (decide from one half, image from all). The price
is memory (24 bytes per batch per pixel) and, with a low-discrepancy sampler, B short sequences
instead of one long one.

Determinism: pass k gives batch b a fixed number of samples (a schedule that depends on k and the
image size only), each launch adds one float64 sum per pixel, and a render of N spp gives batch b
``N // B + (b < N % B)`` samples. So a render stopped by a budget after pass k (or inside its
final, truncated pass) is bit-identical to ``render_progressive(..., spp=result.spp_total)``.

"Relative error of the image" is defined once, in :func:`relative_error`, and used everywhere
(the CLI's final line, ``target_error``, the convergence report, the benchmarks).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np
import warp as wp

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.integrators import check_sliceable, fast_inputs
from warp_spt.rendering.result import (
    ERROR_FLOOR_FRACTION,
    RenderResult,
    RenderStats,
    batch_statistics,
    result_from_batches,
)
from warp_spt.rendering.schedule import (
    DEFAULT_BATCHES,
    batch_counts,
    batch_seed,
    pass_samples,
)
from warp_spt.rendering.settings import TILE_PIXELS, RenderSettings, settings_from
from warp_spt.rendering.setup import Bound, bind, check
from warp_spt.runtime.threads import cores, run_jobs
from warp_spt.scene import limits
from warp_spt.scene.camera import Camera
from warp_spt.scene.model import Scene

SAMPLE_COST_RAYS = -0.6      # a sample's cost beyond its rays, in rays: negative, because a ray that misses
                             # everything (the last of many paths) costs a fraction of one that hits and is
                             # shaded (fitted -0.4 to -0.8 from timings, bench_budgets.py --parts cost)
UNLIMITED_SPP = 1 << 20
ADAPTIVE_METRICS = ("relative", "rmse")   # what adaptive sampling minimises (docs/error.md)
DEFAULT_ADAPTIVE_METRIC = "relative"


# ---------------------------------------------------------------------------------------------
# The one definition of "relative error of the image"


# ---------------------------------------------------------------------------------------------
# Batch statistics (pure numpy, used by the driver, the tests and the convergence report)


# ---------------------------------------------------------------------------------------------
# Result


PassCallback = Callable[[RenderResult], "bool | None"]


# ---------------------------------------------------------------------------------------------
# The pass driver


def render_progressive(
    scene: Scene | DeviceScene,
    camera: Camera | None = None,
    *,
    time_budget: float | None = None,
    target_error: float | None = None,
    adaptive: bool = False,
    adaptive_metric: str = DEFAULT_ADAPTIVE_METRIC,
    min_spp: int | None = None,
    batches: int = DEFAULT_BATCHES,
    sample_budget: int | None = None,
    on_pass: PassCallback | None = None,
    keep_partial: bool = False,
    started: float | None = None,
    **settings,
) -> RenderResult:
    """Render in passes until ``spp``, ``time_budget`` (seconds) or ``target_error`` is reached.

    ``settings`` are the fields of :class:`warp_spt.rendering.settings.RenderSettings` (width, height, spp,
    max_depth, sky, seed, integrator, sampler, roulette_depth, texture_filter, threads, features,
    device) except ``sample_offset`` and ``tile_pixels``: the batches own the sample indices.
    ``spp`` is the maximum samples per pixel (default 16 without a budget, unlimited with one).
    ``time_budget`` counts from ``started`` (a ``time.perf_counter()`` value; default: this call),
    so it includes the upload and kernel compile done here; the CLI passes its own start time so
    the budget also covers loading the scene. ``target_error`` is the relative error of
    :func:`relative_error`. ``adaptive`` spends passes after ``min_spp`` (default 2 x batches) on the
    pixels with the fewest samples for their noise (estimated from the even batches), so that samples
    end up proportional to each pixel's relative noise over the square root of its cost, which
    minimises the relative error for the work spent (see _Driver._adaptive_pass). ``adaptive_metric``
    chooses what adaptive sampling minimises: ``"relative"`` (the relative error above) or ``"rmse"``
    (samples proportional to each pixel's absolute noise over the square root of its cost, which
    minimises the RMSE for the work spent).
    A host :class:`Scene` far from the origin is recentred first, as :func:`render_scene` does (a
    :class:`DeviceScene` is used as it is). ``sample_budget`` caps the total pixel-samples
    (equal-work comparisons). ``on_pass(result)`` is called after every pass; returning True stops
    the render. With ``keep_partial``, Ctrl-C returns what is accumulated so far
    (``stats.stopped_by == "interrupt"``) instead of raising KeyboardInterrupt.
    """
    t0 = time.perf_counter() if started is None else started
    for name in ("sample_offset", "tile_pixels"):
        if name in settings:
            raise TypeError(f"render_progressive does not take {name!r}: its batches own the sample indices")
    budgeted = time_budget is not None or target_error is not None or sample_budget is not None
    if settings.get("spp") is None:
        settings["spp"] = UNLIMITED_SPP if budgeted else RenderSettings.spp
    rs = settings_from(settings)
    check(rs, camera)                           # ValueError before anything is uploaded
    check_sliceable(rs.integrator, "render_progressive")
    check_budget(time_budget, target_error, batches, min_spp, adaptive_metric)
    if sample_budget is not None and (not isinstance(sample_budget, (int, np.integer)) or sample_budget < 1):
        raise ValueError(f"sample_budget must be a positive integer, got {sample_budget!r}")
    driver = _Driver(bind(scene, camera, rs), batches)
    plan = _Plan(rs.spp, time_budget, target_error, adaptive,
                 min(rs.spp, 2 * batches if min_spp is None else min_spp), t0, sample_budget, adaptive_metric)
    return driver.run(plan, on_pass, keep_partial)


def check_budget(time_budget, target_error, batches, min_spp, adaptive_metric=DEFAULT_ADAPTIVE_METRIC) -> None:
    """Raise ValueError naming the first budget argument of :func:`render_progressive` that is not valid."""
    if time_budget is not None and not (math.isfinite(time_budget) and time_budget > 0):
        raise ValueError(f"time_budget must be a positive number of seconds, got {time_budget!r}")
    if target_error is not None and not (math.isfinite(target_error) and target_error > 0):
        raise ValueError(f"target_error must be a positive number, got {target_error!r}")
    if (not isinstance(batches, (int, np.integer)) or isinstance(batches, bool)
            or not 2 <= batches <= limits.MAX_BATCHES):     # each batch holds a float64 image
        raise ValueError(f"batches must be an integer in [2, {limits.MAX_BATCHES}] (the error estimate needs "
                         f"two), got {batches!r}")
    if min_spp is not None and (not isinstance(min_spp, (int, np.integer)) or min_spp < 1):
        raise ValueError(f"min_spp must be a positive integer, got {min_spp!r}")
    if adaptive_metric not in ADAPTIVE_METRICS:
        raise ValueError(f"adaptive_metric must be one of {', '.join(ADAPTIVE_METRICS)}, got {adaptive_metric!r}")


@dataclass
class _Plan:
    spp: int
    time_budget: float | None
    target_error: float | None
    adaptive: bool
    min_spp: int
    t0: float
    sample_budget: int | None = None
    adaptive_metric: str = DEFAULT_ADAPTIVE_METRIC

    @property
    def deadline(self) -> float:
        return math.inf if self.time_budget is None else self.t0 + self.time_budget


class _Driver:
    """Owns the batch buffers on the device and launches passes over runs of pixels."""

    def __init__(self, bound: Bound, batches: int):
        self.bound, self.dev, self.rs, self.B = bound, bound.dev, bound.settings, batches
        self.width, self.height, self.n = bound.width, bound.height, bound.pixels
        dev, rs = self.dev, self.rs
        self.kernel_features = bound.features
        self.seeds = [batch_seed(rs.seed, b) for b in range(batches)]
        # one allocation for every batch's film (batch b's film is the view film_memory[b]): the last
        # snapshot reads them all without a copy
        self.film_memory = wp.zeros((batches, self.n), dtype=wp.vec3d, device=dev.device)
        self.films = [self.film_memory[b] for b in range(batches)]
        self.counters = [wp.zeros((self.n, 2), dtype=wp.int64, device=dev.device) for _ in range(batches)]
        self.counts = np.zeros((batches, self.n), dtype=np.int64)
        self.launches: dict = {}     # (batch, task slot) -> recorded launch
        self.threads = max(1, rs.threads or cores())
        self.stop = threading.Event()
        self.cost_rate = 0.0         # cost (rays + SAMPLE_COST_RAYS per sample) per second in the last pass
        self.after_pass = 0.0        # seconds of snapshot and callback after the last pass
        self.stats = RenderStats(self.kernel_features, rs.integrator, rs.sampler, threads=self.threads, passes=0)

    # -- launching

    def _launch(self, b: int, slot: int, lo: int, hi: int, start: int, count: int, work=None) -> None:
        """Launch batch b over pixels lo..hi-1 from sample ``start``, ``count`` samples each; or, with
        ``work`` (a device array of (pixel, first sample, samples) and its host copy), over its items
        lo..hi-1."""
        if self.stop.is_set():
            return
        cmd = self._command(b, slot)
        cmd.set_dim(hi - lo)
        cmd.set_param_by_name("rp", self.bound.params(lo, start, count, seed=self.seeds[b]))
        cmd.set_param_by_name("work", None if work is None else work[0][lo:hi])
        cmd.launch()
        # disjoint pixels per launch: safe across threads; counted once launched (Ctrl-C, keep_partial)
        if work is None:
            self.counts[b, lo:hi] += count
        else:
            self.counts[b, work[1][lo:hi, 0]] += work[1][lo:hi, 2]

    def _command(self, b: int, slot: int):
        """A recorded launch of batch b's film, one per task slot, so that concurrent tasks never share
        one (replayed with new params: packing the scene's structs afresh cost about 160 us per launch)."""
        cmd = self.launches.get((b, slot))
        if cmd is None:
            args = self.bound.scene_args(self.bound.params(seed=self.seeds[b]))
            cmd = self.launches[b, slot] = wp.launch(
                self.bound.kernel, dim=1, device=self.dev.device, record_cmd=True,
                inputs=fast_inputs(args, self.films[b], self.counters[b]))
        return cmd

    def _batch_tasks(self, b: int, inc: np.ndarray, shares: int, cost: np.ndarray | None) -> list:
        """Batch b's launches for a pass, split into at most ``shares`` tasks of about equal work.

        When every pixel gets the same samples from the same index (uniform passes), the launches
        are runs of consecutive pixels; otherwise one compacted work list of the pixels that get
        samples, each with its own first index and count (adaptive passes), cut into contiguous
        pieces of about equal estimated cost (``cost``: per sample and pixel)."""
        done = self.counts[b]
        if inc.min() == inc.max() and done.min() == done.max():
            runs = [(lo, hi, int(done[lo]), int(inc[lo]), None) for lo, hi in _runs(inc, done)]
            work = np.cumsum([(hi - lo) * c for lo, hi, _, c, _ in runs])
        else:
            pix = np.flatnonzero(inc > 0)
            items = np.stack([pix, done[pix], inc[pix]], axis=1).astype(np.int32)
            arr = (wp.array(items, dtype=wp.vec3i, device=self.dev.device), items)
            per_item = np.cumsum(inc[pix] * (1.0 if cost is None else cost[pix]))
            cuts = np.searchsorted(per_item, per_item[-1] * np.arange(1, shares) / shares, side="right")
            edges = np.unique(np.concatenate(([0], cuts, [len(pix)])))
            runs = [(int(lo), int(hi), 0, 0, arr) for lo, hi in zip(edges[:-1], edges[1:]) if hi > lo]
            work = per_item[[hi - 1 for _, hi, _, _, _ in runs]]
        share = np.minimum((work - 0.5) * shares // max(float(work[-1]), 1), shares - 1).astype(int)
        return [[(b, slot, *r) for r, sh in zip(runs, share) if sh == slot] for slot in np.unique(share).tolist()]

    def _run_pass(self, inc: np.ndarray, cost: np.ndarray | None = None) -> None:
        """Give pixel p ``inc[b, p]`` more samples in batch b. A task launches a share of one batch's
        runs (or pieces of its work list) in turn; a batch's runs are split into enough tasks to keep every
        thread busy when a pass feeds fewer batches than there are threads. Tasks of one batch touch
        disjoint pixels, and a pixel gets one launch per batch and pass, so the sums do not depend on
        the split (nor on the number of threads)."""
        fed = [b for b in range(self.B) if inc[b].any()]
        shares = max(1, -(-4 * self.threads // max(1, len(fed)))) if self.threads > 1 else 1
        tasks = [t for b in fed for t in self._batch_tasks(b, inc[b], shares, cost)]
        self.stats.launches += sum(len(t) for t in tasks)
        for task in tasks:
            self._command(*task[0][:2])       # recorded here, not on the workers
        # The renderer's tile runner (parallel.run_jobs): a Ctrl-C only sets its stop flag, so it never
        # lands between a finished launch and its bookkeeping, nor inside a thread pool's locks.
        def work(task, stop, done) -> None:
            for it in task:
                if stop.is_set():
                    return
                self._launch(*it)

        try:
            run_jobs(tasks, work, self.threads, lambda units: None)
            wp.synchronize_device(self.dev.device)    # CUDA launches return at once: the pass's time is its work
        except BaseException:
            self.stop.set()               # no launches after an interruption
            raise

    # -- the loop

    def snapshot(self, last: bool = False) -> RenderResult:
        """The result so far. A ``last`` one (no launch follows) shares the batch buffers instead of
        copying them: at 2560 x 2560 the copies (1.7 GB of fresh memory) took seconds after a Ctrl-C."""
        shape = (self.B, self.height, self.width)
        sums = self.film_memory.numpy().reshape(*shape, 3)
        counts = self.counts.reshape(shape)
        if not last:
            sums, counts = sums.copy(), counts.copy()
        # summed a column at a time: over axis 0 of an (n, 2) array numpy loops over n rows of two
        c = [int(col.sum()) for counters in self.counters for col in counters.numpy().T]
        self.stats.rays, self.stats.dropped_samples = sum(c[0::2]), sum(c[1::2])
        self.stats.pixel_samples = int(self.counts.sum())
        return result_from_batches(sums, counts, self.stats, self.rs)

    def run(self, plan: _Plan, on_pass: PassCallback | None, keep_partial: bool) -> RenderResult:
        result, k, rate, in_flight = None, 0, None, None     # in_flight: when the pass under way began
        try:
            while True:
                inc, why = self._next_pass(plan, k, result, rate)
                if why is not None:
                    self.stats.stopped_by = why
                    break
                t_start = in_flight = time.perf_counter()
                if k == 0:
                    self.stats.setup_seconds = t_start - plan.t0
                result = None                     # launches under way: a new snapshot is needed
                inc, cost = inc if isinstance(inc, tuple) else (inc, None)
                self._run_pass(inc, cost)
                dt = time.perf_counter() - t_start
                in_flight = None
                self.stats.render_seconds += dt
                rate = int(inc.sum()) / max(dt, 1e-6)          # pixel-samples per second
                k += 1
                self.stats.passes = k
                rays_before = self.stats.rays
                result = self.snapshot()
                self.cost_rate = (self.stats.rays - rays_before + SAMPLE_COST_RAYS * int(inc.sum())) / max(dt, 1e-6)
                self.stats.seconds = time.perf_counter() - plan.t0
                self.stats.pass_errors.append(result.relative_error)
                self.stats.pass_seconds.append(self.stats.seconds)
                if on_pass is not None and on_pass(result):
                    self.stats.stopped_by = "callback"
                    break
                # what follows every pass (snapshot, callback) is paid before the caller sees the image
                self.after_pass = time.perf_counter() - t_start - dt
        except KeyboardInterrupt:
            if not keep_partial or not self.counts.any():
                raise
            if in_flight is not None:     # the samples of the pass cut short count, so does its time
                self.stats.render_seconds += time.perf_counter() - in_flight
            self.stats.stopped_by = "interrupt"
            result = None
        if result is None:
            result = self.snapshot(last=True)
        self.stats.seconds = time.perf_counter() - plan.t0
        return result

    def _next_pass(self, plan: _Plan, k: int, result, rate):
        """(samples per batch and pixel (B, n), None) for pass k, or (None, reason to stop)."""
        done = self.counts.sum(axis=0)
        spp_now = int(done.max())
        if result is not None and plan.target_error is not None and result.relative_error <= plan.target_error:
            return None, "error"
        if plan.adaptive and spp_now >= plan.min_spp and result is not None:
            return self._adaptive_pass(plan, k, result, rate)
        # Uniform pass: every pixel, towards the target per-batch counts (the same for every pixel).
        step = 2 if k == 0 else self.B * pass_samples(k, self.n, self.B)   # pass 0: the first estimate
        n_total = min(plan.spp, spp_now + step)
        if plan.adaptive:
            n_total = min(n_total, max(plan.min_spp, spp_now + 1))
        n_total = self._limit_by_error(plan, result, spp_now, n_total)
        n_total = self._limit_by_time(plan, rate, spp_now, n_total, self.n)
        if n_total <= spp_now:
            return None, "spp" if spp_now >= plan.spp else self._budget_reason(plan)
        inc = batch_counts(n_total, self.B) - self.counts[:, 0]
        return np.repeat(inc[:, None], self.n, axis=1), None

    def _limit_by_error(self, plan: _Plan, result, spp_now: int, n_total: int) -> int:
        """Aim the final pass at the target error: error falls as 1/sqrt(spp)."""
        if plan.target_error is None or result is None or spp_now < 2 * self.B:
            return n_total
        e = result.relative_error
        if not math.isfinite(e):
            return n_total
        need = math.ceil(spp_for_error(spp_now, e, plan.target_error))
        return min(n_total, max(need, spp_now + 1))

    def _limit_by_time(self, plan: _Plan, rate, spp_now: int, n_total: int, pixels: int) -> int:
        """Cut the pass so it ends at the deadline (at the measured pixel-samples per second) and
        within the sample budget."""
        if plan.sample_budget is not None:
            left_work = (plan.sample_budget - int(self.counts.sum())) // max(1, pixels)
            n_total = min(n_total, spp_now + max(0, left_work))
        if plan.time_budget is None:
            return n_total
        left = plan.deadline - time.perf_counter() - self.after_pass
        if rate is None:          # first pass (2 spp): no rate yet, and an image needs samples
            return n_total
        affordable = int(left * rate / max(1, pixels))
        return min(n_total, spp_now + max(0, affordable))

    def _budget_reason(self, plan: _Plan) -> str:
        """Which budget ended the render: the time budget if its deadline has passed, else the samples."""
        timed_out = plan.time_budget is not None and time.perf_counter() >= plan.deadline
        return "samples" if plan.sample_budget is not None and not timed_out else "time"

    def _adaptive_pass(self, plan: _Plan, k: int, result: RenderResult, rate):
        """Distribute one pass's work over the pixels so that samples approach the best allocation.

        The image's relative error is an RMS over pixels, sum_p s_p^2 / n_p, with s_p a pixel's
        relative standard deviation per sample (``adaptive_metric="relative"``); its RMSE has the
        same form with s_p the absolute standard deviation per sample (``"rmse"``). For a given
        cost sum_p n_p c_p (c_p: the cost of one of its samples) either is smallest when
        n_p = C s_p / sqrt(c_p) / sum_q s_q sqrt(c_q) (a Lagrange multiplier). Each pass raises the
        cost C by what a uniform pass would spend and gives every pixel what it lacks of that target.
        (Cycles instead stops a pixel once its own error estimate is below a threshold, which
        equalises the per-pixel error, n proportional to s^2: that spends more on the noisiest
        pixels than the RMS error repays.) Pixels whose
        samples are all equal (s = 0) get nothing more.

        s_p^2 and c_p are averaged over the pixel's 3x3 neighbourhood (_box3): the even batches give
        s_p^2 only B/2 - 1 degrees of freedom, and a pixel whose noise is under-estimated by chance
        would be starved. c_p is the pixel's rays per sample in the even batches plus SAMPLE_COST_RAYS
        (docs/error.md): a path's length correlates with its radiance, so the odd batches' ray counts
        stay out of the decisions too.
        A pixel's samples are spread over the batches as a render of that many samples spreads
        them (batch_counts), so the batches stay balanced; one launch per batch walks a compacted
        list of the pixels that get samples (one kernel for uniform and adaptive passes).
        """
        # The decision uses the even batches only; the odd half of every pixel is therefore an
        # unbiased estimate given the decisions, and the image (all batches) carries only the even
        # half's stopping bias, which the tests measure (docs/error.md).
        mean, se, n_dec = batch_statistics(result.sums, result.counts, slice(0, None, 2))
        floor = max(ERROR_FLOOR_FRACTION * float(mean.mean()), 1e-12)
        scale = np.maximum(mean, floor) if plan.adaptive_metric == "relative" else 1.0
        s2 = np.nan_to_num((se / scale) ** 2, nan=np.inf) * n_dec[..., None]
        s = np.sqrt(_box3(s2.mean(axis=2))).reshape(-1)                    # per-sample (relative) std
        done = result.spp.reshape(-1).astype(np.int64)
        rays = sum(c.numpy()[:, 0] for c in self.counters[::2]).reshape(self.height, self.width)   # even too
        cost = np.maximum(_box3(rays / np.maximum(n_dec, 1)).reshape(-1) + SAMPLE_COST_RAYS, 0.1)
        known = np.isfinite(s)
        step = self.B * pass_samples(k, self.n, self.B)
        budget = float((done * cost).sum()) + step * float(cost.sum())     # cost after a uniform pass
        weight = float((np.where(known, s, 0.0) * np.sqrt(cost)).sum())
        target = np.where(known, budget * np.where(known, s, 0.0) / np.sqrt(cost) / max(weight, 1e-300), 0.0)
        inc = np.where(known, np.floor(target - done), step)               # unknown noise: a uniform step
        inc = np.clip(inc, 0, plan.spp - done).astype(np.int64)
        total = int(inc.sum())
        if total == 0:
            return None, "spp"
        # Cut to the sample budget, and to the deadline at the last pass's cost per second: adaptive
        # passes go to costly pixels, so pixel-samples per second would over-promise.
        fraction = self._limit_by_time(plan, None, 0, total, 1) / total
        if plan.time_budget is not None and self.cost_rate > 0:
            left = plan.deadline - time.perf_counter() - self.after_pass
            fraction = min(fraction, max(0.0, left) / (float((inc * cost).sum()) / self.cost_rate))
        if fraction < 1.0:
            inc = (inc * fraction).astype(np.int64)
            if not inc.any():
                return None, self._budget_reason(plan)
        out = batch_counts_per_pixel(done + inc, self.B) - self.counts
        return (out, cost), None


def spp_for_error(spp: float, error: float, target: float) -> float:
    """Samples per pixel at which an image with relative ``error`` at ``spp`` reaches ``target``: error
    falls as 1/sqrt(spp), so spp x (error / target)^2 (the final pass's aim and the CLI's time to go)."""
    return spp * (error / target) ** 2


def batch_counts_per_pixel(spp: np.ndarray, batches: int) -> np.ndarray:
    """:func:`batch_counts` for each pixel's own sample count: (batches, pixels)."""
    b = np.arange(batches)[:, None]
    return spp[None, :] // batches + (b < spp[None, :] % batches).astype(np.int64)


def _box3(a: np.ndarray) -> np.ndarray:
    """The mean over each pixel's 3x3 neighbourhood (edges use the pixels they have); inf spreads."""
    h, w = a.shape
    pad = np.zeros((h + 2, w + 2))
    cnt = np.zeros((h + 2, w + 2))
    pad[1:-1, 1:-1] = a
    cnt[1:-1, 1:-1] = 1.0
    s = sum(pad[i:i + h, j:j + w] for i in range(3) for j in range(3))
    c = sum(cnt[i:i + h, j:j + w] for i in range(3) for j in range(3))
    return s / c


def _runs(inc: np.ndarray, done: np.ndarray) -> list[tuple[int, int]]:
    """Maximal runs of consecutive pixels with the same increment (> 0) and the same sample count, at
    most TILE_PIXELS long. One launch renders a run (the kernel takes a first pixel, one first
    sample index and one sample count)."""
    key = np.where(inc > 0, done * (1 << 31) + inc, -1)
    n = key.size
    edges = np.flatnonzero(np.diff(key)) + 1
    starts = np.concatenate(([0], edges))
    ends = np.concatenate((edges, [n]))
    runs = []
    for lo, hi in zip(starts.tolist(), ends.tolist()):
        if key[lo] < 0:
            continue
        runs += [(p, min(hi, p + TILE_PIXELS)) for p in range(lo, hi, TILE_PIXELS)]
    return runs
