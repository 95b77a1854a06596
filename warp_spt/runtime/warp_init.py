"""Warp initialised once, quietly: no banner, no module-load lines, no missing-CUDA-driver line.

On a machine without an NVIDIA driver, Warp's native library prints "Warp CUDA warning: Could not
find or load the NVIDIA CUDA driver..." with C ``fprintf(stderr)`` while ``wp.init()`` runs, and
Warp logs a banner and one line per loaded module at INFO level. For a CPU renderer that is noise.

:func:`init_warp` runs ``wp.init()`` with file descriptor 2 pointed at a temporary file and then
writes back to stderr every captured line except that one known warning, so a real native error
still surfaces. It also lowers Warp's log level to warnings, unless the caller changed it already
or asked for ``verbose`` (the CLI's ``--verbose``; ``WARP_SPT_VERBOSE=1`` for the API).

It also keeps Clang's precompiled header across processes (:func:`share_clang_pch`): Warp builds it
in a new temporary directory in every process, 2.2-2.4 CPU s before the process's first CPU compile
(docs/performance.md, Start-up), so every new scene paid for it again.
"""

from __future__ import annotations

import io
import os
import re
import sys
import tempfile
from contextlib import contextmanager

# The one native line hidden by default (cuda_util.cpp, init_cuda_driver); matched by its start.
_NO_DRIVER = b"Warp CUDA warning: Could not find or load the NVIDIA CUDA driver"

_state = {"done": False}     # Warp's own initialisation is process-wide: so is the record of it


def init_warp(verbose: bool | None = None, *, quiet: bool = False) -> None:
    """Initialise Warp (once per process); see the module docs.

    ``verbose`` None reads ``WARP_SPT_VERBOSE``; ``quiet`` (the CLI's ``--quiet``) also hides
    Warp's warnings.
    """
    if _state["done"] and verbose is None:      # an explicit earlier choice (the CLI's) stands
        return
    import warp as wp

    if verbose is None:
        verbose = os.environ.get("WARP_SPT_VERBOSE", "") not in ("", "0")
    if not verbose and wp.config.log_level == wp.LOG_INFO:     # still Warp's default
        wp.config.log_level = wp.LOG_WARNING
    if quiet and not verbose:
        wp.config.log_level = max(wp.config.log_level, wp.LOG_ERROR)
    if _state["done"]:
        return
    if verbose:
        wp.init()
    else:
        _init_capturing_stderr(wp)
    share_clang_pch(wp)
    _state["done"] = True


DEVICE_SYNTAX = re.compile(r"cpu|cuda(:[0-9]{1,3})?")


def check_device(name) -> str:
    """``name`` ("cpu", "cuda" or "cuda:N") if Warp can run kernels there, else ValueError with one
    line saying what was asked for and what this machine has. Syntax first, without Warp (the
    command line parses before Warp starts); then, for CUDA, Warp is initialised (quietly) and asked.
    A Warp ``Device`` is taken by its name (``cuda:0``)."""
    if type(name).__name__ == "Device" and hasattr(name, "alias"):
        name = name.alias
    if not isinstance(name, str) or not DEVICE_SYNTAX.fullmatch(name):
        raise ValueError(f"device must be 'cpu', 'cuda' or 'cuda:N', got {name!r}")
    if name == "cpu":
        return name
    init_warp()
    import warp as wp

    count = wp.get_cuda_device_count()
    if count == 0:
        raise ValueError(f"device {name!r}: no CUDA device is available here (Warp found no NVIDIA driver "
                         f"or GPU); render with device 'cpu'")
    index = int(name.partition(":")[2] or 0)
    if index >= count:
        raise ValueError(f"device {name!r}: this machine has {count} CUDA device(s), cuda:0 to cuda:{count - 1}")
    return name


PCH_FOLDER = "wp_spt_clang_pch"     # "wp_" first: wp.clear_kernel_cache() removes it with the kernels


