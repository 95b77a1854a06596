"""Procedural textures written in Python as Warp functions and compiled into the scene's kernel.

A texture is a function of the surface point: texture coordinates ``uv``, world position ``p`` and
shading normal ``n``, returning a linear RGB colour. Register it by name::

    import warp as wp
    import warp_spt

    @warp_spt.texture("stripes", width=0.1, color1=(1.0, 1.0, 1.0), color2=(0.1, 0.1, 0.1))
    def stripes(uv: wp.vec2, p: wp.vec3, n: wp.vec3, prm: warp_spt.ProcParams) -> wp.vec3:
        if wp.mod(p[0], 2.0 * prm[0]) < prm[0]:
            return wp.vec3(prm[1], prm[2], prm[3])
        return wp.vec3(prm[4], prm[5], prm[6])

Parameters and their defaults are the decorator's keyword arguments, each a number or an RGB
triple; they are packed, in the order written, into one :data:`ProcParams` vector of
``MAX_PARAMS`` floats (``width`` is ``prm[0]``, ``color1`` is ``prm[1..3]``...). A texture without
parameters may omit ``prm`` (three arguments).

MTL syntax, in any colour slot (``map_Kd``, ``map_Kr``/``map_Ks``, ``map_Kt``, ``map_Kl``/``map_Ke``)::

    map_Kd proc:NAME [key=value ...]      value: a number, or r,g,b (three numbers, no spaces)

Unknown textures, unknown keys, a wrong number of values or a non-finite value raise
:class:`~warp_spt.scene.errors.SceneError` with the MTL file and line. The CLI's ``--textures FILE.py``
imports a user module that registers textures.

Kernels: each distinct (texture, parameter values) pair of a scene is one *instance*: material
slots hold ``TEX_PROC_BASE - instance``, and the device keeps per-instance kinds and parameter
vectors (``Textures.proc_kind``, ``Textures.proc_params``; the latter is the array a gradient
kernel can receive parameter gradients in). ``Features.procedural`` lists the textures a scene uses
with a hash of their source, so only those are compiled in (``make_dispatch``, a ``wp.static``
dispatch) and the kernel cache keys on them; a scene without procedural textures has
``procedural == ()`` and compiles no procedural code at all.

Built-ins, written the same way: ``checker`` (the seed's pattern, bit-identical), ``noise``
(Perlin gradient noise), ``marble``, ``wood`` and ``grid``.

Two halves: the declarations (names, parameter layouts and ranges, the built-ins' parameters), their
registry, :class:`ProcRef` and the MTL hook ``parse_proc_map`` live Warp-free in
:mod:`warp_spt.scene.proctex_registry`, so reading a scene needs no Warp; this module holds the Warp
functions, registered beside the declarations under the same names, and compiles them. Every name
of the host half is importable from here too.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.util
import inspect
import sys
import textwrap
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import warp as wp

from warp_spt.device.textures import checker as _seed_checker
from warp_spt.runtime import kernel_cache
from warp_spt.scene.errors import SceneError
from warp_spt.scene.proctex_registry import (  # noqa: F401 (re-exported: this module's public names)
    BUILTINS,
    MAX_PARAMETER,
    MAX_PARAMS,
    PREFIX,
    ProcParam,
    ProcRef,
    ProcTexture,
    colour_problem,
    declare,
    get_texture,
    instance_arrays,
    parse_proc_map,
    proc_texture,
    register_declaration,
    registered,
)

ProcParams = wp.types.vector(length=MAX_PARAMS, dtype=wp.float32)


@dataclass(frozen=True)
class ProcFunction:
    """The Warp half of a registered texture, beside its declaration (``texture``, the Warp-free
    half in scene.proctex_registry): its function, always ``(uv, p, n, prm)``, and where it is written.
    Other attributes (``name``, ``params``, ``layout()``, ``pack()``...) are the declaration's."""

    texture: ProcTexture
    func: object                                  # wp.Function (uv, p, n, prm) -> vec3
    user_func: object                             # the function as written (3 or 4 arguments)
    file: str
    line: int
    source_hash: str

    def __getattr__(self, attr: str):
        if attr == "texture" or attr.startswith("__"):   # not yet set (copy, pickle): no recursion
            raise AttributeError(attr)
        return getattr(self.texture, attr)


_FUNCTIONS: dict[str, ProcFunction] = {}   # a plugin registry, beside the declarations': names -> Warp halves


