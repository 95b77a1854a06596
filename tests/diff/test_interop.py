"""A render recorded on the user's own ``wp.Tape`` (``warp_spt.render_arrays``): parameters from
``wp.array``s written by the user's kernels, the image as a ``wp.array`` whose loss the user's kernels
compute, and ``tape.backward`` taking the gradient through the render back into the user's inputs.

The references are independent of the interop code: ``render_gradients`` called directly with the
same adjoint and seed, chained through the user's map by hand (the two must agree to float32
rounding: the same kernels, the same samples), and, for the whole chain, central differences of the
fast renderer with common random numbers, with the tolerance from both sides' standard errors.
Scenes are the geometry-gradient tests' (one feature set: no kernel of their own).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import warp as wp

import warp_spt
from warp_spt.diff.gradients import render_gradients
from warp_spt.diff.params import parameters
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene
from tests.support import geometry_scenes as gs

W = H = 16
RS = RenderSettings(width=W, height=H, spp=16, max_depth=2, seed=3, integrator="seed")
TARGET = np.random.default_rng(5).uniform(0.0, 0.6, (H, W, 3)).astype(np.float32)
CENTRE, DRIFT = np.array([0.1, 0.05, 0.0]), np.array([0.3, -0.2, 0.1])


@wp.kernel
def _drift(start: wp.array(dtype=wp.vec3), velocity: wp.array(dtype=wp.vec3), t: float,
           out: wp.array(dtype=wp.vec3)):
    """The user's 'simulation': a point moving at a constant velocity."""
    i = wp.tid()
    out[i] = start[i] + velocity[i] * t


@wp.kernel
def _l2(image: wp.array(dtype=float, ndim=3), target: wp.array(dtype=float, ndim=3), loss: wp.array(dtype=float)):
    y, x, c = wp.tid()
    d = image[y, x, c] - target[y, x, c]
    wp.atomic_add(loss, 0, d * d)


def _sphere_params():
    return parameters(gs.scene([], np.array([[*CENTRE, 0.5]]), np.array([gs.RED])), gs.CAMERA, gs.SKY)


def _pipeline(p, velocity: np.ndarray, times, seed: int, gradient_seed: int):
    """(loss, d loss / d velocity, the tape): each time's render on one tape, the L2 losses summed."""
    start = wp.array([CENTRE], dtype=wp.vec3)
    v = wp.array([velocity], dtype=wp.vec3, requires_grad=True)
    target = wp.array(TARGET, dtype=float)
    loss = wp.zeros(1, dtype=float, requires_grad=True)
    tape = wp.Tape()
    with tape:
        for k, t in enumerate(times):
            c = wp.zeros(1, dtype=wp.vec3, requires_grad=True)
            wp.launch(_drift, dim=1, inputs=[start, v, float(t)], outputs=[c])
            image = warp_spt.render_arrays(p, {"sphere0.center": c}, replace(RS, seed=seed + k),
                                           gradient_seed=gradient_seed + k)
            wp.launch(_l2, dim=image.shape, inputs=[image, target], outputs=[loss])
    tape.backward(loss)
    return float(loss.numpy()[0]), v.grad.numpy()[0].astype(np.float64), tape


def test_the_tape_carries_the_render_gradient_into_the_users_kernels():
    """One render: the velocity's gradient from ``tape.backward`` is render_gradients' centre gradient
    (same adjoint 2 (I - T), same gradient seed) times the time, as the chain rule says; the
    renderer's own launches stay off the tape (one recorded function per render)."""
    p = _sphere_params()
    t = 0.5
    loss, g_v, tape = _pipeline(p, DRIFT, [t], seed=3, gradient_seed=11)
    assert len(tape.launches) == 3          # the user's two kernels and the render's one function
    centre = CENTRE + t * DRIFT
    p["sphere0.center"] = centre
    image = render_scene(p.scene, p.camera, replace(RS, seed=3, sky=p.sky)).image
    assert loss == pytest.approx(float(np.sum((image.astype(np.float64) - TARGET) ** 2)), rel=1e-5)
    adj = (2.0 * (image - TARGET)).astype(np.float32)
    g_c = render_gradients(p, RS, adjoint=adj, wrt=["sphere0.center"], gradient_seed=11).grads["sphere0.center"]
    print("velocity gradient", g_v, "chained by hand", t * g_c)
    assert np.abs(g_c).max() > 0.1
    np.testing.assert_allclose(g_v, t * g_c, rtol=1e-4, atol=1e-5 * np.abs(g_c).max())


def test_renders_at_several_times_each_differentiate_the_values_they_rendered_with():
    """Two renders of one parameter set on one tape (two time steps): each backward pass puts back the
    centre its render saw, so the sum is the two direct gradients chained, not twice the last one's."""
    p = _sphere_params()
    times = (0.25, 1.0)
    _, g_v, _ = _pipeline(p, DRIFT, times, seed=3, gradient_seed=11)
    want = np.zeros(3)
    for k, t in enumerate(times):
        p["sphere0.center"] = CENTRE + t * DRIFT
        image = render_scene(p.scene, p.camera, replace(RS, seed=3 + k, sky=p.sky)).image
        adj = (2.0 * (image - TARGET)).astype(np.float32)
        want += t * render_gradients(p, replace(RS, seed=3 + k), adjoint=adj, wrt=["sphere0.center"],
                                     gradient_seed=11 + k).grads["sphere0.center"]
    np.testing.assert_allclose(g_v, want, rtol=1e-4, atol=1e-5 * np.abs(want).max())


