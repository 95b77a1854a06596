"""Minimal reproducer: a struct field written in place after a call hands that call's adjoint the new value.

    PYTHONPATH=. python scripts/warp_struct_write_repro.py

Warp (1.19) lowers ``s.field = value`` on a local struct to an in-place store into the struct's one
C++ variable (codegen ``emit_Assign``, struct branch), not to a new SSA value. The reverse sweep runs
after the whole forward replay, so the adjoint of any earlier call that took ``s`` sees ``s`` as it
is at the end. Below, ``scale(s, x)`` reads ``s.k``; writing ``s.k = 10`` after the call makes the
adjoint use k = 10, so d out / d x comes out 10 instead of 2. The same class of restriction as
Warp's "assign each vector component once" rule (NVIDIA/warp#1697). Writing the update through a
function that returns a new struct (``s = with_k(s, 10)``) gives the right 2.

In warp_spt this made NEE gradients with the independent sampler wrong: ``step`` wrote
``p.sampler = st`` after ``direct(..., p, ...)``, so the adjoint of ``direct`` replayed with the
sampler already past the light dimensions and drew other light samples (Sobol' is stateless, so it
was unaffected). Fixed by the copy ``lit = p`` in ``integrators.nee``'s vertex.
"""

import numpy as np
import warp as wp


@wp.struct
class S:
    k: float


@wp.func
def scale(s: S, x: float) -> float:
    return s.k * x


@wp.func
def with_k(s: S, k: float) -> S:
    t = s
    t.k = k
    return t


@wp.kernel
def in_place(x: wp.array(dtype=float), out: wp.array(dtype=float)):
    s = S()
    s.k = 2.0
    y = scale(s, x[0])
    s.k = 10.0             # written in place after the call
    out[0] = y + s.k * 0.0


@wp.kernel
def functional(x: wp.array(dtype=float), out: wp.array(dtype=float)):
    s = S()
    s.k = 2.0
    y = scale(s, x[0])
    s = with_k(s, 10.0)    # a new struct value
    out[0] = y + s.k * 0.0


def grad(kernel) -> float:
    x = wp.array(np.ones(1, np.float32), dtype=float, requires_grad=True)
    out = wp.zeros(1, dtype=float, requires_grad=True)
    tape = wp.Tape()
    with tape:
        wp.launch(kernel, dim=1, inputs=[x, out], device="cpu")
    tape.backward(grads={out: wp.array(np.ones(1, np.float32), dtype=float)})
    return float(x.grad.numpy()[0])


if __name__ == "__main__":
    print(f"d out / d x, field written in place: {grad(in_place):g} (expected 2)")
    print(f"d out / d x, new struct:             {grad(functional):g} (expected 2)")
