"""The one process-wide cache of built Warp kernels and functions, behind one lock.

Building a kernel (the Python closures that specialise it for a scene's features, an integrator and
a sampler) is deterministic, and a kernel built twice is compiled twice and occupies two modules:
so every builder asks this cache for ``(kind, *key)`` instead of keeping a dictionary of its own.
Warp's disk cache keeps the compiled code across processes; this one keeps the Python objects.

The lock is re-entrant because builders nest (the fast kernel asks for the integrator's step, which
asks for the sampler). Loading a kernel's module onto a device (:func:`load`) happens outside it,
on the caller's thread, so that a compile does not block unrelated look-ups.
"""

from __future__ import annotations

import functools
import threading
from typing import Callable, Hashable, TypeVar

T = TypeVar("T")

_built: dict[tuple, object] = {}
_lock = threading.RLock()


def cached(kind: str, key: Hashable, build: Callable[[], T]) -> T:
    """The object built by ``build()`` for ``(kind, key)``, built once per process."""
    full = (kind, key)
    with _lock:
        if full not in _built:
            _built[full] = build()
        return _built[full]


def memoize(kind: str) -> Callable[[Callable[..., T]], Callable[..., T]]:
    """Decorator: cache a builder's results in this cache under ``(kind, args, kwargs)`` (a locked
    ``functools.cache``; the arguments must be hashable)."""

    def wrap(fn: Callable[..., T]) -> Callable[..., T]:
        @functools.wraps(fn)
        def get(*args, **kwargs) -> T:
            return cached(kind, (args, tuple(sorted(kwargs.items()))), lambda: fn(*args, **kwargs))

        return get

    return wrap


def load(kernel, device: str = "cpu"):
    """Compile or load ``kernel``'s module on ``device`` (initialising Warp first, quietly, once);
    returns the kernel. Call it on the launching thread before any worker launches the kernel."""
    import warp as wp

    from warp_spt.runtime.warp_init import init_warp

    init_warp()
    wp.load_module(kernel.module, device=device)
    return kernel


def entries(kind: str | None = None) -> list[tuple]:
    """The keys held (of one ``kind``, or all): for tests and diagnostics."""
    with _lock:
        return [k for k in _built if kind is None or k[0] == kind]