def texture(name: str, **params):
    """Decorator: register a Python function (or ``wp.func``) as procedural texture ``name``.

    Keyword arguments declare the parameters and their defaults (numbers or RGB triples). A later
    registration of the same name replaces the earlier one (kernels key on the source, so the new
    one is compiled). Returns the Warp function.
    """
    def register(fn):
        return register_texture(name, fn, **params).user_func
    return register


def register_texture(name: str, fn, **params) -> ProcFunction:
    """Register ``fn`` (``(uv, p, n[, prm]) -> vec3``) as ``name``; see :func:`texture`."""
    return _register(declare(name, **params), fn)


def _builtin(name: str):
    """Decorator for a built-in's Warp function: its parameters are the declaration's (BUILTINS)."""
    def register(fn):
        return _register(BUILTINS[name], fn).user_func
    return register


def _register(tex: ProcTexture, fn) -> ProcFunction:
    """Register the declaration ``tex`` and ``fn``, its Warp function, together (both or neither)."""
    py = getattr(fn, "func", fn)                  # the Python function behind a wp.Function
    nargs = len(inspect.signature(py).parameters)
    if nargs not in (3, 4):
        raise ValueError(f"procedural texture {tex.name!r}: expected (uv, p, n) or (uv, p, n, prm), "
                         f"got {nargs} arguments")
    user = fn if hasattr(fn, "adj") else wp.func(fn)  # a wp.Function already has its Adjoint
    source_hash = hashlib.sha1((_source_of(py) + py.__qualname__ + repr(tex.params)).encode()).hexdigest()[:16]
    entry = ProcFunction(texture=tex, func=user if nargs == 4 else _with_params(user), user_func=user,
                         file=inspect.getsourcefile(py) or "<unknown>", line=py.__code__.co_firstlineno,
                         source_hash=source_hash)
    register_declaration(tex)
    _FUNCTIONS[tex.name] = entry
    return entry


def _source_of(py) -> str:
    """The text the kernel cache keys on: the whole module of the function where it can be read, so
    an edited helper in the user's file also changes the key; else the function's own source."""
    for obj in (inspect.getmodule(py), py):
        try:
            return inspect.getsource(obj)
        except (OSError, TypeError):
            continue
    return py.__code__.co_code.hex()


def _with_params(f):
    """``(uv, p, n, prm)`` around a texture written without parameters."""
    @wp.func
    def adapted(uv: wp.vec2, p: wp.vec3, n: wp.vec3, prm: ProcParams) -> wp.vec3:
        return f(uv, p, n)
    return adapted


# ---------------------------------------------------------------------------------------------
# Host side: user modules, kernel keys


def load_texture_module(path: str) -> list[str]:
    """Import a user's Python file (which registers textures); returns the names it added or replaced.

    Raises :class:`SceneError` naming the file for a missing file or an error while importing it.
    """
    file = Path(path)
    if not file.is_file():
        raise SceneError(str(path), 0, "texture module not found")
    before = dict(_FUNCTIONS)
    # a source loader whatever the file's suffix: spec_from_file_location gives None for "tex.txt"
    loader = importlib.machinery.SourceFileLoader(f"warp_spt_user_textures_{file.stem}", str(file))
    spec = importlib.util.spec_from_loader(loader.name, loader)
    module = importlib.util.module_from_spec(spec)
    try:
        loader.exec_module(module)
    except SystemExit as err:  # the user's code must not end the render, with any status
        raise SceneError(str(file), _user_line(err, str(file)),
                         f"the texture module called sys.exit({err.code!r}) while it was imported") from None
    except Exception as err:   # the user's code: report it as one line naming their file
        line = _user_line(err, str(file))
        raise SceneError(str(file), line, f"cannot import texture module: {type(err).__name__}: {err}") from None
    sys.modules[spec.name] = module
    return sorted(n for n, t in _FUNCTIONS.items() if before.get(n) is not t)


def _user_line(err: BaseException, file: str) -> int:
    """The last traceback line inside ``file`` (0 if none)."""
    line = 0
    tb = err.__traceback__
    while tb is not None:
        if Path(tb.tb_frame.f_code.co_filename).resolve() == Path(file).resolve():
            line = tb.tb_lineno
        tb = tb.tb_next
    return getattr(err, "lineno", None) if isinstance(err, SyntaxError) and err.lineno else line


