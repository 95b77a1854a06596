"""Path guiding: next-event estimation + MIS whose BSDF directions are mixed with a learnt guide.

The render learns, from its own earlier passes, where light arrives from in each region of the
scene (an SD-tree: a binary tree over space, a directional quadtree per leaf; after Müller, Gross
and Novák 2017, "Practical path guiding"; device half ``warp_spt.integrators.guided.sd_tree``, host half
``guiding_tree``), and samples the direction that continues a path from the mixture

    p(wi) = (1 - a) p_bsdf(wi) + a p_guide(wi)          (one-sample MIS, the balance heuristic)

at every vertex with a density lobe (diffuse): with probability ``a`` from the guide, otherwise
from the material. ``a`` is learnt per quadtree between passes (``guiding_tree.quadtree_alpha``:
0, 0.1, 0.25 or 0.5, whichever minimises the learnt radiance's second moment times the guide's
cost; 0 where the quadtree learnt nothing), from earlier passes only, so each pass is unbiased;
where it is 0 the vertex costs a spatial look-up and nothing more. The choice reuses the
direction's first sample coordinate (below ``a``: the guide, rescaled; else the material), so the
2D points of each branch stay stratified (with Sobol', drawing the choice from a dimension of its
own cost 25% in MSE on the indirect room) and the bounce keeps ``nee``'s dimensions. The
throughput is f cos / p (so the estimator stays unbiased whatever the guide). The power heuristic
against light sampling (``nee``'s, ``nee.make_light_sample``) weighs the material's share of the
mixture, (1 - a) p_bsdf, on both sides: MIS weights need only sum to 1, and this spares a guide
look-up per light sample (the guide does not learn the emitters a path meets right after a
recorded vertex, which light sampling covers, so it has little density there). Singular lobes
(mirror, glass) are sampled by the material only, their weight divided by the probability 1 - a
of taking the material's branch.

Training. The spp the caller asked for are split into passes of 1, 1, 2, 4, ... samples per pixel
(each an aligned block of sample indices: a Sobol' net of its own) while they fit in half the
budget; the rest is the last pass. Every pass but the last records, for each diffuse vertex of each
path, the radiance the path then gathered through that direction (less an emitter met right at the
next vertex), times the cosine to the axis of its quadtree's normal bin (so the guide learns the
product's shape), divided by the throughput and the direction's density, into the recording tree;
between passes the host refines the tree (``guiding_tree.refine``, numpy), learns the alphas and
uploads the new sampling and recording trees. From training pass ``stop_after`` on (the third by default), when fewer than
``stop_fraction`` of the records fell in quadtrees that would sample the guide, training stops and
the rest of the samples are one pass without the guide (at ``nee``'s cost: the Cornell box). The
image is the sum of *every* pass's samples with equal weight (training passes included: each is an
unbiased estimate, the first one pure BSDF sampling), so the film holds exactly the requested spp,
the union of the passes is the sample sequence 0 .. spp - 1 (weighting the passes by their
estimated inverse variance was measured and lost: it breaks the Sobol' set apart, 1.8x the MSE on
the Cornell box at 16 spp), and the image is built pass after pass in a fixed order.

Parameters (``PARAMS``, set by name in ``RenderSettings.integrator_options``): ``alpha`` fixes the
guide's probability in every quadtree that learnt something (and training never stops); 0 is
``nee``'s estimator, so its image is ``nee``'s bit for bit (tests/integrators/test_guiding.py) at the cost of
the recording; the others tune training and the tree (``guiding_tree``'s constants are their defaults).

Not a speed option: on the benchmarks' indirectly lit room it reaches 1.6-1.8x lower MSE than ``nee``
at equal spp but costs 1.4-1.5x its CPU time, so its efficiency (1 / (MSE x time)) is 1.1-1.2x
``nee``'s, short of the 1.5x that would make it worth choosing for speed (docs/performance.md,
Path guiding); ``nee`` stays the default and the integrator to pick for speed.

Determinism: the records are integer sums (fixed point), exact in any order, and each worker
thread records into its own arrays, added on the host; the pass schedule depends only on the spp
and on the trees;
so the trees and the image are a pure function of (scene, settings, seed), bit-identical over
thread counts and tile sizes. It renders only through the tile renderer (``render_scene``): the
tree is trained over the whole image, so row windows, progressive batches and the cluster's
sample slices (which would each train their own tree) are refused. On a cluster the tree would
be trained once (on one machine, or identically on each, it is deterministic) and shipped with
the tasks; that shipping is not implemented.
"""