def share_clang_pch(wp) -> str | None:
    """Point Warp's CPU compiles at one precompiled-header folder inside its (versioned) kernel cache,
    shared by threads and processes, instead of a new temporary folder per thread; returns the
    folder (None when left alone: no warp-clang, precompiled headers off, not POSIX, or
    ``WARP_SPT_SHARED_PCH=0``).

    Sharing is safe because warp-clang names each header by its build options and writes it to a
    unique temporary file renamed into place (checked with strace: ``O_EXCL`` ``.pch.tmp``, then
    ``rename``), so a reader sees a whole header or none. Renaming over a file that another process
    has open is POSIX behaviour, hence POSIX only.

    A header records the absolute paths of Warp's native headers it was built from, and when those
    are gone (the same Warp version installed in another virtual environment, the old one deleted:
    every CI run) Clang refuses it with "malformed or corrupted precompiled file" on stderr and
    warp-clang compiles without it, every time, without rebuilding it. So the folder is one per Warp
    installation (:func:`pch_folder`).
    """
    from warp._src import context

    runtime = context.runtime
    if (os.name != "posix" or os.environ.get("WARP_SPT_SHARED_PCH", "1") == "0" or runtime is None
            or runtime.llvm is None or not wp.config.use_precompiled_headers or not wp.config.kernel_cache_dir):
        return None
    folder = pch_folder(wp.config.kernel_cache_dir, os.path.join(context.warp_home, "native"))
    try:
        os.makedirs(folder, exist_ok=True)
    except OSError:             # a read-only cache: keep Warp's temporary folders
        return None
    runtime.get_clang_pch_dir = lambda: folder     # the one call site is Module's CPU build
    return folder


def pch_folder(cache_dir: str, native_dir: str) -> str:
    """The shared precompiled-header folder for the Warp whose native headers are in ``native_dir``:
    named by their real path and by builtin.h's size and modification time, so a header is only ever
    read by the installation it was built from (see :func:`share_clang_pch`)."""
    import hashlib

    native = os.path.realpath(native_dir)
    try:
        st = os.stat(os.path.join(native, "builtin.h"))
        stamp = f"{st.st_size}:{st.st_mtime_ns}"
    except OSError:
        stamp = "-"
    key = hashlib.sha1(f"{native}\0{stamp}".encode()).hexdigest()[:16]
    return os.path.join(cache_dir, PCH_FOLDER, key)


def _init_capturing_stderr(wp) -> None:
    """``wp.init()`` with fd 2 redirected; every captured line but the no-driver one is re-emitted."""
    text = bytearray()
    try:
        with native_output((2,)) as text:
            wp.init()
    finally:
        kept = b"".join(line for line in text.splitlines(keepends=True) if not line.startswith(_NO_DRIVER))
        if kept:
            print(kept.decode("utf-8", "replace"), end="", file=sys.stderr)


@contextmanager
def native_output(fds: tuple[int, ...] = (1, 2)):
    """What native code writes to the file descriptors ``fds`` while the block runs, kept from the
    terminal: yields a bytearray that holds it once the block ends (empty where the descriptors cannot
    be redirected, as in embedded interpreters). Libraries written in C print there directly, past
    Python's streams (OpenEXR's messages on a damaged file), which are flushed first so that nothing
    written before is caught. Process-wide while the block runs (other threads' output is caught too)."""
    captured = bytearray()
    saved: list[tuple[int, int]] = []
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError, AttributeError):   # closed, or None
            pass
    try:
        for fd in fds:
            saved.append((fd, os.dup(fd)))
    except OSError:                 # no usable descriptor (embedded interpreters)
        for _, copy in saved:
            os.close(copy)
        saved = []
    if not saved:
        yield captured
        return
    names = [name for fd, name in ((1, "stdout"), (2, "stderr")) if fd in fds]
    streams = {name: getattr(sys, name) for name in names}
    text = io.StringIO()            # a binding's own print (pybind11's py::print) goes to sys.stdout
    with tempfile.TemporaryFile() as capture:
        for fd, _ in saved:
            os.dup2(capture.fileno(), fd)
        for name in names:
            setattr(sys, name, text)
        try:
            yield captured
        finally:
            for name, stream in streams.items():
                setattr(sys, name, stream)
            for fd, copy in saved:
                os.dup2(copy, fd)
                os.close(copy)
            capture.seek(0)
            captured += capture.read() + text.getvalue().encode("utf-8", "replace")