def features_key(names) -> tuple[tuple[str, str], ...]:
    """``Features.procedural`` for these texture names: sorted (name, source hash) pairs."""
    return tuple((n, _FUNCTIONS[n].source_hash) for n in sorted(set(names)))


# ---------------------------------------------------------------------------------------------
# Kernel side


@wp.func
def _no_texture(kinds: wp.array(dtype=wp.int32), params: wp.array(dtype=ProcParams), inst: int,
                uv: wp.vec2, p: wp.vec3, n: wp.vec3) -> wp.vec3:
    return wp.vec3(0.0, 0.0, 0.0)


def make_dispatch(key: tuple[tuple[str, str], ...]):
    """``proc(kinds, params, instance, uv, p, n) -> vec3`` over exactly the textures in ``key``.

    A chain of closures, one per texture, rather than ``wp.static(funcs[i])`` in an unrolled loop:
    Warp leaves static expressions over loop variables out of the module hash, so two kernels with
    as many textures but different ones were deduplicated into one (tests/device/test_proctex.py caught it).
    A closure's function is hashed with its source.
    """
    if not key:
        return _no_texture
    func = _FUNCTIONS[key[-1][0]].func
    rest = make_dispatch(key[:-1])
    kind = len(key) - 1

    @wp.func
    def proc(kinds: wp.array(dtype=wp.int32), params: wp.array(dtype=ProcParams), inst: int,
             uv: wp.vec2, p: wp.vec3, n: wp.vec3) -> wp.vec3:
        if kinds[inst] == kind:
            return func(uv, p, n, params[inst])
        return rest(kinds, params, inst, uv, p, n)

    return proc


def _probe_kernel(key):
    """A kernel evaluating every instance at given surface points: out[i, k] = texture k at point i
    (built once per texture set, in the one kernel cache)."""
    return kernel_cache.cached("proc_probe", key, lambda: _make_probe_kernel(key))


def _make_probe_kernel(key):
    proc = make_dispatch(key)

    @wp.kernel(enable_backward=False, module="unique")
    def probe(kinds: wp.array(dtype=wp.int32), params: wp.array(dtype=ProcParams), uv: wp.array(dtype=wp.vec2),
              p: wp.array(dtype=wp.vec3), n: wp.array(dtype=wp.vec3), out: wp.array2d(dtype=wp.vec3)):
        i, k = wp.tid()
        out[i, k] = proc(kinds, params, k, uv[i], p[i], n[i])

    return probe


def evaluate(refs: list[ProcRef], uv, p, n, device: str = "cpu") -> np.ndarray:
    """(N, K, 3) colours of the instances ``refs`` at N surface points (a test and diagnosis tool)."""
    key = features_key(r.name for r in refs)
    kinds, params = instance_arrays(refs, key)
    uv, p, n = (np.ascontiguousarray(a, dtype=np.float32) for a in (uv, p, n))
    kernel = kernel_cache.load(_probe_kernel(key), device)     # initialises Warp quietly first
    out = wp.zeros((len(uv), len(refs)), dtype=wp.vec3, device=device)
    wp.launch(kernel, dim=(len(uv), len(refs)), device=device, inputs=[
        wp.array(kinds, dtype=wp.int32, device=device), wp.array(params, dtype=ProcParams, device=device),
        wp.array(uv, dtype=wp.vec2, device=device), wp.array(p, dtype=wp.vec3, device=device),
        wp.array(n, dtype=wp.vec3, device=device), out])
    return out.numpy()


def enable_texture_gradients(dev) -> wp.array:
    """Make a DeviceScene's procedural parameters carry gradients and return that array.

    After a differentiable render (``warp_spt.diff.gradients.render_differentiable``) and
    ``tape.backward``, ``array.grad[k]`` holds d(loss)/d(parameter vector of instance k), in the
    layout of :meth:`ProcTexture.layout` (``dev.scene.procedural[k]`` names the instance).
    """
    if not dev.proc_params.requires_grad:
        dev.proc_params = wp.array(dev.proc_params.numpy(), dtype=ProcParams, device=dev.proc_params.device,
                                   requires_grad=True)
    return dev.proc_params


