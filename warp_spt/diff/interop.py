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

The choice of interface: recorded on the tape, so that the common case (simulate, render, loss,
``tape.backward``) is one call inside the user's ``with tape:`` block. The other way round works
too: ``render_gradients(params, settings, adjoint=...)`` returns the gradients as numpy arrays, and
``tape.backward(grads={x: wp.array(g)})`` continues from them. For PyTorch, :func:`render_torch` is the
same render as a ``torch.autograd.Function`` (torch is not a dependency; ``pip install ".[torch]"`` in the clone):
tensors in, an image tensor out, ``loss.backward()`` through it.

What is copied: on the CPU device a ``wp.array``'s ``numpy()`` is a view, so the inputs cost no copy;
the image is one (H, W, 3) float32 array; each gradient is added through the host (one parameter-sized
copy each way); on CUDA the inputs are read to the host too, since the scene's geometry is kept on
the host and rebuilt from it. A change of geometry rebuilds the changed mesh's BVH and the top-level
BVH, as ``params[name] = value`` does. An iteration costs 1.01x the same calls made directly (Cornell
box 128x128, 4 spp, its positions: ``benchmarks/bench_gradients.py --skip modes growth texels geometry``).
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
    return _reshaped(params, name, a.numpy(), f"the array has shape {tuple(a.shape)} of {a.dtype.__name__}")


def _reshaped(params: SceneParameters, name: str, v: np.ndarray, what: str) -> np.ndarray:
    """``v`` as the parameter's float64 value, refused (naming ``what`` was given) if its size differs."""
    shape = params.info(name).shape
    if v.size != int(np.prod(shape, dtype=np.int64)):
        raise ValueError(f"{name}: expected {int(np.prod(shape))} numbers (shape {shape}), {what}")
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
    image: wp.array | None
    gradient_kwargs: dict

    def restore(self) -> None:
        """Put back the values this render saw where later renders changed them."""
        p = self.params
        p.camera, p.sky = self.camera, self.sky
        for n, v in self.values.items():
            if not np.array_equal(p[n], v.astype(np.float32)):     # params[n] reads float32
                p[n] = v

    def gradients(self, adjoint: np.ndarray) -> dict:
        """d loss / d parameter by name for the adjoint image ``adjoint``, at the values rendered."""
        from warp_spt.diff.gradients import render_gradients

        with _tape_off():
            self.restore()
            return render_gradients(self.params, self.settings, adjoint=adjoint, wrt=list(self.inputs),
                                    image=False, **self.gradient_kwargs).grads

    def backward(self) -> None:
        """The tape's backward step: the image's adjoint in, each input's ``.grad`` added to."""
        grads = self.gradients(self.image.grad.numpy())
        for n, a in self.inputs.items():
            if a.grad is None:
                continue
            g = a.grad.numpy()
            a.grad.assign((g + grads[n].reshape(g.shape)).astype(g.dtype))


def _render(params: SceneParameters, values: dict, rs: RenderSettings) -> np.ndarray:
    """Set the values (float64, the parameters' shapes) and render; no tape records."""
    with _tape_off():
        for n, v in values.items():
            params[n] = v
        return render_scene(params.scene, params.camera, replace(rs, sky=params.sky)).image


def _check_call(params, inputs, gradient_kwargs, what: str) -> None:
    if not isinstance(params, SceneParameters):
        raise TypeError(f"params must be warp_spt.parameters(...), got {type(params).__name__}")
    if not isinstance(inputs, dict) or not inputs:
        raise TypeError(f"inputs must be a non-empty dict of parameter name -> {what}")
    unknown = [n for n in inputs if n not in params]
    if unknown:
        raise KeyError(f"no parameter {unknown[0]!r}; parameters are: {', '.join(params.names())}")
    bad = {"loss", "adjoint", "wrt", "image"} & set(gradient_kwargs)
    if bad:
        raise TypeError(f"no {sorted(bad)[0]}= here: the loss is the caller's")


def _seed(rs: RenderSettings, gradient_seed: int | None) -> int:
    return rs.seed + GRADIENT_SEED_OFFSET if gradient_seed is None else gradient_seed


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
    _check_call(params, inputs, gradient_kwargs, "wp.array")
    active = recording_tape()
    values = {n: _value_of(params, n, a) for n, a in inputs.items()}
    image = _render(params, values, rs)
    out = wp.array(np.ascontiguousarray(image, dtype=np.float32), dtype=wp.float32,
                   device=params.scene.device, requires_grad=True)
    tape = tape if tape is not None else active
    if tape is not None:
        rec = _Recorded(params, dict(inputs), values, params.camera, params.sky, rs, out,
                        dict(gradient_kwargs, gradient_seed=_seed(rs, gradient_seed)))
        tape.record_func(rec.backward, [a for a in inputs.values() if a.grad is not None] + [out])
    return out


def render_torch(params: SceneParameters, inputs: dict, settings: RenderSettings | None = None, *,
                 gradient_seed: int | None = None, **gradient_kwargs):
    """:func:`render_arrays` for PyTorch: ``inputs`` name -> ``torch.Tensor``; the image is a tensor (H,
    W, 3) float32 on the first input's device, and ``loss.backward()`` gives each input that requires
    grad its ``.grad`` (a ``torch.autograd.Function``: the render is one node of torch's graph)."""
    import torch

    rs = settings or RenderSettings(width=64, height=64, spp=4, max_depth=4)
    _check_call(params, inputs, gradient_kwargs, "torch.Tensor")
    names = list(inputs)
    for n in names:
        if not isinstance(inputs[n], torch.Tensor):
            raise TypeError(f"{n}: expected a torch.Tensor, got {type(inputs[n]).__name__}")
    return _torch_function()(params, rs, names, dict(gradient_kwargs, gradient_seed=_seed(rs, gradient_seed)),
                             *[inputs[n] for n in names])


def _torch_function():
    """The autograd Function, built on first use (torch is optional)."""
    import torch

    class RenderFunction(torch.autograd.Function):
        @staticmethod
        def forward(ctx, params, rs, names, kw, *tensors):
            values = {n: _reshaped(params, n, t.detach().cpu().numpy(), f"the tensor has shape {tuple(t.shape)}")
                      for n, t in zip(names, tensors)}
            image = _render(params, values, rs)
            ctx.record = _Recorded(params, dict(zip(names, tensors)), values, params.camera, params.sky, rs,
                                   None, kw)
            ctx.like = [(t.shape, t.dtype, t.device) for t in tensors]
            return torch.from_numpy(np.ascontiguousarray(image, np.float32)).to(tensors[0].device)

        @staticmethod
        def backward(ctx, grad_image):
            grads = ctx.record.gradients(grad_image.detach().cpu().numpy().astype(np.float32))
            out = [torch.from_numpy(np.asarray(grads[n])).reshape(shape).to(device=device, dtype=dtype)
                   for n, (shape, dtype, device) in zip(ctx.record.inputs, ctx.like)]
            return (None, None, None, None, *out)

    return RenderFunction.apply
