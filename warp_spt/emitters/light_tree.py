"""A light tree over emitting triangles: a spatially aware choice among many lights.

After Conty Estevez & Kulla (2018), simplified to what this renderer's emitters need: a binary tree
over the emitting triangles (a median split of their centroids along the widest axis, one triangle a
leaf), each node holding the bounds of its triangles and their total power (the light table's
weights). From a shading point ``x`` the tree is descended from the root, choosing a child with
probability proportional to its *importance* ``power / max(d^2, r^2)``, ``d`` the distance from ``x``
to the centre of the child's bounds and ``r`` half their diagonal (pbrt-v4's distance bound: a
point inside or near a cluster does not divide by a vanishing distance). The triangles here emit
from both faces, so the orientation cones of the paper would not bound anything and are left out.

The choice probability of a triangle from ``x`` is the product of the child choices on its path;
``leaf_prob`` recomputes it from the leaf up (parent links), with the same function of the same
numbers, for MIS. Descending reuses one uniform number, rescaled at each choice (pbrt-v4's
remapping): each level spends about one of its 24 bits, what is left places the point on the
triangle.

A scene uses the tree when it has at least ``MIN_TREE_LIGHTS`` emitting triangles
(``Features.lights``: "triangle.tree"); below that the power table alone is as good and compiles no tree code.
"""

from __future__ import annotations

import numpy as np
import warp as wp

MIN_TREE_LIGHTS = 64
ONE_MINUS_EPS = wp.constant(0.99999994)
TREE_NEAR = wp.constant(0.0025)


@wp.struct
class LightTree:
    """Nodes in depth-first order, the root first; ``left`` is -1 at a leaf, whose triangle entry is
    ``entry``; ``leaf`` maps a triangle entry to its leaf."""

    lower: wp.array(dtype=wp.vec3)
    upper: wp.array(dtype=wp.vec3)
    power: wp.array(dtype=wp.float32)
    left: wp.array(dtype=wp.int32)
    right: wp.array(dtype=wp.int32)
    parent: wp.array(dtype=wp.int32)
    entry: wp.array(dtype=wp.int32)
    leaf: wp.array(dtype=wp.int32)


@wp.func(inline=True)     # out of line, each call copied the tree's struct (its eight arrays)
def importance(tree: LightTree, node: int, x: wp.vec3) -> float:
    lo = tree.lower[node]
    hi = tree.upper[node]
    q = wp.vec3(wp.clamp(x[0], lo[0], hi[0]), wp.clamp(x[1], lo[1], hi[1]), wp.clamp(x[2], lo[2], hi[2]))
    d2 = wp.length_sq(x - q)
    r2 = TREE_NEAR * wp.length_sq(hi - lo)
    return tree.power[node] / wp.max(wp.max(d2, r2), 1.0e-30)


@wp.func(inline=True)
def pick_leaf(tree: LightTree, x: wp.vec3, u: float):
    """(triangle entry, its choice probability from x, u rescaled for reuse) by descending the tree."""
    node = int(0)
    prob = float(1.0)
    uu = u
    while tree.left[node] >= 0:
        l = tree.left[node]
        r = tree.right[node]
        il = importance(tree, l, x)
        ir = importance(tree, r, x)
        pl = il / (il + ir)
        if uu < pl:
            node = l
            prob = prob * pl
            uu = wp.min(uu / pl, ONE_MINUS_EPS)
        else:
            node = r
            prob = prob * (1.0 - pl)
            uu = wp.min((uu - pl) / (1.0 - pl), ONE_MINUS_EPS)
    return tree.entry[node], prob, uu


@wp.func(inline=True)
def leaf_prob(tree: LightTree, entry: int, x: wp.vec3) -> float:
    """The probability with which ``pick_leaf`` from ``x`` chooses triangle entry ``entry``."""
    node = tree.leaf[entry]
    prob = float(1.0)
    par = tree.parent[node]
    while par >= 0:
        l = tree.left[par]
        il = importance(tree, l, x)
        ir = importance(tree, tree.right[par], x)
        if node == l:
            prob = prob * (il / (il + ir))
        else:
            prob = prob * (ir / (il + ir))
        node = par
        par = tree.parent[node]
    return prob


# ---------------------------------------------------------------------------------------------
# Host side


def build_tree(corners: np.ndarray, power: np.ndarray) -> dict[str, np.ndarray]:
    """The tree's arrays for triangles ``corners`` (N, 3, 3) float64 with ``power`` (N,) > 0."""
    n = len(power)
    lo_t, hi_t = corners.min(axis=1), corners.max(axis=1)
    cen = corners.mean(axis=1)
    size = 2 * n - 1
    lower, upper = np.zeros((size, 3)), np.zeros((size, 3))
    pw = np.zeros(size)
    left, right, parent, entry = (np.full(size, -1, np.int64) for _ in range(4))
    leaf = np.zeros(n, np.int64)
    order = np.arange(n)
    count = 0
    # (items, parent node, which child slot of the parent), depth first with the left child first
    stack = [(order, -1, 0)]
    while stack:
        items, par, side = stack.pop()
        node = count
        count += 1
        if par >= 0:
            parent[node] = par
            if side == 0:
                left[par] = node
            else:
                right[par] = node
        lower[node], upper[node] = lo_t[items].min(0), hi_t[items].max(0)
        pw[node] = power[items].sum()
        if len(items) == 1:
            entry[node] = items[0]
            leaf[items[0]] = node
            continue
        c = cen[items]
        axis = int(np.argmax(c.max(0) - c.min(0)))
        half = len(items) // 2
        split = np.argpartition(c[:, axis], half - 1)
        stack.append((items[split[half:]], node, 1))
        stack.append((items[split[:half]], node, 0))
    assert count == size
    return {"lower": lower, "upper": upper, "power": pw, "left": left, "right": right, "parent": parent,
            "entry": entry, "leaf": leaf}


def upload_tree(arrays: dict[str, np.ndarray] | None, device: str) -> LightTree:
    """The device tree (one dummy leaf for ``None``: Warp structs need arrays)."""
    if arrays is None:
        arrays = build_tree(np.zeros((1, 3, 3)), np.ones(1))
    t = LightTree()
    for name in ("lower", "upper"):
        setattr(t, name, wp.array(arrays[name].astype(np.float32), dtype=wp.vec3, device=device))
    t.power = wp.array(arrays["power"].astype(np.float32), dtype=wp.float32, device=device)
    for name in ("left", "right", "parent", "entry", "leaf"):
        setattr(t, name, wp.array(arrays[name].astype(np.int32), dtype=wp.int32, device=device))
    return t
