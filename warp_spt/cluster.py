"""Rendering on a ``dask.distributed`` cluster: tasks of sample ranges x row tiles, merged bit for bit.

::

    from dask.distributed import Client
    import warp_spt, warp_spt.cluster

    with warp_spt.cluster.local_client(n_workers=2) as client:      # or Client("tcp://scheduler:8786")
        img = warp_spt.cluster.render(client, scene, camera, width=512, height=512, spp=256, seed=1)
        result = warp_spt.cluster.render_scene(client, scene, camera, RenderSettings(...), ClusterOptions(...))

The image is **bit-identical** to ``warp_spt.render`` with the same scene, camera and
:class:`~warp_spt.rendering.settings.RenderSettings`. Why that holds: the renderer adds each pixel's samples
to its float64 film one *pass* at a time (a pass is a fixed number of samples that depends on the
image size only), so a single-process film is ``((0 + P0) + P1) + P2 ...`` over the per-pass sums
``Pk``. Every ``Pk`` depends only on (seed, pixel, sample index): the random streams key on the
global pixel index, so a task rendering some rows (``render_scene(..., rows=...)``) gets exactly those
rows of the full render. A task renders a run of whole passes of some rows and returns their sums
*separately*; the client adds them in pass order, row tile by row tile. Float64 addition is not
associative, so summing a task's passes on the worker would not do.

What travels: the parsed :class:`~warp_spt.scene.model.Scene` (numpy arrays, textures included), each
mesh apart, keyed by content hashes, never file paths (they need not exist on workers). Each
worker uploads a scene once (:class:`SceneCache`, a worker plugin) and reuses it for all its tasks;
meshes are cached by content too, so an animation's static meshes are shipped and uploaded once
per worker. A worker that dies costs only its tasks: Dask reruns them elsewhere, and because a
task's result depends only on its inputs, the image is unchanged.

With a time budget or a target error, :func:`render_progressive` schedules rounds of passes until
either is met, with warp_spt.rendering.progressive's error estimate (batch buffers with independent seeds).
"""

from __future__ import annotations

import hashlib
import logging
import math
import os
import pickle
import signal
import threading
import time
import uuid
from collections import OrderedDict, deque
from contextlib import contextmanager
from dataclasses import dataclass, fields, replace
from typing import Callable, Iterator, Sequence

import numpy as np

from warp_spt.rendering.film import Film
from warp_spt.rendering.result import RenderResult
from warp_spt.rendering.schedule import (
    batch_spp,
    pass_ranges,
    samples_per_pass,
    unit_passes,
)
from warp_spt.rendering.settings import RenderSettings
from warp_spt.runtime.extras import install_hint
from warp_spt.runtime.progress import ProgressFn, progress_reporter
from warp_spt.scene.camera import Camera
from warp_spt.scene.model import Scene

INSTALL_HINT = 'distributed rendering needs dask.distributed: ' + install_hint("cluster")

try:
    import distributed
    from distributed import WorkerPlugin
except ImportError as _err:  # the [cluster] extra is optional
    raise ImportError(INSTALL_HINT) from _err

PLUGIN_NAME = "warp_spt-scenes"
TASKS_PER_WORKER = 4            # default tasks per worker: a slow or lost worker delays the end little
TASK_FILM_BYTES = 32 << 20      # a task returns at most about this much film per pass: larger images get row tiles
FILM_PIXEL_BYTES = 24           # float64 RGB


@dataclass(frozen=True)
class ClusterOptions:
    """How a render is cut into tasks (what is rendered is a :class:`~warp_spt.rendering.settings.RenderSettings`).

    ``task_spp``: samples per task, rounded to the renderer's passes (default: about
    ``TASKS_PER_WORKER`` tasks per worker). ``tile_rows``: image rows per task (default: the whole
    image, cut into row tiles when it has too few passes to keep every worker busy, or when one
    pass of it would return more than ``TASK_FILM_BYTES``). ``timeout``: seconds for the whole
    render (default: no limit). Render threads per task are ``RenderSettings.threads`` (default 1,
    which suits one Dask thread per core).
    """

    task_spp: int | None = None
    tile_rows: int | None = None
    timeout: float | None = None

    def __post_init__(self) -> None:
        for name in ("task_spp", "tile_rows"):
            v = getattr(self, name)
            if v is not None and (not isinstance(v, (int, np.integer)) or v < 1):
                raise ValueError(f"{name} must be a positive integer, got {v!r}")
        if self.timeout is not None and not self.timeout > 0:
            raise ValueError(f"timeout must be a positive number of seconds, got {self.timeout!r}")


