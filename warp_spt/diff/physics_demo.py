"""Physics to pixels on one tape: a thrown ball's launch velocity recovered from a strobe photograph.

``examples/physics_to_pixels.py`` runs it and ``notebooks/physics_to_pixels.ipynb`` at its quick size;
it lives in the package so that the notebook finds it wherever Jupyter starts its kernel. The
simulation is ordinary user code written with Warp (the kernels below), which is the point: nothing in
it knows about the renderer, and the renderer knows nothing of it.

The simulation: a ball thrown from ``START`` with velocity ``v0`` under gravity, stepped at ``DT``,
bouncing on the floor with restitution ``RESTITUTION`` at its time of impact inside a step (``step``
says why). Every state is its own row of one array, so that the tape can run the steps backwards.

The photograph: the ball at ``len(FRAMES)`` instants, each an analytic sphere ``sphere<k>`` of the
scene, over a grey floor under a gradient sky, as one image. Each iteration simulates, hands the
balls' centres (views into the state array) to :func:`warp_spt.render_arrays` on the same tape,
computes a multi-scale L2 loss (``image_loss``) against the target in Warp kernels and runs ``tape.backward``: the gradient
reaches ``v0`` through the render (interior and silhouette terms, and the balls' contact shadows) and
through every simulation step. Adam on the three numbers of ``v0``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np
import warp as wp

from warp_spt.diff.interop import render_arrays
from warp_spt.diff.inverse_demo import OptimisationRun
from warp_spt.diff.params import parameters
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene
from warp_spt.scene.camera import Camera
from warp_spt.scene.model import CHECKER_NAME, Material, MaterialTable, MeshData, Scene
from warp_spt.scene.sky import Sky

RADIUS = 0.15
START = (-1.2, 0.0, 0.6)
TRUE_V0 = (2.0, 0.3, 2.5)                    # m/s: the apex at 0.25 s, the bounce at about 0.65 s
START_V0 = (1.4, -0.3, 3.2)                  # where the optimiser starts: 1.10 m/s off
GRAVITY = (0.0, 0.0, -9.81)
DT = 1.0 / 120.0                             # exact flight: the step only picks the instants
RESTITUTION = 0.7
FRAMES = (24, 48, 72, 96, 120)               # the strobe's instants, in steps: 0.2 s apart
CAMERA = Camera(position=(0.0, -4.0, 2.2), direction=(0.0, 4.0, -1.8), fov=42.0, aperture=0.0, focus=4.4,
                up=(0.0, 0.0, 1.0))
SKY = Sky.gradient(zenith=(0.45, 0.6, 0.95), nadir=(0.95, 0.9, 0.8))
BALL, FLOOR = 1, 2


@wp.kernel
def step(x: wp.array(dtype=wp.vec3), v: wp.array(dtype=wp.vec3), i: int, dt: float, gravity: wp.vec3,
         radius: float, restitution: float):
    """State i to state i + 1: the ball's flight, exact under constant gravity, and a bounce on the
    floor (z = 0) at its time of impact inside the step, found by solving for it: the state is then a
    smooth function of the launch velocity. (Contact by a stiff spring stepped in time is not: where
    in a step the ball first touches changes its rebound, and the state's pointwise derivative, what
    a tape gives, differs from the derivative of its trend by up to 2.5x at 1/1200 s steps.)"""
    p, u = x[i], v[i]
    a, b = 0.5 * gravity[2], u[2]
    c = wp.max(p[2] - radius, 0.0)                  # height above touching; a < 0
    if c + b * dt + a * dt * dt < 0.0:              # it touches in this step: at the root of c + b t + a t^2
        t = 2.0 * c / (wp.sqrt(b * b - 4.0 * a * c) - b)
        q = p + u * t + 0.5 * gravity * t * t
        w = u + gravity * t
        w = wp.vec3(w[0], w[1], -restitution * w[2])
        r = dt - t
        v[i + 1] = w + gravity * r
        x[i + 1] = q + w * r + 0.5 * gravity * r * r
    else:
        v[i + 1] = u + gravity * dt
        x[i + 1] = p + u * dt + 0.5 * gravity * dt * dt


@wp.kernel
def box_blur(image: wp.array(dtype=float, ndim=3), target: wp.array(dtype=float, ndim=3), radius: int,
             out: wp.array(dtype=float, ndim=3)):
    """``out`` += the box blur of (image - target), the box (2 radius + 1) pixels wide, one window
    offset ``k`` per thread. Atomic adds rather than a sum in a loop: Warp's adjoint drops a local
    variable carried through a dynamic loop."""
    p, k, c = wp.tid()
    h, w = image.shape[0], image.shape[1]
    n = 2 * radius + 1
    y, x = p / w, p % w
    j, i = y + k / n - radius, x + k % n - radius
    if j >= 0 and j < h and i >= 0 and i < w:
        wp.atomic_add(out, y, x, c, (image[j, i, c] - target[j, i, c]) / float(n * n))


@wp.kernel
def mean_square(blurred: wp.array(dtype=float, ndim=3), weight: float, loss: wp.array(dtype=float)):
    y, x, c = wp.tid()
    d = blurred[y, x, c]
    wp.atomic_add(loss, 0, weight * d * d / float(blurred.shape[0] * blurred.shape[1]))


# (box radius in pixels at the quick size's 48 pixels across, weight): coarse to fine
LOSS_SCALES = ((6, 4.0), (2, 2.0), (0, 1.0))


def image_loss(image: wp.array, target: wp.array, loss: wp.array) -> None:
    """The multi-scale loss the optimisation minimises (on the tape if one records): at each scale
    the mean over pixels of |box blur of (image - target)|^2 times its weight. The wide boxes give a
    ball that does not yet overlap its target a gradient towards it: under plain L2 a silhouette
    feels the target only where the two overlap."""
    h, w = image.shape[0], image.shape[1]
    for radius, weight in LOSS_SCALES:
        r = int(round(radius * w / 48.0))
        blurred = wp.zeros(image.shape, dtype=float, device=image.device, requires_grad=True)
        wp.launch(box_blur, dim=(h * w, (2 * r + 1) ** 2, 3), inputs=[image, target, r], outputs=[blurred],
                  device=image.device)
        wp.launch(mean_square, dim=image.shape, inputs=[blurred, weight], outputs=[loss], device=image.device)


def simulate(v0: wp.array, steps: int = FRAMES[-1]) -> wp.array:
    """The ball's positions (steps + 1,) vec3 from launch velocity ``v0`` (1,) vec3 (on the tape if
    one records: every launch reads one row and writes the next)."""
    x = wp.zeros(steps + 1, dtype=wp.vec3, device=v0.device, requires_grad=v0.requires_grad)
    v = wp.zeros(steps + 1, dtype=wp.vec3, device=v0.device, requires_grad=v0.requires_grad)
    wp.copy(v, v0, count=1)
    x.assign(np.broadcast_to(np.asarray(START, np.float32), (steps + 1, 3)))   # row 0 is the start
    for i in range(steps):
        wp.launch(step, dim=1, inputs=[x, v, i, DT, wp.vec3(*GRAVITY), RADIUS, RESTITUTION],
                  device=v0.device)
    return x


def scene() -> Scene:
    """The floor (a 12 m square at z = 0) and one sphere per strobe frame (placed by the simulation)."""
    h = 6.0
    floor = MeshData("floor", np.array([(-h, -h, 0.0), (h, -h, 0.0), (h, h, 0.0), (-h, h, 0.0)]),
                     np.array([(0, 1, 2), (0, 2, 3)], np.int32), np.zeros((2, 3, 2), np.float32), None,
                     np.full(2, FLOOR, np.int32))
    mats = MaterialTable.from_rows([Material(CHECKER_NAME),
                                    Material("ball", diffuse=(0.85, 0.25, 0.1), roughness=1.0),
                                    Material("floor", diffuse=(0.6, 0.6, 0.6), roughness=1.0)])
    spheres = np.array([[0.0, 3.0 * k, RADIUS + 10.0, RADIUS] for k in range(len(FRAMES))])   # until set
    return Scene(meshes=[floor], spheres=spheres, sphere_material=np.full(len(FRAMES), BALL, np.int32),
                 materials=mats, textures=[], seed_dialect=False)


def settings(quick: bool) -> RenderSettings:
    w, h, spp = (48, 32, 4) if quick else (96, 64, 8)
    return RenderSettings(width=w, height=h, spp=spp, max_depth=2, integrator="seed", tile_pixels=w * h)


def centres(x: wp.array) -> dict:
    """The strobe frames' states as the spheres' centres: views into ``x`` (their ``.grad`` too)."""
    return {f"sphere{k}.center": x[f:f + 1] for k, f in enumerate(FRAMES)}


def photograph(params, v0, rs: RenderSettings, seed: int, **kw) -> wp.array:
    """Simulate from ``v0`` (a (3,) sequence or a (1,) vec3 array) and render the strobe image."""
    a = v0 if isinstance(v0, wp.array) else wp.array([v0], dtype=wp.vec3)
    return render_arrays(params, centres(simulate(a)), replace(rs, seed=seed), **kw)


def loss_and_gradient(params, v0: np.ndarray, target: wp.array, rs: RenderSettings, seed: int,
                      gradient_seed: int, **kw) -> tuple[float, np.ndarray]:
    """The loss of the strobe image from ``v0`` against ``target`` and its gradient in ``v0``, by one
    ``tape.backward`` through the loss kernels, the render and every simulation step (``kw``: the
    gradient's budgets and terms, as :func:`render_gradients` takes them)."""
    v = wp.array([v0], dtype=wp.vec3, requires_grad=True)
    loss = wp.zeros(1, dtype=float, requires_grad=True)
    tape = wp.Tape()
    with tape:
        image = photograph(params, v, rs, seed, gradient_seed=gradient_seed, **kw)
        image_loss(image, target, loss)
    tape.backward(loss)
    return float(loss.numpy()[0]), v.grad.numpy()[0].astype(np.float64)


def loss_of(params, v0, target: wp.array, rs: RenderSettings, seed: int) -> float:
    """The same loss, forward only (no tape): what finite differences take."""
    loss = wp.zeros(1, dtype=float)
    image_loss(photograph(params, v0, rs, seed), target, loss)
    return float(loss.numpy()[0])


@dataclass
class Throw(OptimisationRun):
    """The recovered launch velocity (the mean of the last fifth of the iterates) beside the run's record."""

    v0: np.ndarray = None

    @property
    def error(self) -> float:
        return velocity_error(self.v0)


def velocity_error(v0) -> float:
    """|v0 - TRUE_V0| in m/s."""
    return float(np.linalg.norm(np.asarray(v0, np.float64) - TRUE_V0))


def recover(quick: bool = False, seed: int = 0, log=None, boundary: bool = True) -> Throw:
    """Adam on ``v0`` from START_V0, the step size decaying (``quick``: 48x32 pixels, 4 spp, 60
    iterations; else 96x64, 8 spp, 120); ``log(iteration, loss, error)`` after each step; ``boundary``
    False leaves the boundary terms out (the control of docs/gradients.md)."""
    rs = settings(quick)
    iterations, lr, decay = (60, 0.1, 0.96) if quick else (120, 0.1, 0.98)
    params = parameters(scene(), CAMERA, SKY)
    target_np = photograph(params, TRUE_V0, replace(rs, spp=16 * rs.spp), 10_000 + seed).numpy()
    target = wp.array(target_np, dtype=float)
    start_image = photograph(params, START_V0, replace(rs, spp=16 * rs.spp), 1).numpy()
    v = np.array(START_V0, np.float64)
    m, s = np.zeros(3), np.zeros(3)
    b1, b2 = 0.9, 0.999
    errors, losses, tail = [], [], []
    t0 = time.perf_counter()
    for it in range(iterations):
        value, g = loss_and_gradient(params, v, target, rs, 1000 * seed + 2 * it, 1000 * seed + 2 * it + 1,
                                     boundary=boundary)
        m = b1 * m + (1 - b1) * g
        s = b2 * s + (1 - b2) * g * g
        v = v - lr * decay ** it * (m / (1 - b1 ** (it + 1))) / (np.sqrt(s / (1 - b2 ** (it + 1))) + 1e-8)
        losses.append(value)
        errors.append(velocity_error(v))
        if log is not None:
            log(it, value, errors[-1])
        if it >= iterations - iterations // 5:
            tail.append(v.copy())
    seconds = (time.perf_counter() - t0) / iterations
    v = np.mean(tail, axis=0)
    final = photograph(params, v, replace(rs, spp=16 * rs.spp), 1).numpy()
    return Throw(velocity_error(START_V0), errors, losses, seconds, target_np, start_image, final, v0=v)


def figure(run: Throw, scale: int = 3):
    """The start, the result and the target side by side over the error curve (log10), as a PIL image."""
    return run.strip("|v0 - v0_true| m/s", scale)
