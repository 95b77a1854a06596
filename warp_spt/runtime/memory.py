"""Large host arrays go back to the operating system when they are freed.

glibc's malloc serves a request from its heap unless it is larger than a threshold, and that
threshold grows to the size of the largest block freed so far (up to 32 MiB). A large mesh's
arrays, built and freed one after another while it loads and uploads (tens of MiB each at a
million triangles), then land in the heap, and their freed space is never returned: at a million
triangles the process kept about 150 MB more than it used (benchmarks/bench_scaling.py). A fixed
threshold of 1 MiB maps every large array on its own, so freeing it releases it at once; arrays
of the render loop are smaller than that or allocated once per render.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import sys

M_MMAP_THRESHOLD = -3           # glibc's mallopt parameter
THRESHOLD = 1 << 20


def map_large_allocations() -> None:
    """Fix glibc's mmap threshold at ``THRESHOLD`` for this process (no-op elsewhere). Idempotent."""
    if not sys.platform.startswith("linux"):
        return
    name = ctypes.util.find_library("c")
    if name is None:
        return
    try:
        libc = ctypes.CDLL(name)
        libc.mallopt(ctypes.c_int(M_MMAP_THRESHOLD), ctypes.c_int(THRESHOLD))
    except (OSError, AttributeError):        # not glibc (musl has no mallopt): nothing to tune
        return
