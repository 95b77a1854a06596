"""Differentiable rendering: gradients of an image (or of a loss on it) with respect to named parameters.

:func:`render_gradients` is the user-facing call. It renders the image with the fast kernel on every
core, evaluates the loss (``warp_spt.losses``) or takes an adjoint image, then runs one of two
backward passes over tiles from a thread pool:

* ``mode="prb"``: path-replay backpropagation (``warp_spt.diff.prb``): a forward-only kernel traces each
  path again with the same random numbers and differentiates the integrator's own ``vertex``
  function at each vertex, with what arrives from beyond it held constant. Any depth; nothing is
  stored per vertex or sample; about the cost of two forward passes. Parameters that move hit points
  or directions (geometry, the camera, fuzz, a light's position) take its pathwise kernel
  (``warp_spt.diff.replay_pathwise``): each path's states are stored in a per-thread row and walked
  backwards, each vertex's adjoint handed to the one before it.
* ``mode="tape"``: Warp's adjoint of a kernel that runs the integrator's ``step`` in a loop unrolled
  to a fixed depth (at most MAX_UNROLLED_DEPTH) with the path's ``alive`` flag instead of a dynamic
  loop (Warp differentiates a dynamic loop correctly only when the carried state is additive). It is
  launched directly (``wp.launch(adjoint=True)``; no ``wp.Tape``, which is one global in Warp 1.19
  and cannot be shared by threads). It is the reference the pathwise replay is checked against, and
  the mode of integrators without a vertex function.

``mode="auto"`` (the default) takes path replay where the integrator has a vertex function. Either way each
tile accumulates into its own gradient buffers, aliased onto the parameter arrays, summed in tile
order in float64, so the gradients are bit-identical whatever the number of threads, and the
backward pass allocates the adjoint image and per-tile buffers whatever the spp and depth
(``GradientResult.backward_bytes``).

What is differentiated (see docs/gradients.md): material colours and emission (exact: paths do not
depend on them), texture texels (nearest and bilinear), ``Roughness`` (the lobe choice is discrete:
``materials.lobe_weight`` adds the score term so the *expected* derivative is right), ``Fuzz``,
the constant sky colour and the gradient sky's zenith and nadir colours, procedural-texture
parameters, the camera's position and direction and geometry (a mesh's positions, an object's pose,
a sphere: each hit primitive re-intersected in closed form, ``ray_queries.make_refine_hit``, because
the traversal's dynamic loop drops its adjoint), with the boundary terms of the curves the camera
sees (``warp_spt.diff.boundary``, edge sampling) and of those the paths' vertices see
(``warp_spt.diff.secondary``: shadows' edges, outlines seen by bounces); docs/gradients.md, Limits.
"""

from __future__ import annotations

import queue
import time
from dataclasses import dataclass, replace

import numpy as np
import warp as wp

from warp_spt.device.camera_rays import CameraParams
from warp_spt.upload.device_scene import DeviceScene
from warp_spt.device.structs import Features, Geometry, Materials, Textures
from warp_spt.emitters import (
    PARAMETER_KINDS,
    PATHWISE_FIELDS,
    Lights,
    alias_field,
    alias_parameters,
    parameter_arrays,
)
from warp_spt.device.media_table import Media, media_of
from warp_spt.device.material_table import with_gradients
from warp_spt.device.textures import tile_view
from warp_spt.diff.params import (
    CAMERA_FIELDS,
    COLOR_FIELDS,
    ENVIRONMENT,
    ENVIRONMENT_TEXELS,
    MATERIAL_FIELDS,
    MEDIUM,
    REPLAYABLE_FIELDS,
    ParamInfo,
    SceneParameters,
    camera_jacobian,
    proc_slice,
)
from warp_spt.diff import geometry_params as geo_params
from warp_spt.diff.geometry_params import GEOMETRY_KINDS, MESH, SPHERE
from warp_spt.diff.boundary import primary_term
from warp_spt.diff.forces import Forces, chain_all
from warp_spt.diff.secondary import receiver_depth, secondary_term
from warp_spt.diff.shadows import shadow_term
from warp_spt.diff.prb import replay_inputs
from warp_spt.diff import replay_pathwise

ENV_TEXELS_KEY = "environment.texels"       # its reduced buffer among the parts of ``_Backward.run``
from warp_spt.integrators import (
    RenderParams,
    check_integrator,
    get_integrator,
    get_step,
)
from warp_spt.losses import Loss
from warp_spt.scene.limits import MAX_SPP
from warp_spt.rendering.film import Film
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.setup import (
    Bound,
    KernelKind,
    bind,
    check,
    register_kind,
    render_features,
)
from warp_spt.rendering.tiles import render_scene
from warp_spt.runtime import kernel_cache
from warp_spt.runtime.threads import cores, run_jobs
from warp_spt.samplers import DEFAULT_SAMPLER, get_sampler
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

