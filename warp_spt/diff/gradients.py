"""Differentiable rendering: gradients of an image (or of a loss on it) with respect to named parameters.

:func:`render_gradients` is the user-facing call. It renders the image with the fast kernel on every
core, evaluates the loss (``warp_spt.losses``) or takes an adjoint image, then runs one of two
backward passes over tiles from a thread pool:

* ``mode="prb"``: path-replay backpropagation (``warp_spt.diff.prb``): a forward-only kernel traces each
  path again with the same random numbers and differentiates the integrator's own ``vertex``
  function at each vertex, with what arrives from beyond it held constant. Any depth; nothing is
  stored per vertex or sample; about the cost of two forward passes.
* ``mode="tape"``: Warp's adjoint of a kernel that runs the integrator's ``step`` in a loop unrolled
  to a fixed depth (at most MAX_UNROLLED_DEPTH) with the path's ``alive`` flag instead of a dynamic
  loop (Warp differentiates a dynamic loop correctly only when the carried state is additive). It is
  launched directly (``wp.launch(adjoint=True)``; no ``wp.Tape``, which is one global in Warp 1.19
  and cannot be shared by threads). It alone has pathwise derivatives (fuzz bends directions, the
  camera moves hits).

``mode="auto"`` (the default) takes path replay unless a parameter needs the tape. Either way each
tile accumulates into its own gradient buffers, aliased onto the parameter arrays, summed in tile
order in float64, so the gradients are bit-identical whatever the number of threads, and the
backward pass allocates the adjoint image and per-tile buffers whatever the spp and depth
(``GradientResult.backward_bytes``).

What is differentiated (see docs/gradients.md): material colours and emission (exact: paths do not
depend on them), texture texels (nearest and bilinear), ``Roughness`` (the lobe choice is discrete:
``materials.lobe_weight`` adds the score term so the *expected* derivative is right), ``Fuzz`` (tape),
the constant sky colour and the gradient sky's zenith and nadir colours, procedural-texture
parameters, the camera's position and direction (tape only, through shading: the tape's kernel
re-intersects each hit primitive in closed form, ``geometry.make_refine_hit``, because the
traversal's dynamic loop drops its adjoint). Visibility is not differentiated (no edge sampling):
silhouettes that move with a parameter bias its gradient.
"""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, replace

import numpy as np
import warp as wp

from warp_spt.core.device_scene import (
    DeviceScene,
    Features,
    Geometry,
    Materials,
    Textures,
)
from warp_spt.core.lights import (
    PARAMETER_KINDS,
    Lights,
    alias_parameters,
    light_table,
    parameter_arrays,
    sky_emits,
)
from warp_spt.core.textures import tile_view
from warp_spt.diff.params import (
    CAMERA_FIELDS,
    COLOR_FIELDS,
    MATERIAL_FIELDS,
    ParamInfo,
    SceneParameters,
    camera_jacobian,
    proc_slice,
)
from warp_spt.diff.prb import get_replay_kernel
from warp_spt.integrators import (
    VERTICES,
    CameraParams,
    RenderParams,
    camera_params,
    check_integrator,
    get_step,
)
from warp_spt.losses import Loss
from warp_spt.rendering.film import Film
from warp_spt.rendering.settings import RenderSettings, check_args
from warp_spt.rendering.tiles import render_scene
from warp_spt.runtime.threads import run_jobs
from warp_spt.samplers import DEFAULT_SAMPLER, get_sampler
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

MAX_UNROLLED_DEPTH = 8     # compile time grows quickly with the unrolled depth
MODES = ("auto", "prb", "tape")
# Parameters path replay differentiates (it holds sampled directions fixed and finds hits outside
# the differentiated vertex, see warp_spt.diff.prb); the others (fuzz bends directions, the camera moves
# rays and hit points) need the tape's pathwise derivative.
REPLAYABLE = {("material", f) for f in MATERIAL_FIELDS if f != "fuzz"} | {("texture", "texels")}


def replayable(p: ParamInfo) -> bool:
    """Path replay differentiates ``p`` (every procedural-texture parameter and every light's: they
    are read at the vertex)."""
    return p.kind == "proc" or p.kind in PARAMETER_KINDS or (p.kind, p.field) in REPLAYABLE


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


_kernels: dict[tuple[str, str, Features, int], wp.Kernel] = {}
_ADJ = wp.Tape()     # used only for get_adjoint (building adjoint structs); it never records


