"""Find a compiled kernel by a key of our own, so that a cached start skips Warp's hash of its code.

Warp finds a module's compiled object in its kernel cache by a hash of the module's code: it builds
every Warp function the kernel calls (parsing each one's Python source) and walks and hashes them
all, about 0.1 CPU s for the path kernel, on every start (docs/performance.md, Start-up). Most of
that is spent proving that nothing changed since the last run.

This index keeps, beside Warp's cache, a small record per kernel named by a key of our own
(:func:`own_key`): a digest of the bytes of every Python source file of this package (read, not
parsed: 4 ms), Warp's and Python's versions, the machine, the kernel's specialisation (kind,
integrator, sampler, features) and every simple value of ``wp.config`` (compiler flags, mode,
optimisation level, ...). The record names what Warp computed the first time: the module's name,
its hash, the kernel's hash and key, its options and the object and metadata files. On a hit,
:func:`load` builds a :class:`warp.Kernel` from the kernel's plain Python function (its source, not
its callees': Warp needs only its arguments to launch it) and hands Warp the recorded hashes in
place of its own, then loads the recorded object: nothing is generated, hashed or compiled.

What the key covers is everything the kernel's code can depend on, as long as the code comes from
this package: the caller must not ask for a key when any of it comes from outside (an integrator,
sampler or procedural texture registered by a user's module), whose source the digest does not
read. A change to any source file of the package changes the key (tests/runtime/test_kernel_index.py), so a
stale object is never loaded; a record whose files are gone, or any failure while loading it,
falls back to Warp's own look-up, which then writes a new record. CPU only: a CUDA object depends on
the device's architecture and context, and its load is not the start-up cost measured here.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys

INDEX_FOLDER = "wp_spt_index"     # "wp_" first: wp.clear_kernel_cache() removes it with the kernels
PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# wp.config values that change no generated code or compiled object: a change to them must not miss
_NOT_CODE = frozenset({"log_level", "verbose", "verbose_warnings", "quiet", "print_launches"})


def enabled() -> bool:
    """False when ``WARP_SPT_KERNEL_INDEX=0``: Warp's own look-up only (for comparisons)."""
    return os.environ.get("WARP_SPT_KERNEL_INDEX", "1") != "0"


def source_digest(root: str = PACKAGE) -> str | None:
    """sha256 of every ``.py`` file under ``root`` (path and bytes, in sorted order); None when
    there are none to read (a package imported from a zip file: no key then)."""
    h = hashlib.sha256()
    count = 0
    for folder, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d != "__pycache__")
        for name in sorted(files):
            if name.endswith(".py"):
                path = os.path.join(folder, name)
                with open(path, "rb") as f:
                    data = f.read()
                rel = os.path.relpath(path, root).encode()
                h.update(len(rel).to_bytes(4, "little") + rel + len(data).to_bytes(8, "little") + data)
                count += 1
    return h.hexdigest() if count else None


def config_state(wp) -> str:
    """The simple values of ``wp.config`` that can change code, as one sorted text."""
    items = sorted((k, v) for k, v in vars(wp.config).items()
                   if not k.startswith("_") and k not in _NOT_CODE
                   and isinstance(v, (bool, int, float, str, type(None))))
    return repr(items)


def own_key(kind: str, spec: tuple, root: str = PACKAGE) -> str | None:
    """The key of kernel ``kind`` specialised by ``spec`` (its ``repr`` must name every choice the
    kernel's code depends on) for the sources under ``root`` (this package), Warp and its
    configuration; None when the sources cannot be read."""
    import warp as wp

    from warp_spt.runtime import kernel_cache

    digest = kernel_cache.cached("source digest", root, lambda: source_digest(root))
    if digest is None:
        return None
    machine = os.uname().machine if hasattr(os, "uname") else os.name
    text = "\n".join([digest, wp.__version__, sys.version.split()[0], machine, kind, repr(spec), config_state(wp)])
    return hashlib.sha256(text.encode()).hexdigest()


def _record_path(wp, key: str) -> str | None:
    folder = wp.config.kernel_cache_dir
    return os.path.join(folder, INDEX_FOLDER, key + ".json") if folder else None


class _RecordedHashes:
    """Stands in for Warp's ``ModuleHasher`` with the hashes Warp computed when it compiled the
    module (what ``Module.load`` and a launch read of it: the module's hash, each kernel's)."""

    def __init__(self, module_hash: bytes, kernel_hashes: dict):
        self.module_hash = module_hash
        self.kernel_hashes = kernel_hashes
        self.unique_kernels = {h: k for k, h in kernel_hashes.items()}

    def get_hash(self) -> bytes:
        return self.module_hash