def nonfinite_textures(scene, device: str = "cpu", samples: int = 4096) -> list[str]:
    """Names of the scene's procedural textures that return NaN or infinity at some probe point.

    The probes: every corner uv and vertex of the meshes, sphere poles, and ``samples`` random points
    in the scene's bounds with random unit normals (deterministic). Used to name the culprit when a
    render dropped non-finite samples.
    """
    refs = scene.procedural
    if not refs:
        return []
    rng = np.random.default_rng(0)
    uv = [m.corner_uv.reshape(-1, 2) for m in scene.meshes] + [rng.uniform(-2, 2, (samples, 2))]
    b = scene.bounds
    lo, hi = (b[0], b[1]) if np.all(np.isfinite(b)) else (np.full(3, -1.0), np.full(3, 1.0))
    pts = np.concatenate([m.world_part()[0][m.indices.reshape(-1)] for m in scene.meshes]   # first placements
                         + [rng.uniform(lo, hi, (samples, 3))]) if scene.meshes else rng.uniform(lo, hi, (samples, 3))
    uv = np.concatenate(uv)[:len(pts)]
    uv = np.concatenate([uv, rng.uniform(-2, 2, (len(pts) - len(uv), 2))])
    n = rng.normal(size=(len(pts), 3))
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    out = evaluate(refs, uv, pts, n, device)
    bad = ~np.isfinite(out).all(axis=(0, 2))
    return sorted({r.name for r, b in zip(refs, bad) if b})


def explain_compile_failure(key: tuple[tuple[str, str], ...], err: Exception, device: str = "cpu") -> Exception:
    """The error to raise when a kernel using the textures in ``key`` failed to build.

    Each texture is compiled alone in a probe kernel; the first that fails is named, with its file
    and line, as a :class:`SceneError`. If all compile alone, ``err`` is returned unchanged.
    """
    for name, source_hash in key:
        tex = _FUNCTIONS[name]
        try:
            wp.load_module(_probe_kernel(((name, source_hash),)).module, device=device)
        except Exception as own:   # Warp's codegen/compile errors have no common base class
            first = next((ln for ln in str(own).splitlines() if ln.strip()), type(own).__name__)
            return SceneError(tex.file, tex.line, f"procedural texture {name!r} failed to compile: "
                                                  f"{textwrap.shorten(first, 300)}")
    return err


# ---------------------------------------------------------------------------------------------
# Built-ins


@_builtin("checker")
def seed_checker(uv: wp.vec2, p: wp.vec3, n: wp.vec3) -> wp.vec3:
    """The seed's Inner_CheckerTexture (parity of trunc(1000 u v), Java semantics; textures.checker)."""
    return _seed_checker(uv)


@wp.func
def _fade(t: float) -> float:
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0)


@wp.func
def _hash3(x: int, y: int, z: int) -> int:
    """An integer hash of a lattice point (wrapping 32-bit arithmetic, no table)."""
    h = wp.uint32(x) * wp.uint32(73856093) ^ wp.uint32(y) * wp.uint32(19349663) ^ wp.uint32(z) * wp.uint32(83492791)
    h = (h ^ (h >> wp.uint32(16))) * wp.uint32(0x45D9F3B)
    h = h ^ (h >> wp.uint32(16))
    return int(h & wp.uint32(15))


@wp.func
def _grad(h: int, x: float, y: float, z: float) -> float:
    """Dot product with one of Perlin's 12 edge gradients (16 entries, 4 repeated)."""
    u = x
    if h >= 8:
        u = y
    v = y
    if h >= 4:
        v = z
        if h == 12 or h == 14:
            v = x
    a = u
    if (h & 1) != 0:
        a = -u
    b = v
    if (h & 2) != 0:
        b = -v
    return a + b


NOISE_RANGE = 1.0e7        # beyond 2^23 a float32 has no fractional part: noise is 0 there