# ---------------------------------------------------------------------------------------------
# The adapter: the only code that knows how the renderer is called, checks its arguments, groups
# samples into passes and reports progress.


@dataclass
class TaskResult:
    """What a task sends back: per-pass float64 sums (passes, rows, W, 3) and the renderer's counters."""

    sums: np.ndarray
    rays: int
    dropped_samples: int
    features: object


def render_passes(dev, camera: Camera, rs: RenderSettings, rows: tuple[int, int],
                  passes: Sequence[tuple[int, int]]) -> TaskResult:
    """Image rows ``rows``, one ``render_scene`` call per pass, the sums of each pass kept apart."""
    from warp_spt.rendering.tiles import render_scene

    results = [render_scene(dev, camera, replace(rs, spp=count, sample_offset=start), rows=tuple(rows))
               for start, count in passes]
    return TaskResult(np.stack([r.film.sum for r in results]), sum(r.stats.rays for r in results),
                      sum(r.stats.dropped_samples for r in results), results[0].stats.features)


def check_settings(rs: RenderSettings) -> None:
    """The renderer's own argument checks, run on the client before anything is submitted."""
    from warp_spt.integrators import check_sliceable, get_integrator
    from warp_spt.rendering.settings import check_args

    check_args(rs)
    check_sliceable(rs.integrator, "the cluster")
    if not get_integrator(rs.integrator).deterministic:     # the bit-exact merge needs the same numbers
        raise ValueError(f"integrator {rs.integrator!r} is not deterministic: its passes cannot be merged")


# ---------------------------------------------------------------------------------------------
# Worker side


class SceneCache(WorkerPlugin):
    """Per-worker cache of uploaded scenes, keyed by content hash (least recently used goes first).

    Meshes are cached apart, by their own content (:func:`warp_spt.upload.device_scene.mesh_key`), so the
    frames of an animation upload their static meshes once per worker. ``builds`` counts scene
    uploads and ``mesh_builds`` mesh uploads (tests check both); ``token`` tells one cache from its
    replacement.
    """

    def __init__(self, size: int = 4) -> None:
        self.size = size
        self.builds = 0
        self.mesh_builds = 0
        self.token = uuid.uuid4().hex
        self._scenes: OrderedDict[str, object] = OrderedDict()
        self._meshes: dict[str, object] = {}
        self._lock = threading.Lock()

    def __getstate__(self) -> dict:
        return {"size": self.size}         # shipped empty; the lock cannot be pickled

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["size"])

    def setup(self, worker) -> None:
        """Initialise Warp quietly (no banner or module-load lines on the worker's stdout)."""
        from warp_spt.runtime.warp_init import init_warp

        init_warp()

    def device_scene(self, key: str, scene: Scene | Callable[[], Scene], rs: RenderSettings):
        """The uploaded scene for ``key`` (``scene``, or a function making it, is used on first use),
        with the kernel ``rs`` needs compiled or loaded.

        Under one lock, so a worker running several task threads uploads once, and compiles or
        loads a kernel module from one thread at a time (Warp's concurrent module loads are unsafe).
        """
        from warp_spt.upload.device_scene import DeviceScene
        from warp_spt.rendering.setup import device_kernel

        with self._lock:
            dev = self._scenes.pop(key, None)
            if dev is None:
                before = len(self._meshes)
                dev = DeviceScene(scene() if callable(scene) else scene, device=rs.device, meshes=self._meshes)
                self.builds += 1
                self.mesh_builds += len(self._meshes) - before
            self._scenes[key] = dev
            while len(self._scenes) > self.size:
                self._scenes.popitem(last=False)
            used = {k for d in self._scenes.values() for k in d.mesh_keys}
            for k in set(self._meshes) - used:
                del self._meshes[k]
            device_kernel(dev, rs)      # the kernel render_scene's set-up will pick, loaded under the lock
            return dev