MAX_UNROLLED_DEPTH = 8     # compile time grows quickly with the unrolled depth
# The tape interface's defaults differ from the renderer's on purpose: render_differentiable (and
# get_diff_kernel) predate NEE and kept the seed's pure path tracing, the cheapest step to unroll;
# changing them would change the gradients their callers get.
TAPE_INTEGRATOR = "seed"
TAPE_KERNEL_SAMPLER = "independent"
MODES = ("auto", "prb", "tape")
DEFAULT_SETTINGS = RenderSettings(width=64, height=64, spp=4, max_depth=4)     # render_gradients' without settings
# Parameters path replay differentiates (it holds sampled directions fixed and finds hits outside
# the differentiated vertex, see warp_spt.diff.prb); the others (fuzz bends directions, the camera moves
# rays and hit points) need the tape's pathwise derivative.
REPLAYABLE = {("material", f) for f in REPLAYABLE_FIELDS} | {("texture", "texels")}


def replayable(p: ParamInfo) -> bool:
    """Path replay differentiates ``p`` (every procedural-texture parameter and every light's: they
    are read at the vertex; not a light's position or direction, which moves the sampled direction
    that replay holds still: the tape's)."""
    if p.kind in PARAMETER_KINDS:
        return p.field not in PATHWISE_FIELDS[p.kind]
    return p.kind in ("proc", MEDIUM) or (p.kind, p.field) in REPLAYABLE


# deltas[k] shift values passed by value in structs (the camera's frame); zero, they exist for
# their gradients
D_CAM = 0                  # CAMERA_FIELDS, in order
NUM_DELTAS = D_CAM + len(CAMERA_FIELDS)


def _make_kernel(step, start_path, depth: int):
    @wp.kernel(module="unique")
    def trace_diff(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, cam: CameraParams,
                   rp: RenderParams, deltas: wp.array(dtype=wp.vec3), image: wp.array(dtype=wp.vec3)):
        tid = wp.tid()
        pix = rp.pixel_start + tid
        c = cam                     # every field set before any call takes c (see nee's vertex: a copy)
        c.origin = cam.origin + deltas[D_CAM]
        c.to_upper_left = cam.to_upper_left + deltas[D_CAM + 1]
        c.x_step = cam.x_step + deltas[D_CAM + 2]
        c.y_step = cam.y_step + deltas[D_CAM + 3]
        c.right = cam.right + deltas[D_CAM + 4]
        c.up = cam.up + deltas[D_CAM + 5]
        inv_spp = 1.0 / float(rp.sample_count)
        for j in range(rp.sample_count):
            path = start_path(c, pix, rp.width, rp.seed, rp.sample_start + j)
            for _bounce in range(wp.static(depth)):      # unrolled: each step traces one ray
                if path.alive != 0:
                    path = step(geo, mats, tex, lights, rp, path)
            wp.atomic_add(image, tid, path.radiance * inv_spp)

    return trace_diff


def tape_inputs(scene_args: list, deltas: wp.array, image: wp.array) -> list:
    """The tape kernel's inputs after the scene's (``Bound.scene_args``), in its order."""
    return [*scene_args, deltas, image]


def adjoint_structs(scene_args: list) -> list:
    """The adjoints of ``scene_args`` for a launch with ``adjoint=True``: mirrors of the structs
    whose arrays' adjoints are their ``.grad`` buffers. A fresh ``wp.Tape`` builds them (it never
    records: Warp's tape is one global context, so none is kept between calls or threads)."""
    mirrors = wp.Tape()
    return [mirrors.get_adjoint(a) for a in scene_args]


def get_diff_kernel(features: Features, depth: int, integrator: str = TAPE_INTEGRATOR,
                    sampler: str = TAPE_KERNEL_SAMPLER, device: str = "cpu") -> wp.Kernel:
    """The differentiable kernel (forward and adjoint) for these features, unrolled to ``depth``."""
    check_integrator(integrator)
    k = kernel_cache.cached("tape", (integrator, sampler, features, depth), lambda: _make_kernel(
        *get_step(integrator, sampler, features, differentiable=True), depth))
    return kernel_cache.load(k, device)      # on this thread, before any worker launches it


register_kind(KernelKind("tape", lambda b: get_diff_kernel(
    b.features, b.settings.max_depth, b.integrator.name, b.settings.sampler, b.dev.device), render_features))