def get_diff_kernel(features: Features, depth: int, integrator: str = "seed", sampler: str = "independent",
                    device: str = "cpu") -> wp.Kernel:
    """The differentiable kernel (forward and adjoint) for these features, unrolled to ``depth``."""
    check_integrator(integrator)
    key = (integrator, sampler, features, depth)
    if key not in _kernels:
        _kernels[key] = _make_kernel(*get_step(integrator, sampler, features, differentiable=True), depth)
    k = _kernels[key]
    wp.load_module(k.module, device=device)      # on this thread, before any worker launches it
    return k


def _check_estimator(integrator: str, sampler: str) -> None:
    """Refuse the (integrator, sampler) pairs whose gradients disagree with finite differences: none
    now. NEE with the independent sampler was refused (gradients off by up to 4x) until the cause
    was found: ``nee``'s vertex updated the path's struct in place after passing it to ``direct``,
    whose adjoint then replayed the light sample with the updated sampler state (the Sobol' state
    does not change, so it was exact); the vertex now updates a copy (docs/gradients.md, NEE)."""
    check_integrator(integrator)
    get_sampler(sampler)


def _check_depth(max_depth: int) -> None:
    if not 1 <= max_depth <= MAX_UNROLLED_DEPTH:
        raise ValueError(f"max_depth must be in [1, {MAX_UNROLLED_DEPTH}] for differentiable renders "
                         f"through the tape (path replay, mode='prb', has no limit)")


def choose_mode(mode: str, infos: list[ParamInfo], integrator: str) -> str:
    """"prb" or "tape" for these parameters: "auto" takes path replay when it covers them all."""
    if mode not in MODES:
        raise ValueError(f"unknown gradient mode {mode!r}; choose from {', '.join(MODES)}")
    pathwise = [p.name for p in infos if not replayable(p)]
    ok = not pathwise and integrator in VERTICES
    if mode == "auto":
        return "prb" if ok else "tape"
    if mode == "prb" and not ok:
        why = (f"{', '.join(pathwise)} need(s) the pathwise derivative of the tape" if pathwise
               else f"integrator {integrator!r} has no vertex function")
        raise ValueError(f"path replay cannot differentiate this: {why}; use mode='tape' or 'auto'")
    return mode


def _render_params(width: int, lo: int, s0: int, spp: int, max_depth: int, seed: int,
                   roulette_depth: int = 0) -> RenderParams:
    rp = RenderParams()
    rp.width, rp.pixel_start, rp.sample_start, rp.sample_count = width, lo, s0, spp
    rp.max_depth, rp.roulette_depth, rp.seed = max_depth, roulette_depth, wp.uint32(seed & 0xFFFFFFFF)
    return rp


# ------------------------------------------------------------------------------------------------
# The user-facing call: named gradients on every core


