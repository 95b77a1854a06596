"""Every kernel family compiles for CUDA, checked on machines without a GPU.

Warp compiles CUDA kernels to PTX through its bundled NVRTC with no GPU and no driver
(``wp.compile_aot_module(module, arch=..., use_ptx=True)``), so code that cannot run on CUDA (a
CPU-only intrinsic, a type NVRTC refuses, an atomic on a type without one) fails here, on the CPU
machines, instead of on the first GPU that runs it.

Two sets of kernels, both built from the registries at collection time, so an integrator, sampler,
kernel kind, material kind or procedural texture registered later is compiled too:

**The representative set** (the default, what CI runs): every ``wp.func`` and every ``wp.static``
branch compiled at least once, for sm_75 (the oldest architecture CUDA 13 supports), and the small
kernels also for sm_90. One fast kernel, the default integrator and sampler's for the meshes-only set
below (what a CUDA render of a mesh scene runs), is compiled as a user's GPU compiles it, optimised;
every other kernel in Warp's debug mode (NVRTC without optimisation): the same source through the same
front end and code generator, so a CPU-only intrinsic, a type NVRTC refuses or an atomic on a type
without one fails there as in release, in a fraction of the time (guided's general kernel: 26 s
against 210 s; ears': 24 s against 255 s, one compile at a time on the development machine). What
only NVRTC's optimiser meets (a kernel it takes an hour to optimise, as volpath's inlined trackers
once did) the optimised kernel and the full matrix meet:

* the fast kernel (``KERNEL_KINDS["fast"]``) of every integrator for ``Features.general()`` (every
  feature, every material kind of ``MATERIAL_KINDS``, both BVHs), the samplers taken in turn (seed
  with sobol, nee with independent, guided with sobol, ...: a sampler's functions do not depend on
  the integrator that calls them), ``guided`` and ``ears`` with their own kernels and training
  records;
* every other registered kernel kind (``tape``, ``replay``, ``aov``, and any added later) once, with
  the default integrator and the samplers in turn across the kinds, for the meshes-only feature set
  below (the kinds' own machinery; the functions they differentiate are compiled for every feature in
  the fast kernels); the tape kernel unrolled to depth 1 (the step's functions, each once: a deeper
  tape unrolls the same step again);
* the default integrator and sampler's fast kernel for three more feature sets that together with
  the general one switch every feature on and off: every registered procedural texture compiled in
  (``general()`` compiles none); meshes only, traced by Warp's BVH alone (the default on CUDA),
  diffuse, lit by emitters, one material kind (no dispatch); spheres only, specular, lit by the
  sky, the last material kind (no diffuse lobe, so no light sampling); and the meshes-only set with
  every medium kind (emitting, behind pass-through boundaries) for ``volpath``, the only integrator
  that reads media (its trackers and shadow path are called, not inlined: inlined, NVRTC ran past an
  hour on this kernel; called, 35 CPU s);
* the small kernels outside the renderers: the procedural-texture probe (every registered texture)
  and the first view's probes (``rendering/first_view``: the CLI's, the viewer's, the API's). The
  viewer has no kernels of its own: it renders through the same set-up (``rendering/setup.bind``).
  These are compiled for sm_90 too (an architecture's own intrinsics show in any kernel that uses
  them).

**The full matrix** (``WARP_SPT_CUDA_FULL=1``): the representative set's feature sets; the fast
kernel of every integrator x every sampler,
every other kind with every integrator (the kinds that refuse ``guided`` and ``ears``, ``replay``
and ``tape``, reported as skipped), every variant for every architecture in ``ARCHS`` (sm_75 and
sm_90; ``WARP_SPT_CUDA_ARCHS=75,86`` overrides), every one optimised as a user's GPU compiles it.
Run it before a release and on a GPU machine
(``benchmarks/gpu_check.py`` runs the kernels themselves there).

The kernels are built as the renderers build them (``KernelKind.build`` of a set-up stub, the one
kernel cache) with ``kernel_cache.load`` made a no-op (nothing is loaded on the CPU), and compiled
in a thread pool (one thread per core: NVRTC compiles run outside Warp's code-generation lock).
Warp's kernel cache keeps each PTX file by the module's hash, so a second run compiles nothing.

Cost, one compile at a time on the 2-core development machine with Warp's cache cold (NVRTC, sm_75),
optimised: the general fast kernel of nee 114 s, seed 43 s, guided 210 s, ears 255 s, volpath 222 s;
path replay's kernel on the meshes-only set 102 s, the tape's (depth 1) 128 s. In debug mode a third
to a tenth of that (seed's: 9 s against 30 s). The representative set compiled every kernel
optimised until 2026-12, 17 compiles in 1,293 s of CI's 2 cores; the fixture prints its count and
time. The full matrix (about 40 compiles, all optimised) ran past an hour of CI's 2 cores: run it
before a release and on a GPU machine. With Warp's cache warm (the modules unchanged): seconds.
"""