def _check_estimator(integrator: str, sampler: str) -> None:
    """Refuse the (integrator, sampler) pairs whose gradients disagree with finite differences: none
    now. NEE with the independent sampler was refused (gradients off by up to 4x) until the cause
    was found: ``nee``'s vertex updated the path's struct in place after passing it to ``direct``,
    whose adjoint then replayed the light sample with the updated sampler state (the Sobol' state
    does not change, so it was exact); the vertex now updates a copy (docs/gradients.md, NEE)."""
    check_integrator(integrator)
    get_sampler(sampler)


def _check_media(params: SceneParameters, infos: list[ParamInfo]) -> None:
    """Refuse a medium's coefficients where their derivative is not estimated: a channel whose
    extinction is 0 (its majorant is 0: no collision is ever drawn to carry the derivative) for
    every coefficient, and a channel whose scattering is 0 for ``sigma_s`` (a scattering sets that
    channel's throughput to 0, and path replay recovers what arrives beyond a vertex from the ratio
    to the throughput). Their gradients would be biased, not noisy (docs/volumes.md, Gradients)."""
    for p in infos:
        if p.kind != MEDIUM or p.field == "g":
            continue
        m = params._medium(p)
        if min(m.sigma_t) <= 0.0 or (p.field == "sigma_s" and min(m.sigma_s) <= 0.0):
            what = "scattering" if min(m.sigma_t) > 0.0 else "extinction"
            raise ValueError(f"{p.name}: the medium's {what} is 0 in a channel ({m.sigma_s if what == 'scattering' else m.sigma_t}); "
                             f"its gradient there is not estimated (docs/volumes.md, Gradients)")


def _check_depth(max_depth: int) -> None:
    if not 1 <= max_depth <= MAX_UNROLLED_DEPTH:
        raise ValueError(f"max_depth must be in [1, {MAX_UNROLLED_DEPTH}] for differentiable renders "
                         f"through the tape (path replay, mode='prb', has no limit)")


def choose_mode(mode: str, infos: list[ParamInfo], integrator: str) -> str:
    """"prb" or "tape" for these parameters: "auto" takes path replay when it covers them all (with
    its pathwise kernel, ``diff.replay_pathwise``, for parameters that move hits or directions)."""
    if mode not in MODES:
        raise ValueError(f"unknown gradient mode {mode!r}; choose from {', '.join(MODES)}")
    rec = get_integrator(integrator)
    pathwise = [p.name for p in infos if not replayable(p)]
    ok = rec.replayable and (not pathwise or rec.pathwise)
    # "auto" takes path replay for parameters that move hits too: the pathwise replay gives the tape's
    # values (tests/diff/test_replay_pathwise.py: 3e-8) at about half its backward time and at any
    # depth (benchmarks/bench_gradients.py, geometry)
    auto_ok = ok
    if mode != "prb" and not (mode == "auto" and auto_ok) and not rec.tape:
        raise ValueError(f"integrator {integrator!r} is not differentiable through the tape")
    if mode == "auto":
        return "prb" if auto_ok else "tape"
    if mode == "prb" and not ok:
        why = (f"{', '.join(pathwise)} need(s) pathwise derivatives, which integrator {integrator!r}'s "
               f"vertex does not have" if pathwise and rec.replayable
               else f"integrator {integrator!r} has no vertex function")
        raise ValueError(f"path replay cannot differentiate this: {why}; use mode='tape' or 'auto'")
    return mode


def replay_kind(infos: list[ParamInfo]) -> str:
    """Path replay's kernel kind for these parameters: the pathwise one where one moves hit points or
    directions (geometry, the camera, fuzz, a light's position), else the forward-order one."""
    return "replay_pathwise" if any(not replayable(p) for p in infos) else "replay"


# ------------------------------------------------------------------------------------------------
# The user-facing call: named gradients on every core


@dataclass
class GradientResult:
    """``image`` (H, W, 3) float32 linear radiance, the fast kernel's (path replay with an adjoint
    image and no ``gradient_seed`` takes it from its first pass, the same sums; None when asked
    for no image); ``loss`` its value
    (None when an adjoint image was given); ``grads`` d loss / d parameter by name (float64, the
    parameter's shape); ``forward_seconds`` wall-clock of the separate forward render (0 when path
    replay gave the image) and ``backward_seconds`` of the rest; ``backward_bytes`` what the
    backward pass allocated (adjoint image, per-tile gradient buffers, scratch); ``mode`` "prb" or
    "tape", the backward pass that ran."""

    image: np.ndarray | None
    loss: float | None
    grads: dict[str, np.ndarray]
    forward_seconds: float
    backward_seconds: float
    backward_bytes: int
    tiles: int
    threads: int
    mode: str = "tape"


