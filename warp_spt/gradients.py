"""Differentiable rendering: gradients of an image (or of a loss on it) with respect to named parameters.

Differentiation is a mode of the same integrator, not a copy of it: the kernel here runs the very
``step`` function of the fast kernel (``warp_spt.integrators``), in a loop unrolled to a fixed depth
with the path's ``alive`` flag instead of a dynamic loop, because Warp differentiates a dynamic loop
correctly only when the carried state is additive (a ``break`` silently zeroes gradients).

:func:`render_gradients` is the user-facing call. It renders the image with the fast kernel on every
core, evaluates the loss (``warp_spt.losses``) or takes an adjoint image, then launches the
*adjoint* of the differentiable kernel directly (no ``wp.Tape``: the tape is one global in Warp
1.19, so it cannot be shared by threads) over tiles from a thread pool. Warp's adjoint kernel replays
each path in registers with the same random numbers and accumulates into the parameters' gradient
arrays, so nothing is stored per bounce or per sample: the backward pass allocates the adjoint image
and one gradient buffer per tile, whatever the spp and depth (``GradientResult.backward_bytes``).
Each tile has its own buffers, summed in tile order in float64, so the gradients are bit-identical
whatever the number of threads.

What is differentiated (see docs/gradients.md): material colours and emission (exact: paths do not
depend on them), texture texels (nearest and bilinear), ``Roughness`` (the lobe choice is discrete:
``materials.lobe_weight`` adds the score term so the *expected* derivative is right), ``Fuzz``, the
constant sky colour, the camera's position and direction (through shading: the kernel here
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

from .camera import Camera
from .device_scene import DeviceScene, Features, Geometry, Materials, Textures
from .integrators import CameraParams, RenderParams, camera_params, check_integrator, get_step
from .lights import Lights, light_table, sky_emits
from .losses import Loss
from .parallel import run_jobs
from .params import CAMERA_FIELDS, COLOR_FIELDS, MATERIAL_FIELDS, SceneParameters, camera_jacobian, proc_slice
from .renderer import RenderSettings, render_scene
from .samplers import DEFAULT_SAMPLER, get_sampler
from .sky import Sky

MAX_UNROLLED_DEPTH = 8     # compile time grows quickly with the unrolled depth
# deltas[k] shift values passed by value in structs (the sky colour, the camera's frame); zero, they
# exist for their gradients
D_SKY = 0                  # constant sky colour, or the gradient sky's mean
D_SKY_SLOPE = 1            # the gradient sky's slope in z
D_CAM = 2                  # CAMERA_FIELDS, in order
NUM_DELTAS = D_CAM + len(CAMERA_FIELDS)


def _make_kernel(step, start_path, depth: int):
    @wp.kernel(module="unique")
    def trace_diff(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, cam: CameraParams,
                   rp: RenderParams, deltas: wp.array(dtype=wp.vec3), image: wp.array(dtype=wp.vec3)):
        tid = wp.tid()
        pix = rp.pixel_start + tid
        lt = lights
        lt.sky_color = lights.sky_color + deltas[D_SKY]
        lt.sky_slope = lights.sky_slope + deltas[D_SKY_SLOPE]
        c = cam                     # every field set before any call takes c (see integrators.nee.add_direct)
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
                    path = step(geo, mats, tex, lt, rp, path)
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
    """Every (integrator, sampler) pair is differentiated; only the names are checked.

    NEE with the independent sampler used to be refused (per-pixel gradients off by up to 4x): the
    bounce step wrote ``p.sampler`` in place after light sampling, and Warp's adjoint of that call
    then replayed with the advanced sampler (``integrators.nee.add_direct``, docs/gradients.md).
    """
    check_integrator(integrator)
    get_sampler(sampler)


def _check_depth(max_depth: int) -> None:
    if not 1 <= max_depth <= MAX_UNROLLED_DEPTH:
        raise ValueError(f"max_depth must be in [1, {MAX_UNROLLED_DEPTH}] for differentiable renders")


def _render_params(width: int, lo: int, s0: int, spp: int, max_depth: int, seed: int) -> RenderParams:
    rp = RenderParams()
    rp.width, rp.pixel_start, rp.sample_start, rp.sample_count = width, lo, s0, spp
    rp.max_depth, rp.roulette_depth, rp.seed = max_depth, 0, wp.uint32(seed & 0xFFFFFFFF)
    return rp


# ------------------------------------------------------------------------------------------------
# The user-facing call: named gradients on every core


@dataclass
class GradientResult:
    """``image`` (H, W, 3) float32 linear radiance from the fast kernel; ``loss`` its value (None when
    an adjoint image was given); ``grads`` d loss / d parameter by name (float64, the parameter's
    shape); ``backward_seconds`` and ``forward_seconds`` wall-clock; ``backward_bytes`` what the
    backward pass allocated (adjoint image, per-tile gradient buffers, scratch)."""

    image: np.ndarray
    loss: float | None
    grads: dict[str, np.ndarray]
    forward_seconds: float
    backward_seconds: float
    backward_bytes: int
    tiles: int
    threads: int


def render_gradients(params: SceneParameters, settings: RenderSettings | None = None, *,
                     loss: Loss | None = None, adjoint: np.ndarray | None = None,
                     wrt: list[str] | None = None, gradient_seed: int | None = None) -> GradientResult:
    """Render ``params.scene`` as seen by ``params.camera`` under ``params.sky`` and return the image
    and the gradients of ``loss(image)`` (or of sum(adjoint * image)) for the parameters named in
    ``wrt`` (default: every parameter). ``settings.sky`` is ignored (the sky is ``params.sky``);
    Russian roulette must be off; ``max_depth`` at most MAX_UNROLLED_DEPTH.

    ``gradient_seed``: replay the backward pass with this seed instead of ``settings.seed``. A loss
    that is not linear in the image (L2) then gets an unbiased gradient of the *expected* image's loss:
    with the same seed, the image's noise and its derivative are correlated and the gradient of
    E[(I - T)^2] is biased (inverse rendering at low spp converges to the wrong value).
    """
    rs = settings or RenderSettings(width=64, height=64, spp=4, max_depth=4)
    if (loss is None) == (adjoint is None):
        raise ValueError("give exactly one of loss= and adjoint=")
    _check_depth(rs.max_depth)
    if rs.roulette_depth != 0:
        raise ValueError("Russian roulette is not differentiated: use roulette_depth=0")
    _check_estimator(rs.integrator, rs.sampler)
    names = list(params.differentiable() if wrt is None else wrt)
    infos = [params.info(n) for n in names]
    dev, sky, camera = params.scene, params.sky, params.camera
    rs = replace(rs, sky=sky, features=None)
    t0 = time.perf_counter()
    fwd = render_scene(dev, camera, rs)
    image = fwd.image
    forward_seconds = time.perf_counter() - t0
    value = None
    if loss is not None:
        value, adj = loss(image)
    else:
        adj = adjoint
    adj = np.asarray(adj, dtype=np.float32)
    if adj.shape != image.shape or not np.all(np.isfinite(adj)):
        raise ValueError(f"the adjoint image must be finite with shape {image.shape}, got {adj.shape}")

    t0 = time.perf_counter()
    brs = rs if gradient_seed is None else replace(rs, seed=gradient_seed)
    bw = _Backward(dev, camera, sky, brs, wants={p.kind for p in infos})
    sums = bw.run(adj.reshape(-1, 3), rs.threads)
    backward_seconds = time.perf_counter() - t0
    grads = {p.name: _pick(p, sums, dev, camera, rs) for p in infos}
    return GradientResult(image, value, grads, forward_seconds, backward_seconds, bw.nbytes, len(bw.tiles),
                          bw.threads)


class _Backward:
    """One backward pass: per-tile gradient buffers, adjoint launches from a pool, ordered reduction."""

    def __init__(self, dev: DeviceScene, camera: Camera, sky: Sky, rs: RenderSettings, wants: set):
        self.dev, self.rs = dev, rs
        feats = replace(dev.features, sky=sky_emits(sky))
        self.kernel = get_diff_kernel(feats, rs.max_depth, rs.integrator, rs.sampler, dev.device)
        self.cam = camera_params(camera, rs.width, rs.height)
        self.lights = light_table(dev, sky)
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
        scratch = wp.zeros(hi - lo, dtype=wp.vec3, device=self.dev.device)
        self.nbytes += scratch.capacity + 2 * deltas.capacity
        return m, t, deltas, scratch

    def run(self, adj: np.ndarray, threads: int | None) -> dict:
        rs, dev = self.rs, self.dev
        adj_image = wp.array(adj, dtype=wp.vec3, device=dev.device)
        self.nbytes += adj_image.capacity
        inputs = [self._tile_inputs(lo, hi) for lo, hi in self.tiles]

        def work(k: int) -> None:
            lo, hi = self.tiles[k]
            m, t, deltas, scratch = inputs[k]
            rp = _render_params(rs.width, lo, rs.sample_offset, rs.spp, rs.max_depth, rs.seed)
            args = [dev.geometry, m, t, self.lights, self.cam, rp, deltas, scratch]
            adj_structs = [_ADJ.get_adjoint(a) for a in args[:6]]   # mirrors holding each array's .grad
            wp.launch(self.kernel, dim=hi - lo, device=dev.device, inputs=args,
                      adj_inputs=adj_structs + [deltas.grad, adj_image[lo:hi]], adjoint=True)

        self.threads = max(1, min(threads or os.cpu_count() or 1, len(self.tiles)))
        # the renderer's tile runner: Ctrl-C stops the workers safely (no concurrent.futures, see parallel)
        run_jobs(list(range(len(self.tiles))), lambda k, stop, done: work(k), self.threads, lambda units: None)
        # reduce in tile order, in float64: independent of threads
        sums: dict = {}
        for m, t, deltas, _ in inputs:
            parts = {f: getattr(m, f).grad for f in MATERIAL_FIELDS}
            parts["deltas"] = deltas.grad
            if self.wants_texels:
                parts["texels"] = t.texels.grad
            if self.wants_proc:
                parts["proc"] = t.proc_params.grad
            for key, g in parts.items():
                v = g.numpy().astype(np.float64)
                sums[key] = sums[key] + v if key in sums else v
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
        x0, y0, w, h = (int(c) for c in dev._atlas[1].numpy()[p.index])
        return sums["texels"][y0:y0 + h, x0:x0 + w].copy()
    if p.kind == "proc":
        off, size = proc_slice(dev.scene, p)
        return sums["proc"][p.index][off:off + size].reshape(p.shape).copy()
    g_mean, g_slope = sums["deltas"][D_SKY], sums["deltas"][D_SKY_SLOPE]
    if p.field == "zenith":                   # mean = (zenith + nadir) / 2, slope = (zenith - nadir) / 2
        return 0.5 * (g_mean + g_slope)
    if p.field == "nadir":
        return 0.5 * (g_mean - g_slope)
    return g_mean.copy()                      # the constant sky's colour


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
    feats = replace(scene.features, sky=sky_emits(sky))
    kernel = get_diff_kernel(feats, max_depth, integrator, sampler, scene.device)
    rp = _render_params(width, 0, 0, spp, max_depth, seed)
    image = wp.zeros(width * height, dtype=wp.vec3, device=scene.device, requires_grad=True)
    deltas = wp.zeros(NUM_DELTAS, dtype=wp.vec3, device=scene.device)
    tape = wp.Tape()
    with tape:
        wp.launch(kernel, dim=width * height, device=scene.device, inputs=[
            scene.geometry, scene.materials, scene.textures(texture_filter), light_table(scene, sky),
            camera_params(camera or Camera(), width, height), rp, deltas, image])
    return DiffRender(image, tape, width, height)