def _render_task(scene_key: str, parts: tuple, camera: Camera, rs: RenderSettings,
                 rows: tuple[int, int], passes: tuple[tuple[int, int], ...]) -> TaskResult:
    """One task: some passes of some rows of one image, on whichever worker Dask chose.
    ``parts`` is (the scene without meshes and textures, its meshes, its textures)."""
    skeleton, meshes, textures = parts
    cache = distributed.get_worker().plugins[PLUGIN_NAME]
    dev = cache.device_scene(scene_key, lambda: replace(skeleton, meshes=list(meshes), textures=list(textures)), rs)
    return render_passes(dev, camera, rs, rows, passes)


# ---------------------------------------------------------------------------------------------
# Client side: shipping scenes


def scene_key(scene: Scene) -> str:
    """SHA-256 of the scene's content (its pickled arrays): equal scenes share uploads on workers."""
    return hashlib.sha256(pickle.dumps(scene, protocol=5)).hexdigest()


@dataclass
class SharedScene:
    """A scene on the cluster: its content key, its meshes and textures (one Dask future each, so that
    what frames share travels once) and the rest (a future)."""

    key: str
    skeleton: object
    meshes: list
    textures: list

    @property
    def parts(self) -> tuple:
        """What a task takes: (skeleton, meshes, textures); Dask resolves the futures inside."""
        return self.skeleton, self.meshes, self.textures


def share_scene(client, scene: Scene, shared: dict[str, object] | None = None) -> SharedScene:
    """Scatter ``scene`` to the cluster, each mesh and texture apart, keyed by content: what ``shared``
    already holds (the static meshes and textures of an animation's earlier frames) is not sent
    again, and a worker that holds a piece from an earlier task does not fetch it again.

    A DeviceScene is accepted too: its host-side Scene is what travels.
    """
    from warp_spt.upload.device_scene import mesh_key

    scene = getattr(scene, "scene", scene)
    shared = {} if shared is None else shared
    key = scene_key(scene)

    def one(k: str, obj) -> object:
        if k not in shared:
            shared[k] = client.scatter(obj, hash=False)
        return shared[k]

    meshes = [one("mesh:" + mesh_key(m), m) for m in scene.meshes]
    textures = [one("texture:" + _array_key(t), t) for t in scene.textures]
    return SharedScene(key, one("scene:" + key, replace(scene, meshes=[], textures=[])), meshes, textures)


def _array_key(a: np.ndarray) -> str:
    a = np.ascontiguousarray(a)
    return hashlib.sha256(f"{a.dtype}{a.shape}".encode() + a.data).hexdigest()


# ---------------------------------------------------------------------------------------------
# Client side: cutting a render into tasks


@dataclass
class Job:
    """One image to render: a scene already on the cluster, a camera and settings."""

    scene: SharedScene
    camera: Camera
    settings: RenderSettings


@dataclass(frozen=True)
class Task:
    """Passes ((first sample, count), ...) of image rows [first, stop) of job ``job``."""

    job: int
    rows: tuple[int, int]
    passes: tuple[tuple[int, int], ...]


def row_tiles(rs: RenderSettings, groups: int, passes_per_task: int, n_workers: int,
              options: ClusterOptions) -> list[tuple[int, int]]:
    """The row ranges each group of passes is cut into.

    ``options.tile_rows`` if given; else as few tiles as give about ``TASKS_PER_WORKER`` tasks per
    worker (when ``groups`` alone do not and no task size was asked for) and keep a task's
    returned film under ``TASK_FILM_BYTES``.
    """
    rows = rs.height
    if options.tile_rows is not None:
        per_tile = options.tile_rows
    else:
        for_workers = 1 if options.task_spp is not None else math.ceil(TASKS_PER_WORKER * n_workers / groups)
        for_memory = math.ceil(passes_per_task * rows * rs.width * FILM_PIXEL_BYTES / TASK_FILM_BYTES)
        per_tile = math.ceil(rows / min(rows, max(1, for_workers, for_memory)))
    return [(y, min(rows, y + per_tile)) for y in range(0, rows, per_tile)]


def plan(rs: RenderSettings, n_workers: int, options: ClusterOptions = ClusterOptions(), job: int = 0) -> list[Task]:
    """The tasks of one image: groups of whole passes (about ``options.task_spp`` samples each) x row tiles.

    Submitted in this order: every tile of the first passes, then of the next, and so on.
    """
    passes = pass_ranges(rs.spp, rs.width, rs.height, rs.sample_offset)
    if options.task_spp is None:
        per_task = max(1, math.ceil(len(passes) / (TASKS_PER_WORKER * max(1, n_workers))))
    else:
        per_task = max(1, round(options.task_spp / passes[0][1]))
    groups = [tuple(passes[i:i + per_task]) for i in range(0, len(passes), per_task)]
    tiles = row_tiles(rs, len(groups), per_task, max(1, n_workers), options)
    return [Task(job, rows, g) for g in groups for rows in tiles]