def render_gradients(params: SceneParameters, settings: RenderSettings | None = None, *,
                     loss: Loss | None = None, adjoint: np.ndarray | None = None,
                     wrt: list[str] | None = None, gradient_seed: int | None = None,
                     mode: str = "auto", boundary: bool = True, boundary_spp: int | None = None,
                     secondary_spp: int | None = None, secondary_depth: int | None = None,
                     image: bool = True) -> GradientResult:
    """Render ``params.scene`` as seen by ``params.camera`` under ``params.sky`` and return the image
    and the gradients of ``loss(image)`` (or of sum(adjoint * image)) for the parameters named in
    ``wrt`` (default: every parameter). ``settings.sky`` is ignored (the sky is ``params.sky``).
    Russian roulette (``settings.roulette_depth``) is replayed: the same samples survive, and the
    survival probability is held constant, which keeps the gradient unbiased (docs/gradients.md).

    ``mode``: "prb" (path replay, ``warp_spt.diff.prb``: any depth, about the cost of two forward
    passes; its pathwise kernel, ``diff.replay_pathwise``, for parameters that move hits or
    directions, at most ``MAX_PATHWISE_DEPTH`` bounces), "tape" (Warp's adjoint of the step unrolled
    to ``max_depth`` <= MAX_UNROLLED_DEPTH), or "auto": "prb" where the integrator has a vertex
    function (the pathwise one where a parameter needs it), else "tape".

    ``boundary``: add the boundary terms to geometry and camera parameters (False: the interior term
    alone): primary visibility (``warp_spt.diff.boundary``), estimated with ``boundary_spp`` samples
    per pixel along the image's silhouettes and edges, and secondary visibility at the camera rays'
    hits and later vertices (``warp_spt.diff.secondary``: shadows' edges, outlines seen from the
    surface) with ``secondary_spp`` paths per pixel, each giving its camera ray's hit and one vertex
    of depth 2 to ``secondary_depth`` (default ``max_depth - 1``; 1: the camera rays' hits alone);
    both budgets default to ``settings.spp``, 0 leaves one out. (The interior term takes
    ``settings.spp``: Mitsuba's sppc, sppp and sppi.)

    ``image``: False skips a forward render that only the returned image needs (with ``adjoint=`` and
    a ``gradient_seed``: ``GradientResult.image`` is then None).

    ``gradient_seed``: replay the backward pass with this seed instead of ``settings.seed``. A loss
    that is not linear in the image (L2) then gets an unbiased gradient of the *expected* image's loss:
    with the same seed, the image's noise and its derivative are correlated and the gradient of
    E[(I - T)^2] is biased (inverse rendering at low spp converges to the wrong value).
    """
    rs = settings or DEFAULT_SETTINGS
    if (loss is None) == (adjoint is None):
        raise ValueError("give exactly one of loss= and adjoint=")
    if isinstance(wrt, str) or not (wrt is None or isinstance(wrt, (list, tuple))):
        raise TypeError(f"wrt must be a list of parameter names (params.names()), got {wrt!r:.80}")
    names = list(params.differentiable() if wrt is None else wrt)
    infos = [params.info(n) for n in names]
    mode = choose_mode(mode, infos, rs.integrator)
    _check_estimator(rs.integrator, rs.sampler)
    _check_media(params, infos)
    receiver_depth(secondary_depth, rs.max_depth)           # refused before any render
    kind = replay_kind(infos) if mode == "prb" else "tape"
    if kind == "tape":
        _check_depth(rs.max_depth)
    elif kind == "replay_pathwise":
        replay_pathwise.check_depth(rs.max_depth)
    dev, sky, camera = params.scene, params.sky, params.camera
    rs = replace(rs, sky=sky, features=None)
    # path replay's first pass traces the very paths of the forward render: when the adjoint is known
    # before the image (no loss) and the seeds are the same, its radiance sums are the image
    replay_image = mode == "prb" and loss is None and gradient_seed is None
    shape = (rs.height, rs.width, 3)
    skip = replay_image or (loss is None and not image)
    image, value, adj, forward_seconds = _forward(dev, camera, rs, loss, adjoint, skip)

    t0 = time.perf_counter()
    brs = rs if gradient_seed is None else replace(rs, seed=gradient_seed)
    bw = _Backward(bind(dev, camera, brs, mode=kind),
                   wants={p.kind for p in infos} | {(p.kind, p.field) for p in infos})
    sums = bw.run(adj.reshape(-1, 3), rs.threads, want_image=replay_image)
    if replay_image:
        image = Film(sums.pop("film").reshape(shape), rs.spp).image()
    grads = {p.name: _pick(p, sums, dev, camera, rs, params._poses, params._base_meshes) for p in infos}
    moved = [p for p in infos if p.kind in (*GEOMETRY_KINDS, "camera")
             or (p.kind == "punctual" and p.field in ("position", "direction"))]
    if boundary and moved:           # the curves they move: estimates of their own
        for n, g in boundary_terms(bw.bound, adj, moved, params._poses, brs.seed,
                                   _budget(boundary_spp, rs.spp, "boundary_spp"),
                                   _budget(secondary_spp, rs.spp, "secondary_spp"), secondary_depth).items():
            grads[n] = grads[n] + g
    backward_seconds = time.perf_counter() - t0
    return GradientResult(image, value, grads, forward_seconds, backward_seconds, bw.nbytes, len(bw.tiles),
                          bw.threads, mode)


