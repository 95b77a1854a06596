"""What every integrator shares: its record, the path state, the sample dimensions, the fast kernel.

An integrator is an :class:`Integrator` record (registered in ``warp_spt.integrators.INTEGRATORS``)
whose ``make_step(features, sampler) -> step`` builds ONE bounce as a ``wp.func`` taking and
returning a :class:`PathState`. The fast kernel runs it in a dynamic loop;
the differentiable kernel (``warp_spt.diff.gradients``) runs the same function in an unrolled loop,
because Warp differentiates only unrolled loops with multiplicative carried state.

Sample dimensions are assigned here, explicitly: the pixel offset (dims 0-1), the lens (2-3), then
per bounce k (from 0) a block of ``stride`` dims starting at ``DIM_BOUNCE + k * stride``, with fixed
offsets inside it (lobe, direction, Fresnel, light choice, light position, roulette). An integrator
that uses fewer of them declares a shorter stride (the seed integrator's 4 keep its numbers those
of the pre-restructure renderer); adding a dimension at the end of a block shifts no other.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Mapping

import numpy as np
import warp as wp

from warp_spt.device.camera_rays import CameraParams, camera_params, camera_ray  # noqa: F401 (re-exported)
from warp_spt.device.structs import Features, Geometry, Materials, Textures
from warp_spt.emitters import Lights
from warp_spt.bsdfs import BsdfSample
from warp_spt.accel.surface import Surface, offset_origin
from warp_spt.scene.numbers import plain_float, plain_int
from warp_spt.samplers import Sampler, SamplerState

DIM_PIXEL = 0          # 2 dims: offset inside the pixel
DIM_LENS = 2           # 2 dims: point on the lens
DIM_BOUNCE = 4         # first dim of bounce 0
# offsets inside a bounce's block
OFF_LOBE = 0           # which lobe of the material
OFF_DIR = 1            # 2 dims: direction within the lobe
OFF_FRESNEL = 3        # reflect or refract
OFF_LIGHT = 4          # which light (NEE)
OFF_LIGHT_POS = 5      # 2 dims: point on that light
OFF_ROULETTE = 7       # survive or not
SEED_STRIDE = 4        # the seed's four draws per bounce
FULL_STRIDE = 8


@dataclass(frozen=True)
class Param:
    """One parameter of an integrator, set by name (as a Mitsuba 3 plugin's): its default (the one
    place it is written), a line of doc, its type (``kind``: bool, int or float; ``optional``: None
    is allowed too) and, for numbers, the interval it must lie in (``low``/``high``, inclusive
    unless ``low_open``/``high_open``; None: unbounded). Host-side: a value reaches a kernel, if at
    all, only after :meth:`check` took it."""

    name: str
    default: Any
    doc: str
    kind: type = float
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    optional: bool = False

    def allowed(self) -> str:
        """What a value may be, in words: "float in (0, 1]", "bool", "int >= 1 or None"."""
        def num(v) -> str:          # ints in full: 1073741824, not 1.07374e+09
            return str(int(v)) if self.kind is int else f"{v:g}"

        if self.kind is bool:
            text = "bool"
        elif self.low is not None and self.high is not None:
            text = (f"{self.kind.__name__} in {'(' if self.low_open else '['}{num(self.low)}, "
                    f"{num(self.high)}{')' if self.high_open else ']'}")
        elif self.low is not None:
            text = f"{self.kind.__name__} {'>' if self.low_open else '>='} {num(self.low)}"
        elif self.high is not None:
            text = f"{self.kind.__name__} {'<' if self.high_open else '<='} {num(self.high)}"
        else:
            text = f"finite {self.kind.__name__}"
        return text + (" or None" if self.optional else "")

    def describe(self) -> str:
        """One line for help texts and errors: name, allowed values, default, doc."""
        return f"{self.name} ({self.allowed()}, default {self.default!r}): {self.doc}"

    def check(self, value: Any, integrator: str = "") -> Any:
        """``value`` as this parameter's type (an int given for a float becomes a float; numpy
        scalars become Python's), or ValueError naming the parameter and what it allows: wrong
        types (a bool is no number, a float no int, 1 no bool), non-finite numbers, values out of range."""
        if value is None and self.optional:
            return None
        bad = ValueError(f"{self._where(integrator)} must be {self.allowed()}, got {value!r}")
        is_bool = isinstance(value, (bool, np.bool_))
        if self.kind is bool:
            if not is_bool:
                raise bad
            return bool(value)
        if is_bool or not isinstance(value, (int, np.integer) if self.kind is int else (int, float, np.integer,
                                                                                         np.floating)):
            raise bad
        try:
            v = self.kind(value)
            finite = math.isfinite(v)  # an int beyond float's range overflows here, even for an int option
        except OverflowError:          # an int too large for a float
            raise bad from None
        if not finite:
            raise bad
        if self.low is not None and (v < self.low or (self.low_open and v == self.low)):
            raise bad
        if self.high is not None and (v > self.high or (self.high_open and v == self.high)):
            raise bad
        return v

    def _where(self, integrator: str) -> str:
        return f"option {self.name!r}" + (f" of integrator {integrator!r}" if integrator else "")

    def parse(self, text: str, integrator: str = "") -> Any:
        """``text`` (a command line's NAME=VALUE value) as this parameter's value, checked:
        "none" for None, true/false (or 1/0, yes/no, on/off) for a bool, plain decimals for numbers."""
        word = text.strip().lower()
        if self.optional and word == "none":
            return None
        if self.kind is bool:
            if word not in _BOOL_WORDS:
                raise ValueError(f"{self._where(integrator)} must be {self.allowed()} (true or false), got {text!r}")
            return _BOOL_WORDS[word]
        try:
            return self.check(plain_int(text.strip()) if self.kind is int else plain_float(text.strip()), integrator)
        except ValueError:         # the message quotes what was typed, not the number it became
            raise ValueError(f"{self._where(integrator)} must be {self.allowed()}, got {text!r}") from None


_BOOL_WORDS = {"true": True, "1": True, "yes": True, "on": True, "false": False, "0": False, "no": False, "off": False}


@dataclass(frozen=True)
class Integrator:
    """An integrator: a name, its Warp function builders and what it can do.

    ``make_step(features, sampler, differentiable=False) -> step``: one bounce (closest hit and
    vertex), run by the fast kernel in a dynamic loop and by the tape's kernel unrolled.
    ``make_vertex(features, sampler, inline=None) -> vertex``: the bounce after its ray was traced,
    what path replay differentiates; None: no path replay (gradients through the tape only).
    ``stride``: sample dimensions per bounce (see the module docs). ``deterministic``: the image is a
    function of the seed alone (every renderer's merge and the house hashes rely on it); ``tape``:
    its step differentiates through Warp's tape. ``prepare(bound) -> data``: optional device data
    of its own, built once per render set-up (``Bound.data``); ``passes(bound, result) -> result``:
    optional work after the image's passes (e.g. a second estimator), run by the tile renderer.
    ``make_kernel(step, start_path) -> kernel``: a fast kernel of its own (None: :func:`make_kernel`),
    whose inputs start with the fast kernel's; ``render_passes(bound, tiles, film, counters,
    threads, report, per_launch) -> launches``: the tile renderer hands it the whole render (its
    own pass schedule and kernel inputs, as ``guided``'s training passes); such an integrator
    renders through the tile renderer only (no row windows, progressive batches or cluster).
    ``params``: its parameters (:class:`Param`), set by name in ``RenderSettings.integrator_options``
    and read through :meth:`options` (e.g. ``Bound.options``). ``pathwise``: its ``make_vertex`` also
    takes ``pathwise=True``, the vertex with the tape's derivatives (hit points, normals, directions
    and light samples that move with the scene), which ``diff.replay_pathwise`` differentiates.
    """

    name: str
    make_step: Callable
    make_vertex: Callable | None
    stride: int
    deterministic: bool = True
    tape: bool = True
    prepare: Callable | None = None
    passes: Callable | None = None
    make_kernel: Callable | None = None
    render_passes: Callable | None = None
    summary: str = ""            # one line for --help and the docs
    params: tuple[Param, ...] = ()
    media: bool = False          # it tracks participating media (Features.media): volpath
    pathwise: bool = False       # make_vertex(..., pathwise=True) exists (see above)

    def param(self, name: str) -> Param:
        """The parameter ``name`` (ValueError naming the integrator's parameters otherwise)."""
        for p in self.params:
            if p.name == name:
                return p
        if not self.params:
            raise ValueError(f"integrator {self.name!r} takes no options, got {name!r}")
        raise ValueError(f"unknown option {name!r} of integrator {self.name!r}; its options: "
                         f"{', '.join(p.name for p in self.params)}")

    def defaults(self) -> dict[str, Any]:
        """Every parameter's default, by name."""
        return {p.name: p.default for p in self.params}

    def options(self, given: Mapping[str, Any] | None = None) -> dict[str, Any]:
        """Every parameter's value, by name: ``given``'s, checked (:meth:`Param.check`, ValueError
        naming an unknown or ill-typed option and what is allowed), the defaults for the rest."""
        if given is None:
            given = {}
        if not isinstance(given, Mapping):
            raise ValueError(f"integrator_options must be a dict of option names to values, got {given!r}")
        out = self.defaults()
        for name, value in given.items():
            out[name] = self.param(name if isinstance(name, str) else repr(name)).check(value, self.name)
        return out

    def parse_options(self, pairs) -> dict[str, Any]:
        """``{name: value}`` from (name, text) pairs (the command line's NAME=VALUE), each parsed by
        its parameter (:meth:`Param.parse`; ValueError otherwise)."""
        return {name: self.param(name).parse(text, self.name) for name, text in pairs}

    @property
    def replayable(self) -> bool:
        """Path replay (``warp_spt.diff.prb``) can differentiate it."""
        return self.make_vertex is not None


@wp.struct
class RenderParams:
    """The per-launch settings a kernel reads (the rest of RenderSettings is host-side)."""

    width: int
    pixel_start: int
    sample_start: int
    sample_count: int
    max_depth: int         # surface hits per path, as in the seed
    roulette_depth: int    # Russian roulette from this many hits on (0: never)
    seed: wp.uint32


@wp.struct
class PathState:
    """One path between bounces."""

    o: wp.vec3
    d: wp.vec3
    throughput: wp.vec3
    radiance: wp.vec3
    depth: int             # surface hits so far
    alive: int
    rays: int              # closest-hit queries traced
    pdf: float             # solid-angle density of the direction d was sampled with (MIS)
    singular: int          # 1: d came from the camera or a singular lobe (emitters hit count in full)
    vis: int               # the last vertex's shadow ray: 1 visible, 0 occluded, -1 none (nee.VIS_*)
    sampler: SamplerState
    # participating media (integrators.volpath alone sets and reads these): the medium row the ray
    # travels in (-1: none), and the path's densities per channel over their mean (spectral MIS)
    medium: int
    spectral: wp.vec3


def make_start_path(sampler: Sampler):
    """``start_path(cam, pixel, width, seed, index) -> PathState``: the camera ray of one sample."""

    @wp.func
    def start_path(cam: CameraParams, pix: int, width: int, seed: wp.uint32, index: int) -> PathState:
        st = sampler.start(seed, pix, index)
        r12, st2 = sampler.next_2d(st, DIM_PIXEL)
        r34 = wp.vec2(0.0, 0.0)
        if cam.lens_radius > 0.0 or wp.static(not sampler.random_access):
            # a pinhole needs no lens dims; a chain (independent) draws them anyway: its later draws
            # keep their values, and the differentiable kernel never replays a skipping loop
            r34, st2 = sampler.next_2d(st2, DIM_LENS)
        o, d = camera_ray(cam, float(pix % width), float(pix // width), r12[0], r12[1], r34[0], r34[1])
        p = PathState()
        p.o = o
        p.d = d
        p.throughput = wp.vec3(1.0, 1.0, 1.0)
        p.radiance = wp.vec3(0.0, 0.0, 0.0)
        p.depth = 0
        p.alive = 1
        p.rays = 0
        p.pdf = 0.0
        p.singular = 1
        p.vis = -1
        p.sampler = st2
        return p

    return start_path


def make_bsdf_dims(sampler: Sampler, stride: int, features: Features):
    """``bsdf_dims(path) -> (u_lobe, u_dir, u_fresnel, path)``: this bounce's material dimensions.

    The lobe and Fresnel choices are drawn only where a material kind of the scene declared it draws
    them (``Features.needs("dims.lobe")``, ``"dims.fresnel"``; a Sobol' request costs a dozen hashes);
    skipping a dimension shifts no other, and the independent sampler's chain still advances past
    it, so its numbers do not change.
    """
    mixed = features.needs("dims.lobe")
    fresnel = features.needs("dims.fresnel")

    @wp.func
    def bsdf_dims(path: PathState):
        base = DIM_BOUNCE + wp.static(stride) * (path.depth - 1)
        st = path.sampler
        u_lobe = float(0.0)
        if wp.static(mixed):
            u_lobe, st = sampler.next_1d(st, base + OFF_LOBE)
        u_dir, st = sampler.next_2d(st, base + OFF_DIR)
        u_fresnel = float(0.0)
        if wp.static(fresnel):
            u_fresnel, st = sampler.next_1d(st, base + OFF_FRESNEL)
        p = path
        p.sampler = st
        return u_lobe, u_dir, u_fresnel, p

    return bsdf_dims


# the largest finite float32: |x| <= FLT_MAX is false for an infinity and for NaN alone
FLT_MAX = wp.constant(3.4028234663852886e38)


@wp.func
def finite3(v: wp.vec3) -> bool:
    """``wp.isfinite(v)``, inline. On the CPU Warp's isfinite calls its runtime library once per
    component (``_wp_isfinite``); the path kernel asked at every hit (is the emission finite?) and
    every sample, and each call made the compiler save the vertex's vector registers around it."""
    return wp.abs(v[0]) <= FLT_MAX and wp.abs(v[1]) <= FLT_MAX and wp.abs(v[2]) <= FLT_MAX


@wp.func
def continue_path(path: PathState, sf: Surface, bs: BsdfSample, extent: float) -> PathState:
    """Follow a sampled direction: weigh the throughput, move off the surface; absorbed paths end."""
    p = path
    if bs.alive == 0:
        p.alive = 0
        return p
    p.throughput = wp.cw_mul(p.throughput, bs.weight)
    if wp.max(wp.max(p.throughput[0], p.throughput[1]), p.throughput[2]) <= 0.0:
        p.alive = 0
        return p
    p.o = offset_origin(sf.p, sf.ng, bs.through, extent)
    p.d = bs.dir
    p.pdf = bs.pdf
    p.singular = bs.singular
    return p


def fast_inputs(scene_args: list, film: wp.array, counters: wp.array2d, work: wp.array | None = None) -> list:
    """The fast kernel's inputs after the scene's (``Bound.scene_args``: geometry, materials,
    textures, lights, camera, render parameters), in its order."""
    return [*scene_args, film, counters, work]


# The fast kernel's compiler flags: Warp's defaults (wp.config.cpu_compiler_flags: -march=native, LLVM's
# inline threshold raised to 9000, SLP recursion depth 4) with the inline threshold at 2000. Measured
# (docs/performance.md, Where the time goes): the same bits, 5-6% less run time and 0.4-0.5 s less
# compile on three scenes (1000 and 4000 were no better than 9000; LLVM's default, 225, was 40% slower).
FAST_KERNEL_OPTIONS = {
    "cpu_compiler_flags": "-march=native -mllvm=-inline-threshold=2000 -mllvm=-slp-recursion-max-depth=4",
}


@wp.func
def add_to_pixel(film: wp.array(dtype=wp.vec3d), counters: wp.array2d(dtype=wp.int64), pix: int, acc: wp.vec3d,
                 rays: int, bad: int):
    """What a fast kernel's thread adds for its pixel once its samples are done: their float64 sum to
    the film, the rays traced and the non-finite samples dropped to the counters (every integrator's
    kernel ends so)."""
    film[pix] = film[pix] + acc
    counters[pix, 0] = counters[pix, 0] + wp.int64(rays)
    counters[pix, 1] = counters[pix, 1] + wp.int64(bad)


def make_kernel(step, start_path, *, decorate: bool = True):
    """The fast forward kernel: each thread renders some samples of one pixel, summed in float64 and
    added to the film, so a large sample count never drifts. ``decorate`` False: its plain Python
    function, which :mod:`warp_spt.runtime.kernel_index` turns into the kernel of a compiled object
    it found by its own key (``step`` and ``start_path`` are then never read).

    Which pixel and samples: with an empty (None) ``work``, thread t renders ``rp.sample_count``
    samples from index ``rp.sample_start`` of pixel ``rp.pixel_start + t`` (a run of pixels); else
    ``work[t]`` = (pixel, first sample index, samples), a compacted list of any pixels each with its own
    count (adaptive passes: one launch covers the active pixels of a whole image). One kernel serves
    both, so adaptive sampling compiles no variant of its own."""

    def trace(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, cam: CameraParams,
              rp: RenderParams, film: wp.array(dtype=wp.vec3d), counters: wp.array2d(dtype=wp.int64),
              work: wp.array(dtype=wp.vec3i)):
        pix = rp.pixel_start + wp.tid()
        first = rp.sample_start
        count = rp.sample_count
        if work.shape[0] > 0:
            item = work[wp.tid()]
            pix = item[0]
            first = item[1]
            count = item[2]
        acc = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0))
        bad = int(0)
        rays = int(0)
        for j in range(count):
            path = start_path(cam, pix, rp.width, rp.seed, first + j)
            while path.alive != 0:
                path = step(geo, mats, tex, lights, rp, path)
            rays += path.rays
            L = path.radiance
            if finite3(L):
                acc += wp.vec3d(wp.float64(L[0]), wp.float64(L[1]), wp.float64(L[2]))
            else:
                bad += 1           # counted and reported in RenderResult.stats; tests require zero
        add_to_pixel(film, counters, pix, acc, rays, bad)

    if not decorate:
        return trace
    return wp.kernel(enable_backward=False, module="unique", module_options=FAST_KERNEL_OPTIONS)(trace)