def register(client) -> None:
    """Install the scene cache on every worker (and on workers that join or restart later).

    Skipped when every worker has it already: registering again would empty the caches, and every
    render would upload its scene anew.
    """
    present = client.run(lambda dask_worker: PLUGIN_NAME in dask_worker.plugins)
    if not present or not all(present.values()):
        client.register_plugin(SceneCache(), name=PLUGIN_NAME)


def n_workers(client) -> int:
    """Workers the scheduler knows now (at least 1)."""
    return max(1, len(client.scheduler_info().get("workers", {})))


class _OrderedMerge:
    """Adds every task's per-pass sums to its job's film rows strictly in submission order per
    (job, rows): every pixel gets its passes in pass order, the single-process order, bit for bit."""

    def __init__(self, jobs: Sequence[Job]) -> None:
        self.films = [Film.empty(j.settings.height, j.settings.width) for j in jobs]
        self.rays = [0] * len(jobs)
        self.dropped = [0] * len(jobs)
        self.features = [None] * len(jobs)
        self._queues: dict[tuple, deque] = {}
        self._waiting: dict[int, TaskResult] = {}

    def expect(self, tid: int, task: Task) -> None:
        self._queues.setdefault((task.job, task.rows), deque()).append((tid, task))

    def add(self, tid: int, task: Task, result: TaskResult) -> None:
        self._waiting[tid] = result
        queue = self._queues[(task.job, task.rows)]
        while queue and queue[0][0] in self._waiting:
            t_id, t = queue.popleft()
            r = self._waiting.pop(t_id)
            rows = self.films[t.job].sum[t.rows[0]:t.rows[1]]
            for s in r.sums:
                rows += s
            self.rays[t.job] += r.rays
            self.dropped[t.job] += r.dropped_samples
            self.features[t.job] = r.features


def _run_tasks(client, jobs: Sequence[Job], tasks: Sequence[Task], merge: _OrderedMerge,
               report: Callable[[int | None], None], timeout: float | None) -> Iterator[int]:
    """Submit ``tasks`` at once, merge their results as they come; yield each job's index when the
    last of its tasks among these is merged."""
    left = [0] * len(jobs)
    futures, owner = [], {}
    for task in tasks:
        job = jobs[task.job]
        f = client.submit(_render_task, job.scene.key, job.scene.parts, job.camera, job.settings, task.rows,
                          task.passes, pure=False)
        tid = len(futures)
        futures.append(f)
        owner[f.key] = (tid, task)
        merge.expect(tid, task)
        left[task.job] += 1
    try:
        for future, result in distributed.as_completed(futures, with_results=True, timeout=timeout):
            tid, task = owner[future.key]
            merge.add(tid, task, result)
            report(sum(c for _, c in task.passes) * (task.rows[1] - task.rows[0]) * jobs[task.job].settings.width)
            left[task.job] -= 1
            if left[task.job] == 0:
                yield task.job
    finally:
        client.cancel(futures)


def run_jobs(client, jobs: Sequence[Job], options: ClusterOptions = ClusterOptions(), *,
             progress: bool | ProgressFn = False) -> Iterator[tuple[int, RenderResult]]:
    """Render every job on the cluster; yield (job index, RenderResult) as each image completes.

    Tasks of all jobs are submitted at once (frames x sample ranges x row tiles); each film is
    merged in pass order, whatever order its tasks finish in. ``progress`` counts finished samples
    x pixels across all workers.
    """
    from warp_spt.rendering.result import RenderStats

    for job in jobs:
        check_settings(job.settings)
    register(client)
    workers = n_workers(client)
    tasks = [t for j, job in enumerate(jobs) for t in plan(job.settings, workers, options, j)]
    total = sum(j.settings.width * j.settings.height * j.settings.spp for j in jobs)
    report = progress_reporter(progress, total)
    merge = _OrderedMerge(jobs)
    start = time.perf_counter()
    try:
        for j in _run_tasks(client, jobs, tasks, merge, report, options.timeout):
            rs = jobs[j].settings
            film = merge.films[j]
            film.spp = rs.spp
            stats = RenderStats(merge.features[j], rs.integrator, rs.sampler, time.perf_counter() - start,
                                merge.rays[j], merge.dropped[j], len({t.rows for t in tasks if t.job == j}),
                                workers * (rs.threads or 1))
            yield j, RenderResult(film, stats, rs)
    finally:
        report(None)