def _budget(value: int | None, default: int, name: str) -> int:
    """A boundary term's samples per pixel (``default`` when None; 0 leaves the term out)."""
    if value is None:
        return default
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 0 <= value <= MAX_SPP:
        raise ValueError(f"{name} must be an integer in [0, {MAX_SPP}], got {value!r}")
    return int(value)


def boundary_terms(bound: Bound, adj: np.ndarray, moved: list, poses: list, seed: int, primary_spp: int,
                   secondary_spp: int, secondary_depth: int | None = None) -> dict[str, np.ndarray]:
    """The boundary terms of the geometry, camera and punctual-light parameters ``moved``: primary
    visibility (``diff.boundary``), secondary visibility at the paths' vertices (``diff.secondary``)
    and the punctual lights' hard shadows (``diff.shadows``), as forces on the geometry's points
    chained to the parameters (``diff.forces``) and the camera's and lights' own gradients."""
    topology: dict = {}                  # the meshes' edge lists, built once for the terms
    visible = [p for p in moved if p.kind != "punctual"]
    f1, cam1 = primary_term(bound, adj, visible, primary_spp if visible else 0, seed, topology)
    f2, cam2 = secondary_term(bound, adj, visible, secondary_spp if visible else 0, seed, topology, secondary_depth)
    f3, lit = shadow_term(bound, adj, moved, primary_spp, seed, topology)
    out = chain_all(moved, Forces.join([f1, f2, f3]), bound.dev.scene, poses)
    for n in cam1:
        out[n] = cam1[n] + cam2[n]
    out.update(lit)
    return out


def _forward(dev: DeviceScene, camera: Camera, rs: RenderSettings, loss: Loss | None, adjoint, skip: bool):
    """(image or None, loss value or None, the adjoint image (H, W, 3) float32, forward seconds):
    the forward render and the loss, unless ``skip`` (path replay's first pass gives the image, or
    nobody wants it)."""
    image, value, seconds = None, None, 0.0
    if skip:
        check(rs, camera)
        adj = adjoint
    else:
        t0 = time.perf_counter()
        image = render_scene(dev, camera, rs).image
        seconds = time.perf_counter() - t0
        value, adj = loss(image) if loss is not None else (None, adjoint)
    adj = np.asarray(adj, dtype=np.float32)
    shape = (rs.height, rs.width, 3)
    if adj.shape != shape or not np.all(np.isfinite(adj)):
        raise ValueError(f"the adjoint image must be finite with shape {shape}, got {adj.shape}")
    return image, value, adj, seconds


