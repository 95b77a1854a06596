"""Zero adjoints: tell Warp that no derivative flows back through a ``wp.func``.

Warp's adjoint of a function re-runs its forward code and then its callees' adjoints; for a function
whose result must not carry a derivative (a sampler's numbers, the detached hit of path replay, the
light sampler's geometry) that work is thrown away, sometimes several times per differentiated
vertex. :func:`zero_adjoint` registers an empty ``wp.func_grad`` for it, written from its signature,
so that no call site spells out a signature (and no copy of it drifts from the function). Only
kernels with adjoint code (the tape, path replay) see the difference; forward kernels do not change.
"""

from __future__ import annotations

import linecache
from typing import Sequence

import warp as wp


def zero_adjoint(func, returns: Sequence[type]) -> None:
    """Register an empty adjoint for the ``wp.func`` ``func``, whose results have the types
    ``returns`` (in order; one entry per returned value)."""
    names = {f"t{i}": t for i, t in enumerate(list(func.input_types.values()) + list(returns))}
    params = [f"{a}: t{i}" for i, a in enumerate(func.input_types)]
    n_in = len(params)
    params += [f"adj_ret_{k}: t{n_in + k}" for k in range(len(returns))] if len(returns) > 1 else \
        [f"adj_ret: t{n_in}"]
    name = f"adj_{func.key}"
    source = f"def {name}({', '.join(params)}):\n    pass\n"
    # Warp reads a function's source to build it: give the generated one a file name linecache knows
    filename = f"<zero_adjoint {func.key}>"
    linecache.cache[filename] = (len(source), None, source.splitlines(True), filename)
    scope: dict = dict(names)
    exec(compile(source, filename, "exec"), scope)
    # wp.func_grad matches the adjoint against the function's return types, which it learns by
    # generating the function's code (and its callees'), about 30 ms per sampler request function
    # at every start, cached kernels or not. The types are given here: state them for the match
    # (what that code generation would find), then leave the function unbuilt as before.
    adj = func.adj
    stated = not hasattr(adj, "return_var")
    if stated:
        from warp._src.codegen import Var
        adj.return_var = tuple(Var(f"ret_{k}", t) for k, t in enumerate(returns))
    try:
        wp.func_grad(func)(scope[name])
    finally:
        if stated:
            del adj.return_var
