"""A render on the user's own ``wp.Tape``: scene parameters from ``wp.array``\\ s, the image as a ``wp.array``.

    tape = wp.Tape()
    with tape:
        centre = simulate(v0)                                   # the user's kernels
        image = warp_spt.render_arrays(params, {"sphere0.center": centre}, settings)
        loss = my_loss(image)                                   # the user's kernels
    tape.backward(loss)                                         # v0.grad: through render and simulation

:func:`render_arrays` sets each named parameter (``params.names()``) from its array's current value,
renders, and returns the image (H, W, 3) float32 on the scene's device with ``requires_grad``. When a
tape is recording it records one backward function on it: when ``tape.backward`` reaches it,
``image.grad`` is the loss's adjoint image, and :func:`warp_spt.diff.gradients.render_gradients` turns it
into each parameter's gradient, added into its array's ``.grad`` (so a tape that continues from there
takes it into the user's kernels). Several renders may be recorded on one tape (views, time steps): each
keeps the parameter values, camera and sky it rendered with and puts them back before its backward pass
if they changed since.

Why a recorded function and not the render's kernels on the tape: the renderer launches from a pool of
threads into per-tile buffers (bit-exact over thread counts), rebuilds BVHs when geometry moves and adds
boundary terms no kernel adjoint gives; Warp's tape is one process-wide global in Warp 1.19, so the
render's own launches are kept off it (``_tape_off``) and its backward is one function.

The backward renders with its own seed (``gradient_seed``, default ``settings.seed + GRADIENT_SEED_OFFSET``):
the user's loss of a noisy image is usually not linear in it (L2), and an adjoint from the same paths as
its derivative gives a biased gradient (docs/gradients.md, "gradient_seed").

What is copied: on the CPU device a ``wp.array``'s ``numpy()`` is a view, so the inputs cost no copy;
the image is one (H, W, 3) float32 array; each gradient is added through the host (one parameter-sized
copy each way). A change of geometry rebuilds the changed mesh's BVH and the top-level BVH, as
``params[name] = value`` does (``benchmarks/bench_gradients.py --only interop`` measures the overhead).
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass, replace

import numpy as np
import warp as wp

from warp_spt.diff.params import SceneParameters
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene

# distinct from the forward seeds of neighbouring iterations that count seeds up by one
GRADIENT_SEED_OFFSET = 1_000_003


@contextlib.contextmanager
def _tape_off():
    """No tape records while the renderer launches (its kernels are not the user's computation)."""
    runtime = wp._src.context.runtime     # Warp 1.19 keeps the recording tape here and only here
    tape, runtime.tape = runtime.tape, None
    try:
        yield tape
    finally:
        runtime.tape = tape


def recording_tape():
    """The ``wp.Tape`` recording now, or None."""
    wp.init()
    return wp._src.context.runtime.tape


def _value_of(params: SceneParameters, name: str, a) -> np.ndarray:
    """The parameter's new value from array ``a`` (any shape with the parameter's number of elements)."""
    if not isinstance(a, wp.array):
        raise TypeError(f"{name}: expected a wp.array, got {type(a).__name__}")
    shape = params.info(name).shape
    v = a.numpy()
    if v.size != int(np.prod(shape, dtype=np.int64)):
        raise ValueError(f"{name}: expected {int(np.prod(shape))} numbers (shape {shape}), "
                         f"the array has shape {tuple(a.shape)} of {a.dtype.__name__}")
    return v.astype(np.float64).reshape(shape)


@dataclass
class _Recorded:
    """What one render rendered with, for its backward pass."""

    params: SceneParameters
    inputs: dict
    values: dict
    camera: object
    sky: object
    settings: RenderSettings
    image: wp.array
    gradient_kwargs: dict

    def restore(self) -> None:
        """Put back the values this render saw where later renders changed them."""
        p = self.params
        p.camera, p.sky = self.camera, self.sky
        for n, v in self.values.items():
            if not np.array_equal(p[n], v.astype(np.float32)):     # params[n] reads float32
                p[n] = v

    def backward(self) -> None:
        from warp_spt.diff.gradients import render_gradients

        with _tape_off():
            self.restore()
            adj = self.image.grad.numpy()
            r = render_gradients(self.params, self.settings, adjoint=adj, wrt=list(self.inputs),
                                 image=False, **self.gradient_kwargs)
        for n, a in self.inputs.items():
            if a.grad is None:
                continue
            g = a.grad.numpy()
            a.grad.assign((g + r.grads[n].reshape(g.shape)).astype(g.dtype))


def render_arrays(params: SceneParameters, inputs: dict, settings: RenderSettings | None = None, *,
                  gradient_seed: int | None = None, tape=None, **gradient_kwargs) -> wp.array:
    """Set ``params[name]`` from each ``inputs[name]`` (a ``wp.array`` with the parameter's number of
    elements, e.g. (V, 3) floats or (V,) vec3 for ``"<mesh>.positions"``, (3,) for a sphere's centre),
    render ``params.scene`` as ``params.camera`` sees it under ``params.sky``, and return the image (H,
    W, 3) float32 on the scene's device, with a ``.grad``.

    ``tape``: the tape to record the backward pass on (default: the one recording now, if any). Its
    ``backward`` then adds d loss / d parameter into ``inputs[name].grad`` for every input that has a
    ``.grad``. ``gradient_seed`` and the remaining keywords (``boundary``, ``boundary_spp``,
    ``secondary_spp``, ``secondary_depth``, ``mode``) go to :func:`render_gradients`.
    """
    rs = settings or RenderSettings(width=64, height=64, spp=4, max_depth=4)
    if not isinstance(params, SceneParameters):
        raise TypeError(f"params must be warp_spt.parameters(...), got {type(params).__name__}")
    if not isinstance(inputs, dict) or not inputs:
        raise TypeError("inputs must be a non-empty dict of parameter name -> wp.array")
    unknown = [n for n in inputs if n not in params]
    if unknown:
        raise KeyError(f"no parameter {unknown[0]!r}; parameters are: {', '.join(params.names())}")
    bad = {"loss", "adjoint", "wrt", "image"} & set(gradient_kwargs)
    if bad:
        raise TypeError(f"render_arrays takes no {sorted(bad)[0]}=: the loss is the tape's")
    with _tape_off() as active:
        values = {n: _value_of(params, n, a) for n, a in inputs.items()}
        for n, v in values.items():
            params[n] = v
        image = render_scene(params.scene, params.camera, replace(rs, sky=params.sky)).image
    out = wp.array(np.ascontiguousarray(image, dtype=np.float32), dtype=wp.float32,
                   device=params.scene.device, requires_grad=True)
    tape = tape if tape is not None else active
    if tape is not None:
        seed = rs.seed + GRADIENT_SEED_OFFSET if gradient_seed is None else gradient_seed
        rec = _Recorded(params, dict(inputs), values, params.camera, params.sky, rs,
                        out, dict(gradient_kwargs, gradient_seed=seed))
        tape.record_func(rec.backward, [a for a in inputs.values() if a.grad is not None] + [out])
    return out