def _is_cpu(wp, device) -> bool:
    """Whether ``device`` is the CPU; False for a device this machine lacks (the CUDA compile test
    builds kernels for "cuda" on machines without a GPU, and Warp raises for the name there)."""
    try:
        return wp.get_device(device).is_cpu
    except RuntimeError:
        return False


def _default_options(context) -> dict:
    return dict(context.Module("_", None).options)


def remember(key: str, kernel, device: str = "cpu") -> None:
    """Record where Warp put ``kernel``'s compiled module (loaded on ``device``) under ``key``,
    replacing a record that says otherwise (one :func:`load` declined); nothing when the same record
    is there, for a load that is not on the CPU, when Warp's module does not look as expected, or
    when the cache folder cannot be written: a record only saves time."""
    import tempfile

    import warp as wp

    path = _record_path(wp, key)
    if path is None or not _is_cpu(wp, device):
        return
    try:
        record = _describe(wp, kernel)
        text = json.dumps(record) if record is not None else None
    except Exception:       # Warp's internals read here changed, or options JSON cannot hold
        return
    if text is None:
        return
    try:
        with open(path) as f:
            if f.read() == text:
                return
    except OSError:         # none yet
        pass
    tmp = None
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), suffix=".tmp")
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)       # a reader sees a whole record or none
    except OSError:                 # a read-only or full cache
        if tmp is not None and os.path.exists(tmp):
            os.remove(tmp)


def _describe(wp, kernel) -> dict | None:
    """What :func:`load` needs of ``kernel``'s module, loaded on the CPU (None: not one CPU variant
    holding this one kernel)."""
    from warp._src import context

    m = kernel.module
    cpu = [bd for context_, bd in m.execs if context_ is None]      # a CPU load's variant: its block_dim
    if len(cpu) != 1:
        return None
    bd = cpu[0]
    hasher, exe = m.hashers.get(bd), m.execs[(None, bd)]
    if hasher is None or kernel not in hasher.kernel_hashes or len(hasher.kernel_hashes) != 1:
        return None
    defaults = _default_options(context)
    module_options = {k: v for k, v in m.options.items() if defaults.get(k) != v}
    cache = wp.config.kernel_cache_dir
    meta = os.path.join(cache, m.get_module_identifier(bd), m._get_meta_name(block_dim=bd))
    return {"module": m.name, "module_hash": hasher.get_hash().hex(), "kernel": kernel.key,
            "kernel_hash": hasher.kernel_hashes[kernel].hex(), "kernel_options": kernel.options, "block_dim": bd,
            "kernel_dim": kernel.adj.kernel_dim, "uses_tid": bool(getattr(kernel.adj, "uses_tid", True)),
            "module_options": module_options, "binary": os.path.relpath(exe.binary_path, cache),
            "meta": os.path.relpath(meta, cache)}


def load(key: str, function, device: str = "cpu"):
    """The kernel of plain Python ``function`` loaded from the object recorded under ``key`` (a
    :class:`warp.Kernel`, launchable on ``device``), or None: no record, its files gone, not a CPU
    device, or anything in the record that does not fit (the caller then builds the kernel)."""
    import warp as wp
    from warp._src import codegen, context

    from warp_spt.runtime.warp_init import init_warp

    init_warp()
    path = _record_path(wp, key)
    if path is None or not _is_cpu(wp, device):
        return None
    try:
        with open(path) as f:
            rec = json.load(f)
        cache = wp.config.kernel_cache_dir
        binary, meta = os.path.join(cache, rec["binary"]), os.path.join(cache, rec["meta"])
        if not (os.path.exists(binary) and os.path.exists(meta)):
            return None
        m = context.Module(rec["module"], None)
        m.defer_reference_scan = True
        m.options.update(rec["module_options"])
        k = context.Kernel(func=function, key=rec["kernel"], module=m, options=rec["kernel_options"])
        if k.is_generic:
            return None
        bd = rec["block_dim"]
        kernel_hash = bytes.fromhex(rec["kernel_hash"])
        with context._codegen_lock:
            m.hashers[bd] = _RecordedHashes(bytes.fromhex(rec["module_hash"]), {k: kernel_hash})
            m.resolved_options[bd] = m.resolve_options(wp.config, block_dim=bd)
            m.has_unresolved_static_expressions = False
        k.hash = kernel_hash
        # what a launch reads of the kernel's built adjoint (Warp sets them while hashing its code)
        k.adj.kernel_dim = int(rec["kernel_dim"])
        k.adj.tid_extent_limit_candidate = codegen._TID_MAX_EXTENT
        m._tid_extent_limits[(bd, kernel_hash)] = codegen._TID_MAX_EXTENT if rec["uses_tid"] else None
        exe = m.load(device, block_dim=bd, binary_path=binary, meta_path=meta)
        if not exe.get_kernel_hooks(k).forward:
            return None
        return k
    except Exception:       # a stale, foreign or corrupt record: Warp's own look-up decides
        return None