@wp.func
def perlin(q: wp.vec3) -> float:
    """Perlin's improved gradient noise in about [-1, 1]; 0 at every lattice point, and 0 far out
    (|q| >= NOISE_RANGE, where float32 has no fraction left and int() would overflow) or at a
    non-finite q, so that no parameter makes a texture NaN."""
    if not (wp.abs(q[0]) < NOISE_RANGE and wp.abs(q[1]) < NOISE_RANGE and wp.abs(q[2]) < NOISE_RANGE):
        return 0.0
    fx = wp.floor(q[0])
    fy = wp.floor(q[1])
    fz = wp.floor(q[2])
    ix = int(fx)
    iy = int(fy)
    iz = int(fz)
    x = q[0] - fx
    y = q[1] - fy
    z = q[2] - fz
    u = _fade(x)
    v = _fade(y)
    w = _fade(z)
    x00 = wp.lerp(_grad(_hash3(ix, iy, iz), x, y, z), _grad(_hash3(ix + 1, iy, iz), x - 1.0, y, z), u)
    x10 = wp.lerp(_grad(_hash3(ix, iy + 1, iz), x, y - 1.0, z), _grad(_hash3(ix + 1, iy + 1, iz), x - 1.0, y - 1.0, z), u)
    x01 = wp.lerp(_grad(_hash3(ix, iy, iz + 1), x, y, z - 1.0), _grad(_hash3(ix + 1, iy, iz + 1), x - 1.0, y, z - 1.0), u)
    x11 = wp.lerp(_grad(_hash3(ix, iy + 1, iz + 1), x, y - 1.0, z - 1.0),
                  _grad(_hash3(ix + 1, iy + 1, iz + 1), x - 1.0, y - 1.0, z - 1.0), u)
    return wp.lerp(wp.lerp(x00, x10, v), wp.lerp(x01, x11, v), w)


TURBULENCE_OCTAVES = 6


@wp.func
def turbulence(q: wp.vec3) -> float:
    """Sum of |noise| over TURBULENCE_OCTAVES octaves, each at twice the frequency and half the weight.

    A constant loop, unrolled, so that Warp differentiates it (a dynamic loop with multiplicative
    carried state such as ``f *= 2`` is not differentiated correctly, see warp_spt.diff.gradients).
    """
    s = float(0.0)
    f = float(1.0)
    for _ in range(wp.static(TURBULENCE_OCTAVES)):
        s += wp.abs(perlin(q * f)) / f
        f *= 2.0
    return s


@wp.func
def _rgb(prm: ProcParams, i: int) -> wp.vec3:
    """The colour stored at prm[i..i+2]."""
    return wp.vec3(prm[i], prm[i + 1], prm[i + 2])


@_builtin("noise")
def noise(uv: wp.vec2, p: wp.vec3, n: wp.vec3, prm: ProcParams) -> wp.vec3:
    """Perlin noise of the world position: color1 at -1 to color2 at +1 (prm: scale, color1, color2)."""
    t = wp.clamp(0.5 + 0.5 * perlin(p * prm[0]), 0.0, 1.0)
    return wp.lerp(_rgb(prm, 1), _rgb(prm, 4), t)


@_builtin("marble")
def marble(uv: wp.vec2, p: wp.vec3, n: wp.vec3, prm: ProcParams) -> wp.vec3:
    """Veins along x: 0.5 + 0.5 sin(scale x + turbulence * turb(p)), between color2 and color1."""
    q = p * prm[0]
    angle = q[0] + prm[1] * turbulence(q)
    if not wp.abs(angle) < NOISE_RANGE:       # sin of a huge or infinite angle: no veins to draw
        angle = 0.0
    t = 0.5 + 0.5 * wp.sin(angle)
    return wp.lerp(_rgb(prm, 5), _rgb(prm, 2), t)


@_builtin("wood")
def wood(uv: wp.vec2, p: wp.vec3, n: wp.vec3, prm: ProcParams) -> wp.vec3:
    """Rings around the y axis, distorted by noise: frac(rings * (r + 0.1 noise)) between the colours."""
    q = p * prm[0]
    r = wp.sqrt(q[0] * q[0] + q[2] * q[2]) + 0.1 * perlin(q)
    t = r * prm[1]
    if not wp.abs(t) < NOISE_RANGE:           # rings finer than float32 resolves (or r infinite)
        t = 0.0
    t = t - wp.floor(t)
    return wp.lerp(_rgb(prm, 2), _rgb(prm, 5), t * t)


@_builtin("grid")
def grid(uv: wp.vec2, p: wp.vec3, n: wp.vec3, prm: ProcParams) -> wp.vec3:
    """Lines of relative ``width`` at every 1/cells in u and in v (colour ``line``), else ``fill``."""
    su = uv[0] * prm[0]
    sv = uv[1] * prm[0]
    du = su - wp.floor(su)
    dv = sv - wp.floor(sv)
    h = 0.5 * prm[1]
    if du < h or du > 1.0 - h or dv < h or dv > 1.0 - h:
        return _rgb(prm, 2)
    return _rgb(prm, 5)
