"""Issue 45, section 1: a prototype of ``nee``'s fast kernel with W paths per Warp thread in lockstep.

Not part of the package (``benchmarks/bench_lockstep.py`` measures it against today's kernel). One
thread renders one pixel; its samples go W at a time (W = 8 or 16), each a lane of fixed-size local
arrays (Warp's ``wp.zeros(shape=W, ...)`` inside a kernel: the paths' ``PathState``, their hits and
surfaces, light samples) with an alive mask. Each bounce runs as stages, each stage a loop over
the lanes unrolled by ``wp.static`` (straight-line lane code, the form clang's SLP vectoriser can
pack):

1. traversal, per lane (``make_hit``: today's wide-BVH query, one ray at a time);
2. the hit: sky, emission, the depth limit, the surface (per lane, masked);
3. the vertex's Sobol' requests of ALL lanes as one out-of-line batch of W x R requests (R: the
   batch lanes ``nee``'s vertex draws, 2 on a diffuse scene), no branch: a dead lane computes
   numbers nobody reads;
4. light sampling and the BSDF's value towards the light (per lane, masked);
5. shadow rays, per lane;
6. MIS, the BSDF sample, the continuation and roulette (per lane, masked).

Every stage calls the package's own functions (``make_surface``, ``make_materials``,
``make_lights``, ``nee.make_light_sample``, ``nee.shadow_ray``, ``continue_path``,
``nee.make_roulette``, the scramble's functions), in ``nee``'s vertex's order, so a lane computes
what ``nee``'s vertex computes for the same sample with the same random numbers per (pixel,
sample, dimension), and the lanes' radiance is summed in sample order: the film is bit-identical
to today's kernel's (``bench_lockstep.py`` checks it). Only what ``nee`` does on the benchmark's
scenes is covered: no hooks, no media, a random-access sampler with a batch, light sampling on.
"""

import warp as wp

from warp_spt.accel.ray_queries import KIND_MISS, Hit
from warp_spt.accel.surface import Surface, make_surface
from warp_spt.bsdfs import make_materials
from warp_spt.bsdfs.cutout import make_blocked, make_hit
from warp_spt.device.camera_rays import CameraParams
from warp_spt.device.lobes import LOBE_SMOOTH
from warp_spt.device.structs import Features, Geometry, Materials, Textures
from warp_spt.emitters import LightSample, Lights, make_lights
from warp_spt.integrators import nee
from warp_spt.integrators.common import (
    DIM_BOUNCE,
    FAST_KERNEL_OPTIONS,
    OFF_DIR,
    OFF_FRESNEL,
    OFF_LIGHT_POS,
    OFF_LOBE,
    OFF_ROULETTE,
    PathState,
    RenderParams,
    add_to_pixel,
    continue_path,
    finite3,
    make_start_path,
)
from warp_spt.samplers import Sampler
from warp_spt.samplers.sobol_points import request_key


