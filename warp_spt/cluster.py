"""Rendering on a ``dask.distributed`` cluster: sample-range tasks, merged bit for bit.

::

    from dask.distributed import Client
    import warp_spt, warp_spt.cluster

    with warp_spt.cluster.local_client(n_workers=2) as client:      # or Client("tcp://scheduler:8786")
        img = warp_spt.cluster.render(client, scene, camera, width=512, height=512, spp=256, seed=1)

The image is **bit-identical** to ``warp_spt.render`` with the same scene, camera, seed and settings.
Why that holds: the renderer adds each pixel's samples to its float64 film one *pass* at a time
(a pass is a fixed number of samples that depends on the image size only), so a single-process
film is ``((0 + P0) + P1) + P2 ...`` over the per-pass sums ``Pk``. Every ``Pk`` depends only on
(seed, pixel, sample index), so any process can compute it; a task here renders a run of whole
passes and returns their sums *separately*, and the client adds them in pass order. Float64
addition is not associative, so summing a task's passes on the worker would not do.

What travels: the parsed :class:`~warp_spt.scene.Scene` (numpy arrays, textures included), scattered
once per render and keyed by a SHA-256 of its content, never file paths (they need not exist on
workers). Each worker uploads a scene once (:class:`SceneCache`, a worker plugin) and reuses it for
all its tasks. A worker that dies costs only its tasks: Dask reruns them elsewhere, and because a
task's result depends only on its inputs, the image is unchanged.

Tiles are not split across tasks: the renderer renders whole images and its random streams are
keyed by the global pixel index, so a pixel-range task would need the renderer's kernel interface.
Large images are split by sample ranges only.
"""

from __future__ import annotations

import hashlib
import logging
import math
import pickle
import threading
import uuid
from collections import OrderedDict
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Callable, Iterator, Sequence

import numpy as np

from .camera import Camera
from .film import Film
from .scene import Scene
from .sky import Sky

INSTALL_HINT = 'distributed rendering needs dask.distributed: pip install "warp-spt[cluster]"'

try:
    import distributed
    from distributed import WorkerPlugin
except ImportError as _err:  # the [cluster] extra is optional
    raise ImportError(INSTALL_HINT) from _err

PLUGIN_NAME = "warp_spt-scenes"
ProgressFn = Callable[[int, int], None]


@dataclass(frozen=True)
class Settings:
    """What a render needs besides the scene and camera (the arguments of ``warp_spt.render``)."""

    width: int = 500
    height: int = 500
    spp: int = 16
    max_depth: int = 6
    sky: Sky = field(default_factory=Sky.black)
    seed: int = 0
    texture_filter: str = "nearest"


# ---------------------------------------------------------------------------------------------
# The adapter: the only code that knows how the renderer is called, checks its arguments, groups
# samples into passes and reports progress (after the renderer's restructuring, only this changes).