def settings_for(kw: dict) -> tuple[RenderSettings, ClusterOptions]:
    """Split keyword arguments into RenderSettings fields and ClusterOptions fields (unknown: TypeError)."""
    names = {f.name for f in fields(ClusterOptions)}
    render_kw = {k: v for k, v in kw.items() if k not in names}
    unknown = set(render_kw) - {f.name for f in fields(RenderSettings)}
    if unknown:
        raise TypeError(f"unknown render setting(s): {', '.join(sorted(unknown))}")
    return RenderSettings(**render_kw), ClusterOptions(**{k: v for k, v in kw.items() if k in names})


def cluster_settings(rs: RenderSettings) -> RenderSettings:
    """``rs`` as tasks run it: one render thread per task unless ``threads`` says otherwise (the sky, when
    the settings name none, is the scene's own, shipped with the scene)."""
    return replace(rs, threads=rs.threads or 1)


def render_scene(client, scene: Scene, camera: Camera | None = None, settings: RenderSettings | None = None,
                 options: ClusterOptions | None = None, *, progress: bool | ProgressFn = False) -> RenderResult:
    """Like :func:`warp_spt.rendering.tiles.render_scene`, on the cluster behind ``client``: the same film bit
    for bit (a host Scene far from the origin is recentred here first, as the renderer does)."""
    from warp_spt.rendering.setup import check_inputs
    from warp_spt.scene.recentre import recentre

    check_inputs(scene, camera)
    rs = cluster_settings(settings or RenderSettings())
    if isinstance(scene, Scene):
        scene, camera, _ = recentre(scene, camera)
    job = Job(share_scene(client, scene), camera or Camera(), rs)
    for _, result in run_jobs(client, [job], options or ClusterOptions(), progress=progress):
        return result
    raise RuntimeError("the cluster returned no film")      # unreachable: run_jobs yields once


def render_film(client, scene: Scene, camera: Camera | None = None, *, progress: bool | ProgressFn = False,
                **kw) -> Film:
    """Like :func:`warp_spt.render_film` on the cluster; keywords are the fields of RenderSettings
    and of :class:`ClusterOptions`."""
    rs, options = settings_for(kw)
    return render_scene(client, scene, camera, rs, options, progress=progress).film


def render(client, scene: Scene, camera: Camera | None = None, **kwargs) -> np.ndarray:
    """Like :func:`warp_spt.render` on the cluster: float32 (H, W, 3) linear radiance (arguments
    as :func:`render_film`)."""
    return render_film(client, scene, camera, **kwargs).image()


# ---------------------------------------------------------------------------------------------
# Budgets and target errors: rounds of passes until the budget or the error is met
#
# The error estimate is warp_spt.rendering.progressive's: ``batches`` films with independent seeds
# ``batch_seed(seed, b)``, whose spread estimates each pixel's standard error. Work is cut into
# *units*, one renderer pass of one batch each, batches in turn; a round submits some units (x row
# tiles), waits for them, and decides the next round from the merged estimate and the measured rate.
# Rounds end on whole units, so a batch's film always equals a plain render of its samples with its
# seed, and a run stopped after any round equals a run asked for exactly the samples it has.