from __future__ import annotations

import os
import sys
import time

import numpy as np
import warp as wp

from warp_spt.device.structs import Features, Geometry, Materials, Textures
from warp_spt.integrators.guided.sd_tree import (
    GuideRecord,
    GuideTree,
    bin_cos,
    dir_leaf,
    guide_pdf,
    guide_quadtree,
    guide_sample,
    new_record,
    record_energy,
    upload_tree,
)
from warp_spt.emitters import Lights
from warp_spt.device.lobes import LOBE_GLOSSY, LOBE_REFLECTION, LOBE_SMOOTH, LOBE_TRANSMISSION
from warp_spt.bsdfs import BsdfSample, make_materials
from warp_spt.accel.surface import Surface
from warp_spt.integrators.guided import tree as guiding_tree
from warp_spt.integrators.common import (
    FAST_KERNEL_OPTIONS,
    FULL_STRIDE,
    CameraParams,
    Integrator,
    Param,
    PathState,
    RenderParams,
    add_to_pixel,
    finite3,
)
from warp_spt.integrators.nee import VertexHooks, make_path_step
from warp_spt.integrators.passes import run_pass
from warp_spt.samplers import Sampler

STRIDE = FULL_STRIDE      # nee's dimensions: the guide's choice reuses the direction's (see vertex)

# Lower bounds that keep the SD-tree's memory and time in proportion to the default's: a quadtree
# holds at most about 4 x MAX_DIR_DEPTH / rho nodes, a pass's spatial leaves about 2 x records / c.
# Measured (cornell 64x64, 64 spp, guided): rho 0.03 197 MB, 0.001 328 MB, 1e-4 3.4 GB and 24 s;
# spatial_c 4000 197 MB, 100 246 MB, 10 391 MB; 0.1 at 32x32 16 spp 5.7 GB and 22 s.
MIN_RHO = 1e-3
MIN_SPATIAL_C = 100.0
MAX_TRAINING_PASSES = 32      # pass k renders 2**(k-1) spp: more than MAX_SPP allows
PARAMS = (
    Param("alpha", None, "probability of sampling the guide, the same in every quadtree that learnt something "
          "(training then never stops); None: learnt per quadtree (guiding_tree.quadtree_alpha)",
          float, 0.0, 1.0, high_open=True, optional=True),
    Param("stop_after", 2, "training passes before the guide may be found not worth it (1 + 1 spp)", int, 1,
          MAX_TRAINING_PASSES),
    # measured fractions: cornell 0.07-0.18, indirect 0.55-0.95, caustics 0.16-0.7
    Param("stop_fraction", 0.25, "training stops when fewer of the records than this fell where the guide "
          "is sampled", float, 0.0, 1.0),
    Param("max_records", 16, "diffuse vertices of one path that record (deeper ones do not train)", int, 1, 256),
    Param("guide_cost", guiding_tree.GUIDE_COST, "the guide's relative cost per vertex that its variance "
          "reduction must pay for (learnt alpha)", float, 0.0, 1e3),
    Param("min_hits", guiding_tree.MIN_HITS, "records a quadtree needs before it is sampled (learnt alpha)", int, 0,
          1 << 30),
    Param("prior_records", guiding_tree.PRIOR_RECORDS, "how strongly a leaf's learnt energy is shrunk towards "
          "the cosine's, in records (learnt alpha)", float, 0.0, 1e9),
    Param("rho", guiding_tree.RHO, "a quadtree node holding more than this fraction of its tree's energy "
          "splits", float, MIN_RHO, 1.0),
    Param("max_dir_depth", guiding_tree.MAX_DIR_DEPTH, "quadtree depth limit (float32 sample warping keeps "
          "about 24 bits over 12 levels)", int, 1, guiding_tree.MAX_DIR_DEPTH),
    Param("spatial_c", guiding_tree.SPATIAL_C, "records a spatial leaf may collect in a 1 spp pass before it "
          "splits (times sqrt(2^k) in pass k)", float, MIN_SPATIAL_C, 1e9),
)


@wp.struct
class GuidedAux:
    """The guided vertex's data (``VertexHooks.Aux``): the sampling tree and this launch's record."""

    g: GuideTree
    rec: GuideRecord


@wp.struct
class GuideVertex:
    """The guide at one vertex (``VertexHooks.guide``): whether it has a density lobe, the sampling
    quadtree's root (-1: the guide is not sampled), the recording quadtree, the guide's probability."""

    dense: int
    root: int
    rqi: int
    a: float