def make_lockstep_kernel(features: Features, sampler: Sampler, lanes: int = 8, staged: bool = True,
                         unroll: bool = True, inline_threshold: int = 2000):
    """The lockstep kernel: the fast kernel's arguments and result, ``lanes`` samples per group.
    ``staged`` False: the control, the same lanes each stepped whole by ``nee``'s own step (traversal
    and vertex of lane 0, then lane 1, ...), which measures what holding the paths in lanes costs
    without the stages. ``unroll`` False: every lane loop stays a loop (Warp's ``max_unroll`` 1 for
    this module), one copy of each stage's code whose lanes are read from the stack by index: the
    code-size control. ``inline_threshold``: LLVM's, 2000 as the fast kernel's; with W call sites
    clang keeps the traversal and the light sample out of line there, and every call copies the
    scene's structs (about 2 KB, passed by value)."""
    if not (sampler.random_access and sampler.make_batch is not None):
        raise ValueError(f"the lockstep prototype needs a Sobol' sampler with a batch, not {sampler.name!r}")
    if not (features.samples_lights and features.scatters and features.emitters):
        raise ValueError("the lockstep prototype covers scenes with emitters that nee samples")
    W = lanes
    scramble = sampler.make_batch.__self__.scramble       # the Points record the batch belongs to
    sample_word, shuffle, x_of, y_of = scramble.sample, scramble.shuffle, scramble.x, scramble.y
    stride = nee.STRIDE

    hit = make_hit(features)
    surface_at = make_surface(features, False)
    mat = make_materials(features)
    blocked = make_blocked(features)
    light = make_lights(features, surface_at, mat.emission)
    light_sample_drawn = nee.make_light_sample(sampler, light, inline=True, drawn=True)
    roulette = nee.make_roulette(sampler)
    start_path = make_start_path(sampler)
    step = nee.make_path_step(features, sampler, light_sampling=True)

    # the vertex's batch, as make_path_vertex(batched=True) chooses it
    wanted = [OFF_LOBE] if features.needs("dims.lobe") else []
    wanted.append(OFF_DIR)
    if features.needs("dims.fresnel"):
        wanted.append(OFF_FRESNEL)
    wanted.append(OFF_LIGHT_POS)
    R = len(wanted)
    L = {off: k for k, off in enumerate(wanted)}
    L_LOBE, L_DIR = L.get(OFF_LOBE, 0), L[OFF_DIR]
    L_FRESNEL, L_POS = L.get(OFF_FRESNEL, 0), L[OFF_LIGHT_POS]
    has_lobe, has_fresnel = OFF_LOBE in L, OFF_FRESNEL in L
    N = W * R
    vi = wp.types.vector(length=W, dtype=wp.int32)
    vr = wp.types.vector(length=R, dtype=wp.int32)
    vn = wp.types.vector(length=2 * N, dtype=wp.float32)
    offs = wp.constant(vr(*wanted))

    @wp.func(inline=False)
    def lane_requests(pkey: wp.uint32, index: vi, base: vi):
        """Request r of lane j at entries j R + r (x) and N + j R + r (y): every lane's 2-D requests
        at ``base[j] + offs[r]`` of sample ``index[j]``, the same integer code lane after lane."""
        out = vn()
        for j in range(wp.static(W)):
            s = sample_word(index[j])
            for r in range(wp.static(R)):
                key = request_key(pkey, base[j] + offs[r])
                i = shuffle(key, s)
                out[j * wp.static(R) + r] = x_of(key, i)
                out[wp.static(N) + j * wp.static(R) + r] = y_of(key, i)
        return out

    # the fast kernel's signature and work split (integrators.common.make_kernel), so that the same
    # launch drives either kernel
    def trace(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, cam: CameraParams,
              rp: RenderParams, film: wp.array(dtype=wp.vec3d), counters: wp.array2d(dtype=wp.int64),
              work: wp.array(dtype=wp.vec3i)):
        pix = rp.pixel_start + wp.tid()
        first = rp.sample_start
        count = rp.sample_count
        acc = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0))
        bad = int(0)
        rays = int(0)
        for g in range(0, count, wp.static(W)):
            ps = wp.zeros(shape=(W,), dtype=PathState)
            hs = wp.zeros(shape=(W,), dtype=Hit)
            sfs = wp.zeros(shape=(W,), dtype=Surface)
            lss = wp.zeros(shape=(W,), dtype=LightSample)
            xs = wp.zeros(shape=(W,), dtype=wp.vec3)
            les = wp.zeros(shape=(W,), dtype=wp.vec3)
            scatter = vi()
            shadow = vi()
            live = int(0)
            for j in range(W):
                ps[j] = start_path(cam, pix, rp.width, rp.seed, first + g + j)
                if g + j >= count:
                    ps[j].alive = 0
                live += ps[j].alive
            while live > 0 and wp.static(not staged):
                live = int(0)
                for j in range(W):
                    if ps[j].alive != 0:
                        ps[j] = step(geo, mats, tex, lights, rp, ps[j])
                    live += ps[j].alive
            while live > 0:
                # 1. traversal, lane by lane
                for j in range(W):
                    if ps[j].alive != 0:
                        hs[j] = hit(geo, mats, tex, ps[j].o, ps[j].d)
                        ps[j].rays += 1
                # 2. the hit: sky, emission, depth limit, surface
                base = vi()
                index = vi()
                for j in range(W):
                    scatter[j] = 0
                    index[j] = ps[j].sampler.index
                    if ps[j].alive != 0:
                        ps[j].vis = nee.VIS_TRACE
                        h = hs[j]
                        if h.kind == KIND_MISS:
                            w = float(1.0)
                            if ps[j].singular == 0:
                                w = nee.power_heuristic(ps[j].pdf, light.pdf_miss(lights, ps[j].d))
                            ps[j].radiance += wp.cw_mul(ps[j].throughput,
                                                        light.le_escaped(lights, ps[j].d, ps[j].depth)) * w
                            ps[j].alive = 0
                        else:
                            ps[j].depth += 1
                            sf = mat.shade(mats, tex, surface_at(geo, h, ps[j].o, ps[j].d))
                            sfs[j] = sf
                            le = mat.emission(mats, tex, sf)
                            if wp.max(wp.max(le[0], le[1]), le[2]) > 0.0 or not finite3(le):
                                w = float(1.0)
                                if ps[j].singular == 0:
                                    w = nee.power_heuristic(ps[j].pdf, light.pdf_li(geo, lights, h, ps[j].o, ps[j].d))
                                ps[j].radiance += wp.cw_mul(ps[j].throughput, le) * w
                            if ps[j].depth >= rp.max_depth:
                                ps[j].alive = 0
                            else:
                                scatter[j] = 1
                    base[j] = DIM_BOUNCE + wp.static(stride) * (ps[j].depth - 1)
                # 3. every lane's requests in one batch (dead lanes too: no branch)
                u = lane_requests(ps[0].sampler.rng, index, base)
                # 4. light samples and the BSDF towards them
                for j in range(W):
                    shadow[j] = 0
                    if scatter[j] != 0:
                        sf = sfs[j]
                        if (mat.lobes(mats, tex, sf) & LOBE_SMOOTH) != 0:
                            u_light = wp.vec2(u[j * wp.static(R) + wp.static(L_POS)],
                                              u[wp.static(N) + j * wp.static(R) + wp.static(L_POS)])
                            ls, x, st = light_sample_drawn(geo, lights, ps[j].sampler, sf, base[j], u_light)
                            ps[j].sampler = st
                            lss[j] = ls
                            xs[j] = x
                            if ls.pdf > 0.0:
                                le = wp.cw_mul(mat.eval(mats, tex, sf, ls.dir), light.le(geo, mats, tex, lights, ls, x))
                                les[j] = le
                                if wp.max(wp.max(le[0], le[1]), le[2]) > 0.0 or not finite3(le):
                                    shadow[j] = 1
                # 5. shadow rays, lane by lane
                for j in range(W):
                    if shadow[j] != 0:
                        so, sd, st_max = nee.shadow_ray(sfs[j], xs[j], lss[j], geo.extent)
                        ps[j].vis = nee.VIS_VISIBLE
                        if blocked(geo, mats, tex, so, sd, st_max):
                            ps[j].vis = nee.VIS_OCCLUDED
                            shadow[j] = 0
                # 6. MIS, the BSDF sample, the continuation, roulette
                live = int(0)
                for j in range(W):
                    if scatter[j] != 0:
                        sf = sfs[j]
                        if shadow[j] != 0:
                            ls = lss[j]
                            w = light.mis_li(ls, nee.power_heuristic(ls.pdf, mat.pdf(mats, tex, sf, ls.dir)))
                            ps[j].radiance += wp.cw_mul(ps[j].throughput, les[j]) * (w / ls.pdf)
                        u_lobe = float(0.0)
                        if wp.static(has_lobe):
                            u_lobe = u[j * wp.static(R) + wp.static(L_LOBE)]
                        u_dir = wp.vec2(u[j * wp.static(R) + wp.static(L_DIR)],
                                        u[wp.static(N) + j * wp.static(R) + wp.static(L_DIR)])
                        u_fresnel = float(0.0)
                        if wp.static(has_fresnel):
                            u_fresnel = u[j * wp.static(R) + wp.static(L_FRESNEL)]
                        bs = mat.sample(mats, tex, sf, u_lobe, u_dir, u_fresnel)
                        p = continue_path(ps[j], sf, bs, geo.extent)
                        ps[j] = roulette(p, rp, base[j] + OFF_ROULETTE)
                    live += ps[j].alive
            for j in range(W):
                if g + j < count:
                    rays += ps[j].rays
                    Lr = ps[j].radiance
                    if finite3(Lr):
                        acc += wp.vec3d(wp.float64(Lr[0]), wp.float64(Lr[1]), wp.float64(Lr[2]))
                    else:
                        bad += 1
        add_to_pixel(film, counters, pix, acc, rays, bad)

    # a lane loop's bound is the constant W: Warp unrolls it up to max_unroll iterations (16 by default)
    flags = FAST_KERNEL_OPTIONS["cpu_compiler_flags"].replace("-inline-threshold=2000",
                                                             f"-inline-threshold={inline_threshold}")
    options = {"cpu_compiler_flags": flags} if unroll else {"cpu_compiler_flags": flags, "max_unroll": 1}
    return wp.kernel(enable_backward=False, module="unique", module_options=options)(trace)