def render_progressive(client, scene: Scene, camera: Camera | None = None, settings: RenderSettings | None = None,
                       options: ClusterOptions | None = None, *, time_budget: float | None = None,
                       target_error: float | None = None, batches: int | None = None,
                       on_pass: Callable | None = None, started: float | None = None):
    """Render on the cluster in rounds until ``settings.spp`` (the maximum), ``time_budget`` seconds
    (counted from ``started``, a ``time.perf_counter()`` value; default now) or ``target_error``
    (:func:`warp_spt.rendering.result.relative_error` of the estimate) is reached.

    Returns a :class:`warp_spt.RenderResult` (image, standard-error map, batch
    buffers, stats; ``stats.passes`` counts rounds). ``on_pass(result)`` is called after every
    round; True stops. Batch b's film is bit for bit ``warp_spt.render_film(scene, camera,
    seed=batch_seed(seed, b), spp=<its samples>)``, and a run stopped by a budget equals this
    function asked for ``result.spp_total`` samples without one. (It is not the in-process
    ``render_progressive`` image: that one launches each batch's pass as one float64 sum.)
    """
    from warp_spt.rendering.result import RenderStats
    from warp_spt.rendering.schedule import DEFAULT_BATCHES, batch_seed
    from warp_spt.rendering.setup import check_inputs
    from warp_spt.scene.recentre import recentre

    t0 = time.perf_counter() if started is None else started
    rs = cluster_settings(settings or RenderSettings())
    batches = DEFAULT_BATCHES if batches is None else batches
    check_inputs(scene, camera)
    check_settings(rs)
    _check_budget(rs, time_budget, target_error, batches)
    options = options or ClusterOptions()
    if isinstance(scene, Scene):
        scene, camera, _ = recentre(scene, camera)
    shared = share_scene(client, scene)
    jobs = [Job(shared, camera or Camera(), replace(rs, seed=batch_seed(rs.seed, b))) for b in range(batches)]
    register(client)
    workers = n_workers(client)
    rounds = _Rounds(rs, batches, time_budget, target_error, t0, max(batches, TASKS_PER_WORKER * workers))
    merge = _OrderedMerge(jobs)
    stats = RenderStats(threads=workers * rs.threads, integrator=rs.integrator, sampler=rs.sampler)
    result = None
    while True:
        n, why = rounds.next(result)
        if why is not None:
            stats.stopped_by = why
            break
        tiles = row_tiles(rs, n, 1, workers, options)
        tasks = [Task(b, rows, (p,)) for u in range(rounds.units, rounds.units + n)
                 for b, p in [unit_passes(u, rs.spp, rounds.per_pass, batches)] for rows in tiles]
        t = time.perf_counter()
        timeout = None if options.timeout is None else max(1e-3, options.timeout - (t - t0))
        for _ in _run_tasks(client, jobs, tasks, merge, lambda inc: None, timeout):
            pass
        stats.render_seconds += time.perf_counter() - t
        rounds.done(n, time.perf_counter() - t)
        result = _snapshot(merge, rounds, stats, t0)
        if on_pass is not None and on_pass(result):
            stats.stopped_by = "callback"
            break
    return result


def _check_budget(rs: RenderSettings, time_budget, target_error, batches) -> None:
    """progressive's checks of the budget arguments, and the cluster's own."""
    from warp_spt.rendering.progressive import check_budget as check_progressive_budget

    if rs.sample_offset:
        raise ValueError("a budgeted render owns its sample indices: sample_offset is not taken")
    check_progressive_budget(time_budget, target_error, batches, None)


class _Rounds:
    """The schedule: how many units the next round gets, or why the render stops."""

    def __init__(self, rs: RenderSettings, batches: int, time_budget, target_error, t0: float, cap: int):
        self.spp, self.B, self.cap = rs.spp, batches, cap
        self.per_pass = samples_per_pass(rs.width, rs.height)
        self.total = math.ceil(rs.spp / self.per_pass)
        self.deadline = math.inf if time_budget is None else t0 + time_budget
        self.target = target_error
        self.units, self.rounds, self.rate = 0, 0, 0.0      # rate: units per second in the last round

    def next(self, result) -> tuple[int, str | None]:
        left = self.total - self.units
        if left <= 0:
            return 0, "spp"
        if self.rounds == 0:
            return min(2, left), None           # two batches: the first error estimate
        e = result.relative_error
        if self.target is not None and e <= self.target:
            return 0, "error"
        n = min(left, self.cap, 2 ** self.rounds)
        if self.target is not None and math.isfinite(e) and self.units >= self.B:
            # aim at the target: error falls as 1 / sqrt(samples)
            need_spp = math.ceil(min(self.units * self.per_pass, self.spp) * (e / self.target) ** 2)
            n = min(n, max(1, math.ceil(need_spp / self.per_pass) - self.units))
        if self.deadline < math.inf:
            n = min(n, int((self.deadline - time.perf_counter()) * self.rate))
            if n <= 0:
                return 0, "time"
        return n, None

    def done(self, n: int, seconds: float) -> None:
        self.units += n
        self.rounds += 1
        self.rate = n / max(seconds, 1e-6)