class _Backward:
    """One backward pass: per-tile gradient buffers, adjoint launches from a pool, ordered reduction."""

    def __init__(self, bound: Bound, wants: set):
        self.bound, self.dev, self.rs, self.tex = bound, bound.dev, bound.settings, bound.tex
        self.mode = "tape" if bound.kind.name == "tape" else "prb"
        self.pathwise = bound.kind.name == "replay_pathwise"
        rs = self.rs
        self.wants_texels = "texture" in wants
        self.wants_proc = "proc" in wants
        # the environment map's texels: a gradient buffer of the map's size per tile, only when asked
        self.wants_env = (ENVIRONMENT, ENVIRONMENT_TEXELS) in wants
        self.wants_media = MEDIUM in wants
        # a mesh's positions or pose, a sphere: the kernels' corners, corner normals, placements and
        # spheres carry this tile's gradient buffers (geometry_params has the chain rules)
        self.wants_geometry = bool(wants & set(GEOMETRY_KINDS))
        n = rs.width * rs.height
        self.tiles = [(p, min(n, p + rs.tile_pixels)) for p in range(0, n, rs.tile_pixels)]
        self.nbytes = 0
        self.threads = 1
        self.corners = None
        if self.wants_geometry:
            self.corners = wp.array(geo_params.corner_points(self.dev.scene), dtype=wp.vec3, device=self.dev.device)
            self.nbytes += self.corners.capacity

    def _grad_alias(self, a: wp.array) -> wp.array:
        """``a``'s data with a fresh zeroed gradient buffer of this tile."""
        g = wp.zeros(a.shape, dtype=a.dtype, device=a.device)
        self.nbytes += g.capacity
        return wp.array(ptr=a.ptr, dtype=a.dtype, shape=a.shape, device=a.device, grad=g)

    def _tile_inputs(self, lo: int, hi: int) -> tuple:
        m = with_gradients(self.dev.materials, self._grad_alias)     # the schema's differentiable columns
        t = self.tex
        if self.wants_texels or self.wants_proc:
            t = Textures()
            t.texels, t.tiles, t.bilinear = self.tex.texels, self.tex.tiles, self.tex.bilinear
            t.proc_kind, t.proc_params = self.tex.proc_kind, self.tex.proc_params
            if self.wants_texels:
                t.texels = self._grad_alias(t.texels)
            if self.wants_proc:
                t.proc_params = self._grad_alias(t.proc_params)
        deltas = wp.zeros(NUM_DELTAS, dtype=wp.vec3, device=self.dev.device, requires_grad=True)
        scratch = None      # the tape's forward output; path replay needs none
        if self.mode == "tape":
            scratch = wp.zeros(hi - lo, dtype=wp.vec3, device=self.dev.device)
            self.nbytes += scratch.capacity
        self.nbytes += 2 * deltas.capacity
        lights = alias_parameters(self.bound.lights, self._grad_alias)     # the sky's colours, as m's
        if self.wants_env:
            lights = alias_field(lights, ENVIRONMENT, ENVIRONMENT_TEXELS, self._grad_alias)
        geo = None
        if self.wants_media or self.wants_geometry:
            geo = self._geometry_alias(self.dev.geometry)
        return m, t, lights, deltas, scratch, geo

    def _geometry_alias(self, geo: Geometry) -> Geometry:
        """A copy of ``geo`` whose media table's coefficients and g (media) or whose corners, corner
        normals, placements and spheres (geometry) carry this tile's gradient buffers."""
        out = Geometry()
        for k in Geometry.vars:
            setattr(out, k, getattr(geo, k))
        if self.wants_media:
            media = Media()
            for k in Media.vars:
                setattr(media, k, getattr(geo.media, k))
            for k in MEDIUM_ARRAYS:
                setattr(media, k, self._grad_alias(getattr(geo.media, k)))
            out.media = media
        if self.wants_geometry:
            out.corner_point = self._grad_alias(self.corners)
            out.has_corner_points = 1
            for k in GEOMETRY_ARRAYS:
                setattr(out, k, self._grad_alias(getattr(geo, k)))
        return out

    def run(self, adj: np.ndarray, threads: int | None, want_image: bool = False) -> dict:
        """The reduced gradient buffers by name; with ``want_image`` (path replay only) also
        ``"film"``, the radiance sums of pass 1 (H*W, 3) float64."""
        dev = self.dev
        adj_image = wp.array(adj, dtype=wp.vec3, device=dev.device)
        self.nbytes += adj_image.capacity
        film = wp.zeros(len(adj) if want_image else 1, dtype=wp.vec3d, device=dev.device)
        inputs = [self._tile_inputs(lo, hi) for lo, hi in self.tiles]
        self.threads = max(1, min(threads or cores(), len(self.tiles)))
        rows = queue.SimpleQueue()      # the pathwise kernel's scratch: one per worker, not per tile
        if self.pathwise:
            for _ in range(self.threads):
                r = replay_pathwise.scratch(self.rs.tile_pixels, self.rs.max_depth, dev.device)
                self.nbytes += sum(a.capacity for a in r)
                rows.put(r)

        def work(k: int) -> None:
            lo, hi = self.tiles[k]
            m, t, lights, deltas, scratch, geo = inputs[k]
            args = self.bound.scene_args(self.bound.params(lo), materials=m, textures=t, lights=lights, geometry=geo)
            kernel = self.bound.kernel
            if self.pathwise:            # a forward launch too, with its scratch and the camera's adjoint
                r = rows.get()
                try:
                    wp.launch(kernel, dim=hi - lo, device=dev.device, inputs=replay_pathwise.pathwise_inputs(
                        args, adj_image[lo:hi], want_image, film[lo:hi] if want_image else film, deltas.grad, r))
                finally:
                    rows.put(r)
                return
            if self.mode == "prb":       # a forward launch: the replay kernel accumulates the adjoints
                wp.launch(kernel, dim=hi - lo, device=dev.device, inputs=replay_inputs(
                    args, adj_image[lo:hi], want_image, film[lo:hi] if want_image else film))
                return
            wp.launch(kernel, dim=hi - lo, device=dev.device, inputs=tape_inputs(args, deltas, scratch),
                      adj_inputs=tape_inputs(adjoint_structs(args), deltas.grad, adj_image[lo:hi]), adjoint=True)

        # the renderer's tile runner: Ctrl-C stops the workers safely (no concurrent.futures, see parallel)
        run_jobs(list(range(len(self.tiles))), lambda k, stop, done: work(k), self.threads, lambda units: None)
        # reduce in tile order, in float64: independent of threads
        sums: dict = {}
        for m, t, lights, deltas, _, geo in inputs:
            parts = {f: getattr(m, f).grad for f in MATERIAL_FIELDS}
            parts.update({kind: a.grad for kind, a in parameter_arrays(lights).items()})
            parts["deltas"] = deltas.grad
            if self.wants_texels:
                parts["texels"] = t.texels.grad
            if self.wants_proc:
                parts["proc"] = t.proc_params.grad
            if self.wants_env:
                parts[ENV_TEXELS_KEY] = getattr(getattr(lights, ENVIRONMENT), ENVIRONMENT_TEXELS).grad
            if self.wants_media:
                parts.update({f"medium.{k}": getattr(geo.media, k).grad for k in MEDIUM_ARRAYS})
            if self.wants_geometry:
                parts.update({f"geometry.{k}": getattr(geo, k).grad for k in ("corner_point", *GEOMETRY_ARRAYS)})
            for key, g in parts.items():
                v = g.numpy().astype(np.float64)
                sums[key] = sums[key] + v if key in sums else v
        if want_image:
            sums["film"] = film.numpy()
        return sums