from __future__ import annotations

import os
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, replace
from types import SimpleNamespace

import pytest
import warp as wp

import warp_spt.diff.gradients  # noqa: F401  (registers the "tape" kernel kind)
import warp_spt.diff.prb  # noqa: F401  (registers "replay")
import warp_spt.diff.boundary_paths  # noqa: F401  (registers "boundary", the boundary terms' paths)
import warp_spt.rendering.aux_buffers  # noqa: F401  (registers "aov")
from warp_spt.device import proctex
from warp_spt.upload.device_scene import Features
from warp_spt.device.lobes import LOBE_DIFFUSE, LOBE_REFLECTION, LOBE_SPECULAR, LOBE_TRANSMISSION
from warp_spt.integrators import DEFAULT_INTEGRATOR, INTEGRATORS, get_integrator
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.setup import KERNEL_KINDS, Bound
from warp_spt.runtime import kernel_cache
from warp_spt.runtime.warp_init import init_warp
from warp_spt.samplers import DEFAULT_SAMPLER, SAMPLERS
from warp_spt.media.registry import KINDS as MEDIUM_KINDS
from warp_spt.scene.material_schema import MATERIAL_KINDS
from warp_spt.scene.sky import Sky

ARCHS = tuple(int(a) for a in os.environ.get("WARP_SPT_CUDA_ARCHS", "75,90").split(","))
FULL = os.environ.get("WARP_SPT_CUDA_FULL", "") not in ("", "0")
# The representative set compiles the adjoint kinds for the small feature set: their own machinery
# (the tape, path replay, the AOV pass) in full, the functions they differentiate in the fast kernels.
# For Features.general() an adjoint kernel took over 20 minutes of NVRTC at load 9 (replay and tape).
ADJOINT_FEATURES = "meshes-warp-bvh"
TAPE_DEPTH = 1

FEATURE_SETS = {
    "general": Features.general(),
    "procedural": replace(Features.general(), procedural=proctex.features_key(proctex.registered())),
    "meshes-warp-bvh": replace(Features.general(), spheres=False, textures=False, checker=False, smooth=False,
                               lights=("environment.seen", "punctual", "sphere", "triangle", "triangle.texels",
                                       "triangle.tree"),
                               bvh_stack=0, warp_meshes=True, material_kinds=MATERIAL_KINDS[:1],
                               lobes=LOBE_DIFFUSE | LOBE_REFLECTION, material_flags=("seed.diffuse",)),
    "spheres-specular": replace(Features.general(), meshes=False, textures=False, checker=False, emitters=False,
                                smooth=False, bvh_stack=0, warp_meshes=False, material_kinds=MATERIAL_KINDS[-1:],
                                lobes=LOBE_SPECULAR | LOBE_REFLECTION | LOBE_TRANSMISSION,
                                material_flags=("dims.fresnel", "dims.lobe", "frame", "pbr.thin", "pbr.transmission")),
}
# participating media: every medium kind, emitting, behind pass-through boundaries (volpath alone reads
# them), on the meshes-only set (the media's functions do not depend on the surface features)
FEATURE_SETS["media"] = replace(FEATURE_SETS["meshes-warp-bvh"], media=tuple(sorted(MEDIUM_KINDS)) + ("emission", "interface"))
FULL_ONLY_SETS: tuple[str, ...] = ()     # feature sets compiled by the full matrix only
# the integrator of each extra feature set (the default one unless the set's code is another's)
SET_INTEGRATOR = {"media": "volpath"}


@dataclass(frozen=True)
class Variant:
    kind: str
    integrator: str
    sampler: str
    features: str

    @property
    def id(self) -> str:
        return f"{self.kind}-{self.integrator}-{self.sampler}-{self.features}"