@dataclass
class GradientResult:
    """``image`` (H, W, 3) float32 linear radiance, the fast kernel's (path replay with an adjoint
    image and no ``gradient_seed`` takes it from its first pass, the same sums); ``loss`` its value
    (None when an adjoint image was given); ``grads`` d loss / d parameter by name (float64, the
    parameter's shape); ``forward_seconds`` wall-clock of the separate forward render (0 when path
    replay gave the image) and ``backward_seconds`` of the rest; ``backward_bytes`` what the
    backward pass allocated (adjoint image, per-tile gradient buffers, scratch); ``mode`` "prb" or
    "tape", the backward pass that ran."""

    image: np.ndarray
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
                     mode: str = "auto") -> GradientResult:
    """Render ``params.scene`` as seen by ``params.camera`` under ``params.sky`` and return the image
    and the gradients of ``loss(image)`` (or of sum(adjoint * image)) for the parameters named in
    ``wrt`` (default: every parameter). ``settings.sky`` is ignored (the sky is ``params.sky``).
    Russian roulette (``settings.roulette_depth``) is replayed: the same samples survive, and the
    survival probability is held constant, which keeps the gradient unbiased (docs/gradients.md).

    ``mode``: "prb" (path replay, ``warp_spt.diff.prb``: any depth, about the cost of two forward
    passes), "tape" (Warp's adjoint of the step unrolled to ``max_depth`` <= MAX_UNROLLED_DEPTH; it
    alone has the pathwise derivatives of fuzz and the camera), or "auto": "prb" unless a parameter
    in ``wrt`` needs the tape.

    ``gradient_seed``: replay the backward pass with this seed instead of ``settings.seed``. A loss
    that is not linear in the image (L2) then gets an unbiased gradient of the *expected* image's loss:
    with the same seed, the image's noise and its derivative are correlated and the gradient of
    E[(I - T)^2] is biased (inverse rendering at low spp converges to the wrong value).
    """
    rs = settings or RenderSettings(width=64, height=64, spp=4, max_depth=4)
    if (loss is None) == (adjoint is None):
        raise ValueError("give exactly one of loss= and adjoint=")
    names = list(params.differentiable() if wrt is None else wrt)
    infos = [params.info(n) for n in names]
    mode = choose_mode(mode, infos, rs.integrator)
    _check_estimator(rs.integrator, rs.sampler)
    if mode == "tape":
        _check_depth(rs.max_depth)
    dev, sky, camera = params.scene, params.sky, params.camera
    rs = replace(rs, sky=sky, features=None)
    # path replay's first pass traces the very paths of the forward render: when the adjoint is known
    # before the image (no loss) and the seeds are the same, its radiance sums are the image
    replay_image = mode == "prb" and loss is None and gradient_seed is None
    image, value, forward_seconds = None, None, 0.0
    shape = (rs.height, rs.width, 3)
    if replay_image:
        check_args(rs)
        camera.validate(rs.width, rs.height)
        adj = adjoint
    else:
        t0 = time.perf_counter()
        image = render_scene(dev, camera, rs).image
        forward_seconds = time.perf_counter() - t0
        value, adj = loss(image) if loss is not None else (None, adjoint)
    adj = np.asarray(adj, dtype=np.float32)
    if adj.shape != shape or not np.all(np.isfinite(adj)):
        raise ValueError(f"the adjoint image must be finite with shape {shape}, got {adj.shape}")

    t0 = time.perf_counter()
    brs = rs if gradient_seed is None else replace(rs, seed=gradient_seed)
    bw = _Backward(dev, camera, sky, brs, wants={p.kind for p in infos}, mode=mode)
    sums = bw.run(adj.reshape(-1, 3), rs.threads, want_image=replay_image)
    if replay_image:
        image = Film(sums.pop("film").reshape(shape), rs.spp).image()
    backward_seconds = time.perf_counter() - t0
    grads = {p.name: _pick(p, sums, dev, camera, rs) for p in infos}
    return GradientResult(image, value, grads, forward_seconds, backward_seconds, bw.nbytes, len(bw.tiles),
                          bw.threads, mode)