def _pick(p, sums: dict, dev: DeviceScene, camera: Camera, rs: RenderSettings, poses: list,
          base_meshes: list) -> np.ndarray:
    """The gradient of one named parameter from the reduced buffers."""
    if p.kind == "camera":       # chain rule through the host's image-plane frame (float64)
        jac = camera_jacobian(camera, p.field, rs.width, rs.height)
        return np.einsum("fi,fij->j", sums["deltas"][D_CAM:D_CAM + len(CAMERA_FIELDS)], jac)
    if p.kind == "material":
        g = sums[p.field][p.index]
        return np.asarray(g, dtype=np.float64).reshape(p.shape)
    if p.kind == "texture":
        return tile_view(sums["texels"], dev.atlas_tiles()[p.index]).copy()
    if p.kind == "proc":
        off, size = proc_slice(dev.scene, p)
        return sums["proc"][p.index][off:off + size].reshape(p.shape).copy()
    if (p.kind, p.field) == (ENVIRONMENT, ENVIRONMENT_TEXELS):
        return sums[ENV_TEXELS_KEY].reshape(p.shape).copy()
    if p.kind == MEDIUM:
        return _medium_gradient(p, sums, dev)
    if p.kind in GEOMETRY_KINDS:
        return geometry_gradient(p, sums, dev, poses, base_meshes)
    if p.kind in PARAMETER_KINDS:            # a light's parameter (the sky's colours): a row of its array
        return sums[p.kind][p.index].copy()
    raise ValueError(f"no gradient buffer holds {p.name}")


MEDIUM_ARRAYS = ("sigma_a", "sigma_s", "g")     # the media table's arrays path replay differentiates
# the Geometry arrays the tape differentiates for geometry parameters (besides corner_point)
GEOMETRY_ARRAYS = ("corner_normal", "spheres", "inst_linear", "inst_offset", "inst_normal")