@wp.struct
class GuideNote:
    """What a guided vertex reports (``VertexHooks.new_out``, ``finish``): the recording leaf and its quadtree's root
    ((-1, -1): nothing to record), the recorded density, the radiance its own hit added (channel sum)."""

    node: wp.vec2i
    pdf: float
    emitted: float


@wp.func
def no_note() -> GuideNote:
    n = GuideNote()
    n.node = wp.vec2i(-1, -1)
    n.pdf = 0.0
    n.emitted = 0.0
    return n


@wp.func
def note_emitted(out: GuideNote, le: wp.vec3) -> GuideNote:
    n = out
    n.emitted = le[0] + le[1] + le[2]
    return n


@wp.func
def finish(p: PathState, out: GuideNote):
    return p, out.node, out.pdf, out.emitted


@wp.func
def material_share(gv: GuideVertex) -> float:
    return 1.0 - gv.a


def make(features: Features, sampler: Sampler, differentiable: bool = False):
    """``step(geo, mats, tex, lights, rp, path, aux) -> (path, record node, record pdf, emitted)``:
    one guided bounce, ``nee``'s vertex with the hooks of :func:`make_hooks`; the record node is (the
    recording tree's leaf for the direction taken, the root of its quadtree), (-1, -1) when there is
    nothing to record; the pdf that direction's density; emitted the radiance its hit added."""
    if differentiable:
        raise ValueError("the guided integrator has no differentiable kernel")
    return make_path_step(features, sampler, light_sampling=True, hooks=make_hooks(features))


def make_hooks(features: Features) -> VertexHooks:
    """``nee``'s vertex with the mixture's direction (``VertexHooks``): the guide looked up once per
    vertex with a density lobe, its share of the direction's density, the mixture's sample, the
    record of the direction taken; no Russian roulette (the guided paths never had it)."""
    mat = make_materials(features)
    guiding = features.scatters

    @wp.func
    def guide(aux: GuidedAux, mats: Materials, tex: Textures, sf: Surface) -> GuideVertex:
        gv = GuideVertex()
        gv.dense = 0
        gv.root = -1
        gv.rqi = -1
        gv.a = 0.0
        if wp.static(guiding):
            if (mat.lobes(mats, tex, sf) & LOBE_SMOOTH) != 0:
                gv.dense = 1
                qi = int(-1)
                if aux.rec.on != 0:
                    # one spatial walk, in the recording tree, which refines the sampling tree
                    gv.rqi = guide_quadtree(aux.rec.tree, sf.p, sf.ns)
                    qi = aux.rec.to_sampling[gv.rqi]
                elif aux.g.alpha > 0.0:
                    qi = guide_quadtree(aux.g, sf.p, sf.ns)
                if qi >= 0 and aux.g.alpha > 0.0:
                    gv.a = aux.g.q_alpha[qi]
                    if gv.a > 0.0:
                        gv.root = aux.g.d_root[qi]
        return gv

    @wp.func
    def sample(aux: GuidedAux, gv: GuideVertex, mats: Materials, tex: Textures, sf: Surface, u_lobe: float,
               u_dir: wp.vec2, u_fresnel: float):
        """The mixture's direction and the density it was drawn with (a BsdfSample whose ``pdf`` is the
        material's share, (1 - a) p_material: what MIS weighs, see the module docs)."""
        bs = BsdfSample()
        pm = float(0.0)
        a = gv.a
        if a > 0.0:
            # the direction's first coordinate also chooses guide or material (rescaled, as reuse_pick):
            # the 2D point set stays stratified within each branch, and no dimension is drawn for it
            if u_dir[0] < a:
                gd, pg = guide_sample(aux.g, gv.root, wp.vec2(wp.min(u_dir[0] / a, 0.99999994), u_dir[1]))
                bs.dir = gd
                bs.singular = 0
                bs.alive = 1
                # the guide covers the sphere: below the surface it continues a transmission
                bs.through = wp.where(wp.dot(gd, sf.ng) < 0.0, 1, 0)
                bs.flags = LOBE_GLOSSY | wp.where(bs.through != 0, LOBE_TRANSMISSION, LOBE_REFLECTION)
                bs.pdf = (1.0 - a) * mat.pdf(mats, tex, sf, gd)
                pm = bs.pdf + a * pg
                f = mat.eval(mats, tex, sf, gd)
                if pm > 0.0 and wp.max(wp.max(f[0], f[1]), f[2]) > 0.0:
                    bs.weight = f / pm
                else:
                    bs.alive = 0
            else:
                u_mat = wp.vec2(wp.min((u_dir[0] - a) / (1.0 - a), 0.99999994), u_dir[1])
                bs = mat.sample(mats, tex, sf, u_lobe, u_mat, u_fresnel)
                if bs.singular == 0:
                    if bs.alive != 0:
                        # weight = f cos / p_material, so f cos = weight x p_material: no eval again
                        bs.pdf = (1.0 - a) * bs.pdf
                        pm = bs.pdf + a * guide_pdf(aux.g, gv.root, bs.dir)
                        bs.weight = bs.weight * (bs.pdf / ((1.0 - a) * pm))
                else:
                    bs.weight = bs.weight / (1.0 - a)
        else:
            bs = mat.sample(mats, tex, sf, u_lobe, u_dir, u_fresnel)
            pm = bs.pdf
        return bs, pm

    @wp.func
    def record(aux: GuidedAux, gv: GuideVertex, out: GuideNote, sf: Surface, bs: BsdfSample, pm: float) -> GuideNote:
        """The recording leaf of the direction taken (training passes, density lobes only) and its
        density over the cosine to its quadtree's axis (the guide learns the product's shape)."""
        n = out
        n.pdf = pm
        if wp.static(guiding):
            if aux.rec.on != 0 and gv.dense != 0 and bs.singular == 0 and bs.alive != 0:
                rroot = aux.rec.tree.d_root[gv.rqi]
                n.node = wp.vec2i(dir_leaf(aux.rec.tree, rroot, bs.dir), rroot)
                c = bin_cos(sf.ns, bs.dir)
                if c > 0.0:
                    n.pdf = pm / c
                else:
                    n.node = wp.vec2i(-1, -1)
        return n

    @wp.func
    def leave(aux: GuidedAux, out: GuideNote, p: PathState, rp: RenderParams, dim: int):
        return p, out

    return VertexHooks(Aux=GuidedAux, new_out=no_note, finish=finish, emitted=note_emitted, guide=guide,
                       share=material_share, sample=sample, record=record, leave=leave)