def _snapshot(merge: _OrderedMerge, rounds: _Rounds, stats, t0: float):
    from warp_spt.rendering.result import RenderResult

    sums = np.stack([f.sum for f in merge.films])
    per_batch = batch_spp(rounds.units, rounds.spp, rounds.per_pass, rounds.B)
    counts = np.broadcast_to(per_batch[:, None, None], sums.shape[:3]).copy()
    stats.passes = rounds.rounds
    stats.rays, stats.dropped_samples = sum(merge.rays), sum(merge.dropped)
    stats.pixel_samples = int(counts.sum())
    stats.seconds = time.perf_counter() - t0
    result = RenderResult.from_batches(sums, counts, stats)
    stats.pass_errors.append(result.relative_error)
    stats.pass_seconds.append(stats.seconds)
    return result


@contextmanager
def local_client(n_workers: int = 2, *, threads_per_worker: int = 1, **cluster_kwargs) -> Iterator[object]:
    """A ``LocalCluster`` of ``n_workers`` processes on the loopback interface, and its Client; closed after."""
    if not isinstance(n_workers, int) or n_workers < 1:
        raise ValueError(f"n_workers must be a positive integer, got {n_workers!r}")
    options = dict(n_workers=n_workers, threads_per_worker=threads_per_worker, processes=True,
                   host="127.0.0.1", dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
    options.update(cluster_kwargs)
    from warp_spt.runtime.signals import deferred_signals

    cluster = client = None
    try:
        # A Ctrl-C while the workers start waits for the start to end (seconds): cut short, the
        # event loop's thread went on forking workers after this thread had given up, and those
        # printed tracebacks as this process exited. Once started, every worker is known and killed
        # at once. A second Ctrl-C cuts the start short.
        with deferred_signals(second_now=True):
            cluster = distributed.LocalCluster(**options)
            client = distributed.Client(cluster)
    except BaseException:
        if cluster is None:
            _kill_children()
        else:
            _abandon(cluster, client)
        raise
    try:
        yield client
    except BaseException:          # Ctrl-C, SIGTERM or an error: nothing the workers do is wanted
        _abandon(cluster, client)
        raise
    client.close()
    cluster.close()


ABANDON_SECONDS = 2.0     # what closing a cluster whose workers were killed may take, at most


def _kill_children() -> None:
    """Kill this process's multiprocessing children at once: what a start cut short by a second Ctrl-C
    or an error leaves (a worker forked after this still finds its semaphores gone, and
    :mod:`warp_spt.runtime.forkserver_preload` keeps it quiet)."""
    import multiprocessing

    for child in multiprocessing.active_children():
        try:
            child.kill()
            child.join(1.0)
        except Exception:                   # already gone, or not ours to join
            pass


def _abandon(cluster, client=None) -> None:
    """Close a local cluster whose work is no longer wanted, at once and quietly.

    A graceful close waits for every worker's running task, and a Warp kernel launch cannot be cut
    short: seconds. Here the worker processes are killed first (they hold nothing that is not in
    this process), then the client and the cluster close; the scheduler's and nannies' reports of
    the workers and scattered data lost that way are the interruption's doing, not news, and are
    silenced while it closes."""
    import gc

    loggers = [logging.getLogger(n) for n in ("distributed", "distributed.scheduler", "distributed.nanny",
                                             "distributed.client", "distributed.core", "distributed.worker",
                                             "asyncio")]
    levels = [lg.level for lg in loggers]
    for lg in loggers:
        lg.setLevel(logging.CRITICAL + 1)
    try:
        for nanny in list(getattr(cluster, "workers", {}).values()):
            pid = getattr(getattr(nanny, "process", None), "pid", None)
            if pid:
                try:
                    os.kill(pid, signal.SIGKILL)
                except OSError:             # already gone
                    pass
        for closing in (client, cluster):
            if closing is not None:
                try:
                    closing.close(timeout=ABANDON_SECONDS)
                except Exception:           # closing what is half gone may fail: the interruption counts
                    pass
        gc.collect()        # the closed connections' futures report their errors when collected: now
    finally:
        for lg, level in zip(loggers, levels):
            lg.setLevel(level)


@contextmanager
def connect(address: str, timeout: float = 30.0) -> Iterator[object]:
    """A Client of the running scheduler at ``address`` (e.g. ``tcp://host:8786``); closed after."""
    with distributed.Client(address, timeout=timeout) as client:
        yield client