def geometry_gradient(p: ParamInfo, sums: dict, dev: DeviceScene, poses: list, base_meshes: list) -> np.ndarray:
    """A geometry parameter's gradient from those of the arrays the kernel read (corners, corner
    normals, placements, spheres; ``geometry_params`` has the chain rules)."""
    scene = dev.scene
    if p.kind == SPHERE:
        row = sums["geometry.spheres"][p.index]
        return row[:3].copy() if p.field == "center" else np.asarray(row[3], dtype=np.float64).reshape(())
    smooth = dev.geometry.has_corner_normals != 0
    if p.kind == MESH:
        k = p.index
        m = scene.meshes[k]
        lo, hi = geo_params.face_ranges(scene)[k]
        corner = sums["geometry.corner_point"][3 * lo:3 * hi].reshape(-1, 3, 3)
        g = geo_params.vertex_gradient(scene, k, corner)
        if smooth and base_meshes[k].corner_normal is None:     # its flat normals, read as corner normals
            g += geo_params.flat_normal_gradient(scene, k, sums["geometry.corner_normal"][3 * lo:3 * hi].reshape(-1, 3, 3))
        if m.transforms is None:         # world-space vertices of base positions moved by its pose
            pose = next(q for q in poses if q.mesh == k)
            g = g @ geo_params.placement(pose)[:3, :3]
        return g
    pose = poses[p.index]
    k = pose.mesh
    m = scene.meshes[k]
    if m.transforms is not None:
        item = geo_params.item_of(scene, pose)
        full = geo_params.pose_gradient_placed(pose, sums["geometry.inst_linear"][item],
                                               sums["geometry.inst_offset"][item], sums["geometry.inst_normal"][item])
    else:
        lo, hi = geo_params.face_ranges(scene)[k]
        world = geo_params.vertex_gradient(scene, k, sums["geometry.corner_point"][3 * lo:3 * hi].reshape(-1, 3, 3))
        normals = sums["geometry.corner_normal"][3 * lo:3 * hi].reshape(-1, 3, 3) if smooth else None
        full = geo_params.pose_gradient_world(pose, base_meshes[k], world, normals)
    return full[geo_params.pose_slice(p.field)]


def _medium_gradient(p: ParamInfo, sums: dict, dev: DeviceScene) -> np.ndarray:
    """A medium's gradient from those of its row of the media table, which holds a grid's
    coefficients times its density scale (and a majorant that moves with them)."""
    row = p.index
    if p.field == "g":
        return np.asarray(sums["medium.g"][row], dtype=np.float64).reshape(())
    ga, gs = sums["medium.sigma_a"][row], sums["medium.sigma_s"][row]
    m = media_of(dev.scene)[0][row]
    scale = m.density_scale if m.density is not None else 1.0
    if p.field == "sigma_a":
        return ga * scale
    if p.field == "sigma_s":
        return gs * scale
    return np.asarray(np.dot(m.sigma_a, ga) + np.dot(m.sigma_s, gs), dtype=np.float64).reshape(())


# ------------------------------------------------------------------------------------------------
# The tape interface (single-threaded; kept for users of wp.Tape and as the benchmark's baseline)


@dataclass
class DiffRender:
    """A differentiable render: ``image`` (H*W vec3, on the tape) and the parameters it depends on."""

    image: wp.array
    tape: wp.Tape
    width: int
    height: int

    def numpy(self) -> np.ndarray:
        return self.image.numpy().reshape(self.height, self.width, 3)


def enable_material_gradients(scene: DeviceScene) -> None:
    """Make the material colour and emission arrays of ``scene`` carry gradients
    (``scene.materials.diffuse.grad`` etc. after ``tape.backward``)."""
    m = scene.materials
    for name in COLOR_FIELDS:
        a = getattr(m, name)
        if not a.requires_grad:
            setattr(m, name, wp.array(a.numpy(), dtype=wp.vec3, device=a.device, requires_grad=True))


def render_differentiable(scene: DeviceScene, camera: Camera | None = None, *, width: int = 32,
                          height: int = 32, spp: int = 4, max_depth: int = 4, sky: Sky | None = None,
                          seed: int = 0, texture_filter: str = "nearest", integrator: str = TAPE_INTEGRATOR,
                          sampler: str = DEFAULT_SAMPLER) -> DiffRender:
    """Render on a ``wp.Tape``; call ``result.tape.backward(grads={result.image: adjoint})`` and read
    e.g. ``scene.materials.diffuse.grad`` (call :func:`enable_material_gradients` first).

    Single-threaded (the tape is global in Warp 1.19); prefer :func:`render_gradients`.
    ``max_depth`` is unrolled, at most MAX_UNROLLED_DEPTH. Same integrator, sampler and samples
    0..spp-1 as :func:`warp_spt.render` (Russian roulette off).
    """
    _check_depth(max_depth)
    if width < 1 or height < 1 or spp < 1:
        raise ValueError("width, height and spp must be positive")
    _check_estimator(integrator, sampler)
    b = bind(scene, camera, RenderSettings(width=width, height=height, spp=spp, max_depth=max_depth, sky=sky,
                                           seed=seed, texture_filter=texture_filter, integrator=integrator,
                                           sampler=sampler, device=scene.device), mode="tape")
    image = wp.zeros(width * height, dtype=wp.vec3, device=scene.device, requires_grad=True)
    deltas = wp.zeros(NUM_DELTAS, dtype=wp.vec3, device=scene.device)
    tape = wp.Tape()
    with tape:
        wp.launch(b.kernel, dim=width * height, device=scene.device,
                  inputs=tape_inputs(b.scene_args(b.params()), deltas, image))
    return DiffRender(image, tape, width, height)