def make_kernel(step, start_path):
    """The guided fast kernel: ``common.make_kernel``'s (same inputs first, same film and counters)
    plus the sampling tree ``g`` and the record ``rec``; each finished path adds, for each of its
    recording vertices (at most as many as ``rec``'s slots per thread: the ``max_records`` option),
    the radiance it gathered after that vertex over the throughput there and the direction's
    density, in fixed point, to ``rec`` with integer atomics (a CUDA launch's threads run at once;
    integer sums are the same in any order)."""

    @wp.kernel(enable_backward=False, module="unique", module_options=FAST_KERNEL_OPTIONS)
    def trace(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, cam: CameraParams,
              rp: RenderParams, film: wp.array(dtype=wp.vec3d), counters: wp.array2d(dtype=wp.int64),
              work: wp.array(dtype=wp.vec3i), g: GuideTree, rec: GuideRecord):
        pix = rp.pixel_start + wp.tid()
        acc = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0))
        bad = int(0)
        rays = int(0)
        aux = GuidedAux()
        aux.g = g
        aux.rec = rec
        for j in range(rp.sample_count):
            path = start_path(cam, pix, rp.width, rp.seed, rp.sample_start + j)
            n = int(0)
            recorded = int(0)
            while path.alive != 0:
                path, node, pdf, emitted = step(geo, mats, tex, lights, rp, path, aux)
                if recorded != 0:
                    # the emitter the last recorded direction met directly: light sampling's share
                    v = rec.slot_value[wp.tid(), n - 1]
                    rec.slot_value[wp.tid(), n - 1] = wp.vec2(v[0] + emitted, v[1])
                recorded = 0
                if node[0] >= 0 and n < rec.slot_node.shape[1]:
                    t = path.throughput[0] + path.throughput[1] + path.throughput[2]
                    if t > 0.0 and pdf > 0.0:
                        rec.slot_node[wp.tid(), n] = node
                        rec.slot_value[wp.tid(), n] = wp.vec2(path.radiance[0] + path.radiance[1] + path.radiance[2],
                                                              1.0 / (t * pdf))
                        n += 1
                        recorded = 1
            rays += path.rays
            L = path.radiance
            if finite3(L):
                acc += wp.vec3d(wp.float64(L[0]), wp.float64(L[1]), wp.float64(L[2]))
                total = L[0] + L[1] + L[2]
                for i in range(n):
                    where = rec.slot_node[wp.tid(), i]
                    v = rec.slot_value[wp.tid(), i]
                    wp.atomic_add(rec.energy, where[0], record_energy((total - v[0]) * v[1]))
                    wp.atomic_add(rec.hits, where[0], wp.int64(1))
            else:
                bad += 1
        add_to_pixel(film, counters, pix, acc, rays, bad)

    return trace