def variants(full: bool = FULL) -> list[Variant]:
    """The kernels compiled (see the module docs), from the registries."""
    samplers = [DEFAULT_SAMPLER] + [s for s in SAMPLERS if s != DEFAULT_SAMPLER]
    integrators = [DEFAULT_INTEGRATOR] + [i for i in INTEGRATORS if i != DEFAULT_INTEGRATOR]
    if full:
        out = [Variant("fast", i, s, "general") for i in INTEGRATORS for s in SAMPLERS]
        pairs = [(i, samplers[k % len(samplers)]) for k, i in enumerate(integrators)]
        pairs += [(DEFAULT_INTEGRATOR, s) for s in samplers[len(integrators):]]
        out += [Variant(k, i, s, "general") for k in KERNEL_KINDS if k != "fast" for i, s in pairs]
    else:
        out = [Variant("fast", i, samplers[k % len(samplers)], "general") for k, i in enumerate(integrators)]
        out += [Variant("fast", DEFAULT_INTEGRATOR, s, "general") for s in samplers[len(integrators):]]
        others = [k for k in KERNEL_KINDS if k != "fast"]
        out += [Variant(k, DEFAULT_INTEGRATOR, samplers[n % len(samplers)], ADJOINT_FEATURES)
                for n, k in enumerate(others)]
    out += [Variant("fast", SET_INTEGRATOR.get(f, DEFAULT_INTEGRATOR), DEFAULT_SAMPLER, f)
            for f in FEATURE_SETS if f != "general" and (full or f not in FULL_ONLY_SETS)]
    return out


VARIANTS = variants()
HELPERS = ("proctex-probe", "view-checks")
# the fast kernel the representative set compiles optimised: the default one for a mesh scene (the
# general one took 114 s of NVRTC optimised, one architecture)
RELEASE_ID = Variant("fast", DEFAULT_INTEGRATOR, DEFAULT_SAMPLER, "meshes-warp-bvh").id


def archs_of(name: str) -> tuple[int, ...]:
    """Every architecture for the full matrix; otherwise the first, and every one for the small
    kernels (an architecture's own intrinsics show in any kernel that uses them)."""
    return ARCHS if FULL or name in HELPERS else ARCHS[:1]


def mode_of(name: str) -> str:
    """Warp's compile mode for a kernel: "release" (optimised, as users' GPUs compile it) for the full
    matrix and RELEASE_ID, "debug" (unoptimised: the same front end, a fraction of the time) for the
    rest of the representative set."""
    return "release" if FULL or name == RELEASE_ID else "debug"


def build(v: Variant) -> wp.Kernel:
    """The kernel of ``v``, built as a render set-up builds it (not loaded anywhere)."""
    kind = KERNEL_KINDS[v.kind]
    rs = RenderSettings(integrator=v.integrator, sampler=v.sampler, max_depth=TAPE_DEPTH,
                        features=FEATURE_SETS[v.features])
    sky = Sky.black()
    features = kind.features(FEATURE_SETS[v.features], rs, sky)
    stub = Bound(SimpleNamespace(device="cuda"), None, rs, sky, features, get_integrator(v.integrator), kind)
    return kind.build(stub)


def build_helper(name: str):
    if name == "proctex-probe":
        return proctex._probe_kernel(proctex.features_key(proctex.registered())).module
    from warp_spt.rendering import first_view      # the first view's probes (the CLI's, the viewer's, the API's)
    return first_view._kernels()[0].module


