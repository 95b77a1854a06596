"""One pass of an integrator that schedules its own passes (``Integrator.render_passes``).

``run_pass`` launches ``count`` samples of every pixel of the tiles, in launches of at most
``per_launch`` samples, from the worker threads; each running job takes one of ``slots`` (a
worker's own record arrays, which the host sums after the pass: fixed-point sums are exact in any
order, so the result does not depend on which job had which slot) and passes what
``inputs(slot)`` gives after the fast kernel's inputs. ``guided`` and ``ears`` use it.
"""

from __future__ import annotations

import queue
from typing import Callable

import warp as wp

from warp_spt.integrators.common import fast_inputs
from warp_spt.runtime.threads import run_jobs


def run_pass(b, tiles: list[tuple[int, int]], film: wp.array, counters: wp.array2d, threads: int, report,
             per_launch: int, first: int, count: int, slots: list, inputs: Callable[[object], list],
             params: Callable | None = None) -> int:
    """Render samples ``first .. first + count - 1`` (relative to the settings' ``sample_offset``) of
    the tiles' pixels; ``params(lo, first, count)`` builds each launch's RenderParams (default
    ``b.params``). Returns the launches made."""
    params = params or b.params
    free = queue.SimpleQueue()              # one slot per concurrently running job
    for s in slots:
        free.put(s)
    chunks = [(first + s, min(per_launch, count - s)) for s in range(0, count, per_launch)]

    def work(tile, stop, done) -> None:
        lo, hi = tile
        slot = free.get()
        try:
            for s0, n in chunks:
                if stop.is_set():
                    return
                wp.launch(b.kernel, dim=hi - lo, device=b.dev.device,
                          inputs=fast_inputs(b.scene_args(params(lo, s0, n)), film, counters) + inputs(slot))
                done(n * (hi - lo))
        finally:
            free.put(slot)

    run_jobs(tiles, work, threads, report)
    return len(tiles) * len(chunks)