def test_the_chained_gradient_matches_finite_differences_of_the_whole_pipeline():
    """d loss / d velocity_x of (drift, render, L2) against central differences of the same pipeline
    run forward (fast renderer, common random numbers), over seeds; the tolerance is four standard
    errors of the difference of the two means, and it must resolve the derivative to a fifth."""
    p = _sphere_params()
    t, h, seeds = 1.0, 0.02, 6
    u = np.array([1.0, 0.0, 0.0])
    g = [float(_pipeline(p, DRIFT, [t], seed=50 + k, gradient_seed=90 + k)[1] @ u) for k in range(seeds)]

    def loss_at(velocity, seed):
        p["sphere0.center"] = CENTRE + t * velocity
        image = render_scene(p.scene, p.camera, replace(RS, spp=256, seed=seed, sky=p.sky)).image
        return float(np.sum((image.astype(np.float64) - TARGET) ** 2))

    fd = [(loss_at(DRIFT + h * u, 200 + k) - loss_at(DRIFT - h * u, 200 + k)) / (2 * h) for k in range(seeds)]
    mg, sg = np.mean(g), np.std(g, ddof=1) / math.sqrt(seeds)
    mf, sf = np.mean(fd), np.std(fd, ddof=1) / math.sqrt(seeds)
    tol = 4.0 * math.hypot(sg, sf)
    print(f"gradient {mg:.4f} +- {sg:.4f}, finite differences {mf:.4f} +- {sf:.4f}")
    assert tol < 0.2 * abs(mf)
    assert abs(mg - mf) <= tol


def test_bad_inputs_are_named():
    p = _sphere_params()
    with pytest.raises(KeyError, match="no parameter 'sphere9.center'"):
        warp_spt.render_arrays(p, {"sphere9.center": wp.zeros(3, dtype=float)}, RS)
    with pytest.raises(ValueError, match=r"sphere0.center: expected 3 numbers"):
        warp_spt.render_arrays(p, {"sphere0.center": wp.zeros(4, dtype=float)}, RS)
    with pytest.raises(TypeError, match="expected a wp.array"):
        warp_spt.render_arrays(p, {"sphere0.center": np.zeros(3)}, RS)
    with pytest.raises(ValueError, match="sphere0.radius"):
        warp_spt.render_arrays(p, {"sphere0.radius": wp.array([-1.0], dtype=float)}, RS)
    with pytest.raises(TypeError, match="no loss="):
        warp_spt.render_arrays(p, {"sphere0.radius": wp.array([0.5], dtype=float)}, RS, loss=None)


def test_without_a_tape_it_is_a_render():
    p = _sphere_params()
    c = wp.array([[0.2, 0.0, 0.0]], dtype=float)
    image = warp_spt.render_arrays(p, {"sphere0.center": c}, RS)
    p["sphere0.center"] = (0.2, 0.0, 0.0)
    want = render_scene(p.scene, p.camera, replace(RS, sky=p.sky)).image
    assert image.shape == (H, W, 3) and image.requires_grad
    np.testing.assert_array_equal(image.numpy(), want)


def test_torch_tensors_in_and_the_gradient_back_through_autograd():
    """``render_torch``: the render as one node of torch's graph. The centre's gradient from
    ``loss.backward()`` is render_gradients' with the same adjoint and gradient seed (skips without
    torch, an optional extra: ``pip install ".[torch]"``)."""
    torch = pytest.importorskip("torch")
    from warp_spt.diff.interop import render_torch

    p = _sphere_params()
    start = torch.tensor(CENTRE, dtype=torch.float64)
    v = torch.tensor(DRIFT, dtype=torch.float64, requires_grad=True)
    image = render_torch(p, {"sphere0.center": start + 0.5 * v}, RS, gradient_seed=11)
    loss = ((image - torch.from_numpy(TARGET)) ** 2).sum()
    loss.backward()
    p["sphere0.center"] = CENTRE + 0.5 * DRIFT
    want_image = render_scene(p.scene, p.camera, replace(RS, sky=p.sky)).image
    np.testing.assert_array_equal(image.detach().numpy(), want_image)
    adj = (2.0 * (want_image - TARGET)).astype(np.float32)
    g_c = render_gradients(p, RS, adjoint=adj, wrt=["sphere0.center"], gradient_seed=11).grads["sphere0.center"]
    np.testing.assert_allclose(v.grad.numpy(), 0.5 * g_c, rtol=1e-4, atol=1e-5 * np.abs(g_c).max())
    with pytest.raises(TypeError, match="expected a torch.Tensor"):
        render_torch(p, {"sphere0.center": np.zeros(3)}, RS)