@pytest.fixture(scope="module")
def compiled():
    """{(name, arch): None, or the error's text, or ("skip", why)}: every variant built, then every
    distinct module compiled to PTX for every arch in a thread pool."""
    init_warp()
    results, modules = {}, {}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(kernel_cache, "load", lambda kernel, device="cpu": kernel)
        for v in VARIANTS:
            try:
                modules[v.id] = build(v).module
            except ValueError as err:           # the kind refuses this integrator (no tape, no replay)
                for a in ARCHS:
                    results[(v.id, a)] = ("skip", str(err))
        for h in HELPERS:
            modules[h] = build_helper(h)
    # a tiny kernel first: a Warp without NVRTC (a CPU-only build) skips, and does not fail, the lot
    try:
        wp.compile_aot_module(_probe_nvrtc.module, arch=ARCHS[0], use_ptx=True)
    except Exception as err:    # Warp raises plain RuntimeErrors/Exceptions here
        pytest.skip(f"this Warp cannot compile CUDA kernels (no NVRTC): {err}")
    distinct = {id(m): m for m in modules.values()}
    wanted = {(id(m), a) for name, m in modules.items() for a in archs_of(name)}
    jobs = sorted(wanted, key=lambda job: (ARCHS.index(job[1]), list(distinct).index(job[0])))
    # one mode per module (a module shared by two names takes release if either asks for it); the
    # modules are the renderers' own (the one kernel cache): their mode is put back afterwards
    modes = {}
    for name, m in modules.items():
        modes[id(m)] = "release" if modes.get(id(m)) == "release" else mode_of(name)
    saved = {key: distinct[key].options.get("mode") for key in distinct}

    def compile_one(job):
        key, a = job
        try:
            wp.compile_aot_module(distinct[key], arch=a, use_ptx=True)
            return job, None
        except Exception as err:    # codegen and NVRTC errors have no common base class
            return job, f"{type(err).__name__}: {err}"

    t0 = time.perf_counter()
    try:
        for key, m in distinct.items():
            m.options["mode"] = modes[key]
            m.mark_modified()
        with ThreadPoolExecutor(max_workers=max(1, os.cpu_count() or 1)) as pool:
            done = dict(pool.map(compile_one, jobs))
    finally:
        for key, m in distinct.items():
            m.options["mode"] = saved[key]
            m.mark_modified()
    n_release = sum(1 for key, _ in jobs if modes[key] == "release")
    print(f"\n{len(jobs)} CUDA compiles ({len(distinct)} modules, {n_release} compiles optimised, "
          f"{'full matrix' if FULL else 'representative set'}): {time.perf_counter() - t0:.1f} s")
    for name, m in modules.items():
        for a in ARCHS:
            results[(name, a)] = done.get((id(m), a), ("skip", f"representative set: sm_{ARCHS[0]} only "
                                                                f"(WARP_SPT_CUDA_FULL=1 compiles every architecture)"))
    return results


@wp.kernel(module="unique")
def _probe_nvrtc(x: wp.array(dtype=wp.int64)):
    wp.atomic_add(x, 0, wp.int64(1))


def test_the_variants_come_from_the_registries():
    """Both sets: every integrator and every sampler in a fast kernel (the full matrix: every pair),
    every registered kind compiled; the feature sets together switch every feature on and off and use
    every material kind."""
    for full in (False, True):
        chosen = variants(full)
        fast = {(v.integrator, v.sampler) for v in chosen if v.kind == "fast" and v.features == "general"}
        if full:
            assert fast == {(i, s) for i in INTEGRATORS for s in SAMPLERS}
        else:
            assert {i for i, _ in fast} == set(INTEGRATORS) and {s for _, s in fast} == set(SAMPLERS)
        assert {v.kind for v in chosen} == set(KERNEL_KINDS)
    assert {"tape", "replay", "replay_pathwise", "aov", "boundary"} <= set(KERNEL_KINDS)
    sets = FEATURE_SETS.values()
    for name in ("meshes", "spheres", "textures", "checker", "emitters", "smooth", "warp_meshes", "scatters"):
        assert {getattr(f, name) for f in sets} == {True, False}, name
    assert {f.lit("sky") for f in sets} == {True, False}       # an emitting sky, on and off
    for flag in ("frame", "cutout", "dims.lobe", "dims.fresnel", "seed.diffuse", "pbr.transmission"):
        assert {f.needs(flag) for f in sets} == {True, False}, flag
    assert {f.bvh_stack == 0 for f in sets} == {True, False}
    assert {bool(f.media) for f in sets} == {True, False}
    assert {k for f in sets for k in f.material_kinds} == set(MATERIAL_KINDS)
    assert any(len(f.material_kinds) == 1 for f in sets)
    # every texture registered when this module was collected (the built-ins at least; other test modules
    # may register more later, which their own renders compile)
    assert {n for n, _ in FEATURE_SETS["procedural"].procedural} >= set(proctex.BUILTINS)


def test_every_kind_compiles_every_sampler(compiled):
    """The cover of the other kinds: among the variants each kind accepted, every sampler (the full
    matrix); the representative set compiles every sampler into the adjoint kinds taken together."""
    others = [k for k in KERNEL_KINDS if k != "fast"]
    groups = [[k] for k in KERNEL_KINDS] if FULL else [["fast"], others]
    for kinds in groups:
        built = {v.sampler for v in VARIANTS
                 if v.kind in kinds and not isinstance(compiled[(v.id, ARCHS[0])], tuple)}
        assert built == set(SAMPLERS), (kinds, built)


@pytest.mark.parametrize("arch", ARCHS)
@pytest.mark.parametrize("name", [v.id for v in VARIANTS] + list(HELPERS))
def test_compiles_for_cuda(compiled, name, arch):
    result = compiled[(name, arch)]
    if isinstance(result, tuple):
        pytest.skip(result[1])
    assert result is None, f"{name} does not compile for sm_{arch}:\n{result[:4000]}"