def pass_ranges(settings: Settings) -> list[tuple[int, int]]:
    """The renderer's passes as (first sample, sample count), in the order it adds them to the film."""
    from .renderer import PASS_SAMPLES, PASS_WORK

    per_pass = max(PASS_SAMPLES, PASS_WORK // (settings.width * settings.height))
    return [(s, min(per_pass, settings.spp - s)) for s in range(0, settings.spp, per_pass)]


def render_passes(dev, camera: Camera, settings: Settings, passes: Sequence[tuple[int, int]],
                  threads: int = 1) -> np.ndarray:
    """Per-pass float64 sums, shape (len(passes), H, W, 3): one ``render_film`` call per pass."""
    from .renderer import render_film

    return np.stack([
        render_film(dev, camera, width=settings.width, height=settings.height, spp=count,
                    max_depth=settings.max_depth, sky=settings.sky, seed=settings.seed,
                    sample_offset=start, texture_filter=settings.texture_filter, threads=threads).sum
        for start, count in passes])


def check_settings(settings: Settings) -> None:
    """The renderer's own argument checks, run on the client before anything is submitted."""
    from .renderer import RenderSettings, _check_args

    s = settings
    _check_args(RenderSettings(width=s.width, height=s.height, spp=s.spp, max_depth=s.max_depth, sky=s.sky,
                               seed=s.seed, texture_filter=s.texture_filter))


def progress_reporter(progress: bool | ProgressFn, total: int) -> Callable[[int | None], None]:
    """The renderer's progress adapter: takes increments, None closes the bar."""
    from .renderer import _progress_reporter

    return _progress_reporter(progress, total)


# ---------------------------------------------------------------------------------------------
# Worker side


class SceneCache(WorkerPlugin):
    """Per-worker cache of uploaded scenes, keyed by content hash (least recently used goes first).

    ``builds`` counts uploads, so tests can check that a worker uploads each scene once; ``token``
    tells one cache from its replacement.
    """

    def __init__(self, size: int = 4) -> None:
        self.size = size
        self.builds = 0
        self.token = uuid.uuid4().hex
        self._scenes: OrderedDict[str, object] = OrderedDict()
        self._lock = threading.Lock()

    def __getstate__(self) -> dict:
        return {"size": self.size}         # shipped empty; the lock cannot be pickled

    def __setstate__(self, state: dict) -> None:
        self.__init__(state["size"])

    def setup(self, worker) -> None:
        """Initialise Warp quietly (no banner or module-load lines on the worker's stdout)."""
        from .warp_runtime import init_warp

        init_warp()

    def device_scene(self, key: str, scene: Scene):
        """The uploaded scene for ``key``, uploading ``scene`` on first use.

        Under one lock, so a worker running several task threads uploads once, and compiles or
        loads the kernel module from one thread at a time (Warp's concurrent module loads are unsafe).
        """
        from dataclasses import replace

        from .device_scene import DeviceScene
        from .integrators import DEFAULT_INTEGRATOR, get_kernel
        from .samplers import DEFAULT_SAMPLER

        with self._lock:
            dev = self._scenes.pop(key, None)
            if dev is None:
                dev = DeviceScene(scene)
                for sky in (False, True):    # the render picks by whether the sky emits
                    get_kernel(replace(dev.features, sky=sky), dev.device, DEFAULT_INTEGRATOR, DEFAULT_SAMPLER)
                self.builds += 1
            self._scenes[key] = dev
            while len(self._scenes) > self.size:
                self._scenes.popitem(last=False)
            return dev


def _render_task(scene_key: str, scene: Scene, camera: Camera, settings: Settings,
                 passes: list[tuple[int, int]], threads: int) -> np.ndarray:
    """One task: a run of whole passes of one image, on whichever worker Dask chose."""
    cache = distributed.get_worker().plugins[PLUGIN_NAME]
    return render_passes(cache.device_scene(scene_key, scene), camera, settings, passes, threads)


# ---------------------------------------------------------------------------------------------
# Client side


def scene_key(scene: Scene) -> str:
    """SHA-256 of the scene's content (its pickled arrays): equal scenes share uploads on workers."""
    return hashlib.sha256(pickle.dumps(scene, protocol=5)).hexdigest()


@dataclass
class Job:
    """One image to render: a scene (already on the cluster), a camera and settings."""

    key: str
    scene: object                 # a Dask future holding the Scene
    camera: Camera
    settings: Settings


def share_scene(client, scene: Scene, shared: dict[str, object] | None = None) -> tuple[str, object]:
    """(content key, future) for ``scene``, scattering it only when ``shared`` does not hold it yet.

    A DeviceScene is accepted too: its host-side Scene is what travels.
    """
    scene = getattr(scene, "scene", scene)
    key = scene_key(scene)
    if shared is not None and key in shared:
        return key, shared[key]
    future = client.scatter(scene, hash=False)
    if shared is not None:
        shared[key] = future
    return key, future


def tasks_for(settings: Settings, n_workers: int, task_spp: int | None = None) -> list[list[tuple[int, int]]]:
    """Group the passes into tasks of about ``task_spp`` samples (rounded to whole passes).

    By default about four tasks per worker, so a slow or lost worker delays the end little.
    """
    passes = pass_ranges(settings)
    if task_spp is None:
        per_task = max(1, math.ceil(len(passes) / (4 * max(1, n_workers))))
    else:
        if task_spp < 1:
            raise ValueError(f"task_spp must be a positive integer, got {task_spp!r}")
        per_task = max(1, round(task_spp / passes[0][1]))
    return [passes[i:i + per_task] for i in range(0, len(passes), per_task)]


def register(client) -> None:
    """Install the scene cache on every worker (and on workers that join or restart later).

    Skipped when every worker has it already: registering again would empty the caches, and every
    render would upload its scene anew.
    """
    present = client.run(lambda dask_worker: PLUGIN_NAME in dask_worker.plugins)
    if not present or not all(present.values()):
        client.register_plugin(SceneCache(), name=PLUGIN_NAME)


def run_jobs(client, jobs: Sequence[Job], *, task_spp: int | None = None, threads: int = 1,
             progress: bool | ProgressFn = False, timeout: float | None = None) -> Iterator[tuple[int, Film]]:
    """Render every job on the cluster; yield (job index, Film) as each image completes.

    Tasks of all jobs are submitted at once (frames x sample ranges); each film is merged in pass
    order, whatever order its tasks finish in. ``progress`` counts finished samples x pixels across
    all workers; ``timeout`` (seconds) bounds the whole run.
    """
    for job in jobs:
        check_settings(job.settings)
    register(client)
    n_workers = max(1, len(client.scheduler_info().get("workers", {})))
    futures, owner = [], {}
    plans = []
    for j, job in enumerate(jobs):
        plan = tasks_for(job.settings, n_workers, task_spp)
        plans.append(plan)
        for t, passes in enumerate(plan):
            f = client.submit(_render_task, job.key, job.scene, job.camera, job.settings, passes, threads,
                              pure=False)
            futures.append(f)
            owner[f.key] = (j, t)
    total = sum(j.settings.width * j.settings.height * j.settings.spp for j in jobs)
    report = progress_reporter(progress, total)
    merger = _OrderedMerge(jobs, plans)
    try:
        for future, sums in distributed.as_completed(futures, with_results=True, timeout=timeout):
            j, t = owner[future.key]
            film = merger.add(j, t, sums)
            report(sum(c for _, c in plans[j][t]) * jobs[j].settings.width * jobs[j].settings.height)
            if film is not None:
                yield j, film
    finally:
        report(None)
        client.cancel(futures)


class _OrderedMerge:
    """Adds each job's per-pass sums to its film strictly in pass order (the bit-exact order)."""

    def __init__(self, jobs: Sequence[Job], plans: list[list[list[tuple[int, int]]]]) -> None:
        self.plans = plans
        self.films = [Film.empty(j.settings.height, j.settings.width) for j in jobs]
        self.waiting: list[dict[int, np.ndarray]] = [{} for _ in jobs]
        self.next = [0] * len(jobs)

    def add(self, j: int, t: int, sums: np.ndarray) -> Film | None:
        """Store task t's sums; merge what is now in order; return the film once it is complete."""
        self.waiting[j][t] = sums
        while self.next[j] in self.waiting[j]:
            t_next = self.next[j]
            for (_, count), s in zip(self.plans[j][t_next], self.waiting[j].pop(t_next)):
                self.films[j].accumulate(s, count)
            self.next[j] += 1
        return self.films[j] if self.next[j] == len(self.plans[j]) else None


def render_film(client, scene: Scene, camera: Camera | None = None, *, width: int = 500, height: int = 500,
                spp: int = 16, max_depth: int = 6, sky: Sky | None = None, seed: int = 0,
                texture_filter: str = "nearest", task_spp: int | None = None, threads: int = 1,
                progress: bool | ProgressFn = False, timeout: float | None = None) -> Film:
    """Like :func:`warp_spt.render_film`, on the cluster behind ``client``; the same film bit for bit.

    ``task_spp`` is the samples per task (rounded to the renderer's passes; default about four tasks
    per worker); ``threads`` is the render threads per task (1 suits one Dask thread per core).
    """
    settings = Settings(width, height, spp, max_depth, sky or Sky.black(), seed, texture_filter)
    key, future = share_scene(client, scene)
    job = Job(key, future, camera or Camera(), settings)
    for _, film in run_jobs(client, [job], task_spp=task_spp, threads=threads, progress=progress,
                            timeout=timeout):
        return film
    raise RuntimeError("the cluster returned no film")      # unreachable: run_jobs yields once


def render(client, scene: Scene, camera: Camera | None = None, **kwargs) -> np.ndarray:
    """Like :func:`warp_spt.render` on the cluster: float32 (H, W, 3) linear radiance.

    Takes the arguments of :func:`render_film` (this module's).
    """
    return render_film(client, scene, camera, **kwargs).image()


@contextmanager
def local_client(n_workers: int = 2, *, threads_per_worker: int = 1, **cluster_kwargs) -> Iterator[object]:
    """A ``LocalCluster`` of ``n_workers`` processes on the loopback interface, and its Client; closed after."""
    if not isinstance(n_workers, int) or n_workers < 1:
        raise ValueError(f"n_workers must be a positive integer, got {n_workers!r}")
    options = dict(n_workers=n_workers, threads_per_worker=threads_per_worker, processes=True,
                   host="127.0.0.1", dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR)
    options.update(cluster_kwargs)
    with distributed.LocalCluster(**options) as cluster, distributed.Client(cluster) as client:
        yield client


@contextmanager
def connect(address: str, timeout: float = 30.0) -> Iterator[object]:
    """A Client of the running scheduler at ``address`` (e.g. ``tcp://host:8786``); closed after."""
    with distributed.Client(address, timeout=timeout) as client:
        yield client