def training_passes(spp: int) -> list[int]:
    """Samples per pixel of each pass: 1, 1, 2, 4, ... while the passes fit in half of ``spp``, then the
    rest (the last pass, which records nothing). Pass k >= 1 of 2**(k-1) samples starts at sample
    2**(k-1): every training pass is an aligned block of the sample sequence (a Sobol' net of its
    own), and so is the last pass when ``spp`` is a power of two."""
    out, done = [], 0
    while done + max(done, 1) <= spp // 2:
        out.append(max(done, 1))
        done += out[-1]
    return out + [spp - done]


def render_passes(b, tiles: list[tuple[int, int]], film: wp.array, counters: wp.array2d, threads: int,
                  report, per_launch: int) -> int:
    """Render ``b.settings.spp`` samples of every pixel of ``tiles`` into ``film`` and ``counters``
    (``Integrator.render_passes``, the tile renderer's hook): training passes with tree refinements
    between them, then the last pass; at most ``per_launch`` samples per launch. Returns the
    launches made. The options (``PARAMS``) come from ``b.options``."""
    rs, device, opt = b.settings, b.dev.device, b.options
    fixed = opt["alpha"]
    if tiles[0][0] != 0 or tiles[-1][1] != b.pixels:
        raise ValueError("the guided integrator trains over the whole image: it cannot render a window of rows")
    plan = training_passes(rs.spp)
    rec_tree = guiding_tree.initial(b.dev.scene.bounds)
    sampling = upload_tree(rec_tree, 0.0, device, sampling=False)      # pass 0: no guide, the material alone
    start, launches, k, stopped = rs.sample_offset, 0, 0, False
    timing = os.environ.get("WARP_SPT_GUIDE_TRACE")     # benchmarks: per pass CPU time and alpha use
    while start < rs.sample_offset + rs.spp:
        training = k < len(plan) - 1 and not stopped
        count = plan[k] if training else rs.sample_offset + rs.spp - start
        rec_dev = upload_tree(rec_tree, 0.0, device, sampling=False)
        slots = [new_record(rec_dev, rec_tree.dir_nodes, training, max(hi - lo for lo, hi in tiles),
                            opt["max_records"], device, guiding_tree.sampling_quadtrees(rec_tree))
                 for _ in range(max(1, threads))]
        t0 = time.process_time()
        launches += run_pass(b, tiles, film, counters, threads, report, per_launch, start - rs.sample_offset, count,
                             slots, lambda rec, sampling=sampling: [sampling, rec])
        if timing:
            print(f"guided pass {k}: {count} spp, {(time.process_time() - t0) / count * 1e3:.2f} CPU ms/spp, "
                  f"training {training}", file=sys.stderr)
        start += count
        if training:
            energy = np.asarray(sum(r.energy.numpy() for r in slots))
            hits = np.asarray(sum(r.hits.numpy() for r in slots))
            host_sampling, rec_tree = guiding_tree.refine(rec_tree, energy, hits, k, c=opt["spatial_c"],
                                                          rho=opt["rho"], max_depth=opt["max_dir_depth"])
            if fixed is None:
                alpha = guiding_tree.quadtree_alpha(host_sampling, hits, cost=opt["guide_cost"],
                                                    min_hits=opt["min_hits"], prior=opt["prior_records"])
            else:
                alpha = fixed
            used = guiding_tree.guided_fraction(host_sampling, hits, alpha)
            # the guide is not worth its cost here: the rest of the samples are one pass without it
            stopped = fixed is None and k + 1 >= opt["stop_after"] and used < opt["stop_fraction"]
            # the sampling tree has the structure of the one this pass recorded in: its arrays are shared
            sampling = upload_tree(host_sampling, 0.0 if stopped else alpha, device, structure=rec_dev,
                                   sampling=not stopped)
            if timing:
                print(f"guided pass {k}: guide used at {used:.3f} of the records' quadtrees, stop {stopped}", file=sys.stderr)
        k += 1
    return launches


INTEGRATOR = Integrator("guided", make, None, STRIDE, tape=False, make_kernel=make_kernel,
                        render_passes=render_passes, params=PARAMS,
                        summary="path guiding: NEE + MIS with BSDF directions mixed with a learnt SD-tree (lower "
                                "error per sample on indirect light, but no faster than nee at equal error: "
                                "not a speed option; see docs/performance.md, Path guiding)")