class _Backward:
    """One backward pass: per-tile gradient buffers, adjoint launches from a pool, ordered reduction."""

    def __init__(self, dev: DeviceScene, camera: Camera, sky: Sky, rs: RenderSettings, wants: set,
                 mode: str = "tape"):
        self.dev, self.rs, self.mode = dev, rs, mode
        feats = replace(dev.features, sky=sky_emits(sky))
        if mode == "prb":
            self.kernel = get_replay_kernel(feats, rs.integrator, rs.sampler, dev.device)
        else:
            self.kernel = get_diff_kernel(feats, rs.max_depth, rs.integrator, rs.sampler, dev.device)
        self.cam = camera_params(camera, rs.width, rs.height)
        self.lights = light_table(dev, sky, camera.up)
        self.tex = dev.textures(rs.texture_filter)
        self.wants_texels = "texture" in wants
        self.wants_proc = "proc" in wants
        n = rs.width * rs.height
        self.tiles = [(p, min(n, p + rs.tile_pixels)) for p in range(0, n, rs.tile_pixels)]
        self.nbytes = 0
        self.threads = 1

    def _grad_alias(self, a: wp.array) -> wp.array:
        """``a``'s data with a fresh zeroed gradient buffer of this tile."""
        g = wp.zeros(a.shape, dtype=a.dtype, device=a.device)
        self.nbytes += g.capacity
        return wp.array(ptr=a.ptr, dtype=a.dtype, shape=a.shape, device=a.device, grad=g)

    def _tile_inputs(self, lo: int, hi: int) -> tuple:
        m = Materials()
        for name in ("tex", "ior", "refractable") + MATERIAL_FIELDS:
            a = getattr(self.dev.materials, name)
            setattr(m, name, self._grad_alias(a) if name in MATERIAL_FIELDS else a)
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
        lights = alias_parameters(self.lights, self._grad_alias)     # the sky's colours, as m's
        return m, t, lights, deltas, scratch

    def run(self, adj: np.ndarray, threads: int | None, want_image: bool = False) -> dict:
        """The reduced gradient buffers by name; with ``want_image`` (path replay only) also
        ``"film"``, the radiance sums of pass 1 (H*W, 3) float64."""
        rs, dev = self.rs, self.dev
        adj_image = wp.array(adj, dtype=wp.vec3, device=dev.device)
        self.nbytes += adj_image.capacity
        film = wp.zeros(len(adj) if want_image else 1, dtype=wp.vec3d, device=dev.device)
        inputs = [self._tile_inputs(lo, hi) for lo, hi in self.tiles]

        def work(k: int) -> None:
            lo, hi = self.tiles[k]
            m, t, lights, deltas, scratch = inputs[k]
            rp = _render_params(rs.width, lo, rs.sample_offset, rs.spp, rs.max_depth, rs.seed, rs.roulette_depth)
            if self.mode == "prb":       # a forward launch: the replay kernel accumulates the adjoints
                wp.launch(self.kernel, dim=hi - lo, device=dev.device, inputs=[
                    dev.geometry, m, t, lights, self.cam, rp, adj_image[lo:hi],
                    int(want_image), film[lo:hi] if want_image else film])
                return
            args = [dev.geometry, m, t, lights, self.cam, rp, deltas, scratch]
            adj_structs = [_ADJ.get_adjoint(a) for a in args[:6]]   # mirrors holding each array's .grad
            wp.launch(self.kernel, dim=hi - lo, device=dev.device, inputs=args,
                      adj_inputs=adj_structs + [deltas.grad, adj_image[lo:hi]], adjoint=True)

        self.threads = max(1, min(threads or os.cpu_count() or 1, len(self.tiles)))
        # the renderer's tile runner: Ctrl-C stops the workers safely (no concurrent.futures, see parallel)
        run_jobs(list(range(len(self.tiles))), lambda k, stop, done: work(k), self.threads, lambda units: None)
        # reduce in tile order, in float64: independent of threads
        sums: dict = {}
        for m, t, lights, deltas, _ in inputs:
            parts = {f: getattr(m, f).grad for f in MATERIAL_FIELDS}
            parts.update({kind: a.grad for kind, a in parameter_arrays(lights).items()})
            parts["deltas"] = deltas.grad
            if self.wants_texels:
                parts["texels"] = t.texels.grad
            if self.wants_proc:
                parts["proc"] = t.proc_params.grad
            for key, g in parts.items():
                v = g.numpy().astype(np.float64)
                sums[key] = sums[key] + v if key in sums else v
        if want_image:
            sums["film"] = film.numpy()
        return sums


def _pick(p, sums: dict, dev: DeviceScene, camera: Camera, rs: RenderSettings) -> np.ndarray:
    """The gradient of one named parameter from the reduced buffers."""
    if p.kind == "camera":       # chain rule through the host's image-plane frame (float64)
        jac = camera_jacobian(camera, p.field, rs.width, rs.height)
        return np.einsum("fi,fij->j", sums["deltas"][D_CAM:D_CAM + len(CAMERA_FIELDS)], jac)
    if p.kind == "material":
        g = sums[p.field][p.index]
        return np.asarray(g, dtype=np.float64).reshape(p.shape)
    if p.kind == "texture":
        return tile_view(sums["texels"], dev._atlas[1].numpy()[p.index]).copy()
    if p.kind == "proc":
        off, size = proc_slice(dev.scene, p)
        return sums["proc"][p.index][off:off + size].reshape(p.shape).copy()
    if p.kind in PARAMETER_KINDS:            # a light's parameter (the sky's colours): a row of its array
        return sums[p.kind][p.index].copy()
    raise ValueError(f"no gradient buffer holds {p.name}")


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
                          seed: int = 0, texture_filter: str = "nearest", integrator: str = "seed",
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
    sky = sky or Sky.black()
    camera = camera or Camera()
    feats = replace(scene.features, sky=sky_emits(sky))
    kernel = get_diff_kernel(feats, max_depth, integrator, sampler, scene.device)
    rp = _render_params(width, 0, 0, spp, max_depth, seed)
    image = wp.zeros(width * height, dtype=wp.vec3, device=scene.device, requires_grad=True)
    deltas = wp.zeros(NUM_DELTAS, dtype=wp.vec3, device=scene.device)
    tape = wp.Tape()
    with tape:
        wp.launch(kernel, dim=width * height, device=scene.device, inputs=[
            scene.geometry, scene.materials, scene.textures(texture_filter), light_table(scene, sky, camera.up),
            camera_params(camera, width, height), rp, deltas, image])
    return DiffRender(image, tape, width, height)
