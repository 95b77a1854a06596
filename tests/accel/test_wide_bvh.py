"""Wide BVH builder (warp_spt.accel.wide_bvh): structural invariants, exact containment, reachability,
the stack bound, and input validation, on random soups and awkward meshes."""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.accel.wide_bvh import WideBvh, build_wide


def soup(rng: np.random.Generator, k: int, size: float = 0.5, spread: float = 100.0):
    """k independent triangles: random centres in a cube, random vertex offsets."""
    c = rng.uniform(0.0, spread, size=(k, 1, 3))
    p = c + rng.normal(scale=size, size=(k, 3, 3))
    return p.reshape(-1, 3), np.arange(3 * k).reshape(k, 3)


def grid_mesh(n: int):
    """A connected n x n quad grid on a wavy surface (2 n^2 triangles sharing vertices)."""
    u, v = np.meshgrid(np.linspace(0, 1, n + 1), np.linspace(0, 1, n + 1), indexing="ij")
    p = np.stack([u, v, 0.1 * np.sin(7 * u) * np.cos(5 * v)], axis=-1).reshape(-1, 3)
    i = np.arange(n)[:, None] * (n + 1) + np.arange(n)[None, :]
    a, b, c, d = i, i + 1, i + n + 1, i + n + 2
    tris = np.concatenate([np.stack([a, b, d], -1).reshape(-1, 3), np.stack([a, d, c], -1).reshape(-1, 3)])
    return p, tris


def check(bvh: WideBvh, points: np.ndarray, tris: np.ndarray, width: int, max_leaf: int) -> None:
    """Every invariant the traversal relies on."""
    k = len(tris)
    m = bvh.num_nodes
    assert bvh.box.dtype == np.float32 and bvh.box.shape == (m, 6, width)
    assert bvh.child.dtype == np.int32 and bvh.child.shape == (m, width)
    assert bvh.order.dtype == np.int32 and bvh.order.shape == (k,)
    assert np.array_equal(np.sort(bvh.order), np.arange(k))
    lo, hi = bvh.box[:, 0:3, :], bvh.box[:, 3:6, :]
    # slots: filled ones first; empty = lower +inf, upper -inf, child 0
    filled = np.isfinite(lo).all(axis=1) & np.isfinite(hi).all(axis=1)
    empty = np.isposinf(lo).all(axis=1) & np.isneginf(hi).all(axis=1)
    assert (filled | empty).all()
    assert (bvh.child[empty] == 0).all()
    assert (np.diff(filled.astype(int), axis=1) <= 0).all(), "empty slots must follow the filled ones"
    assert filled[:, 0].all(), "every node has at least one child"
    assert (lo <= hi)[np.broadcast_to(filled[:, None, :], lo.shape)].all()
    # interior children: each non-root node referenced exactly once, always by a lower-numbered node
    ch = bvh.child
    inner = filled & (ch >= 0)
    targets = ch[inner]
    assert np.array_equal(np.sort(targets), np.arange(1, m))
    parents = np.nonzero(inner)[0]
    assert (targets > parents).all()
    # leaves tile the order: ranges of 1..max_leaf, disjoint, covering [0, K)
    leaf = filled & (ch < 0)
    code = -ch[leaf].astype(np.int64) - 1
    first, count = code >> 3, code & 7
    assert ((count >= 1) & (count <= max_leaf)).all()
    o = np.argsort(first)
    assert first[o][0] == 0 and first[o][-1] + count[o][-1] == k
    assert np.array_equal(first[o][1:], (first + count)[o][:-1])
    # containment: every triangle's float64 vertices inside its leaf slot's box and every ancestor's
    p = np.asarray(points, dtype=np.float64)
    tri = p[np.asarray(tris)[bvh.order]]                     # (K, 3, 3) in leaf order
    tlo, thi = tri.min(axis=1), tri.max(axis=1)
    node_of_slot, slot = np.nonzero(leaf)
    llo = lo[node_of_slot, :, slot].astype(np.float64)
    lhi = hi[node_of_slot, :, slot].astype(np.float64)
    pos = np.repeat(np.arange(len(first)), count)
    at = np.concatenate([np.arange(f, f + c) for f, c in zip(first, count)]) if len(first) else np.array([], int)
    assert (tlo[at] >= llo[pos]).all() and (thi[at] <= lhi[pos]).all()
    # a child's box lies inside the slot box that points at it (so containment holds at every level)
    pn, ps = np.nonzero(inner)
    cn = ch[pn, ps]
    clo = np.where(filled[cn][:, None, :], lo[cn], np.inf).min(axis=2)
    chi = np.where(filled[cn][:, None, :], hi[cn], -np.inf).max(axis=2)
    assert (clo >= lo[pn, :, ps]).all() and (chi <= hi[pn, :, ps]).all()
    # depth and the stack bound, recomputed by walking the tree
    depth = np.zeros(m, dtype=np.int64)
    behind = np.zeros(m, dtype=np.int64)                     # siblings left on the stack by ancestors
    depth[0] = 1
    fan = filled.sum(axis=1)
    for i in range(m):                                       # parents precede children
        kids = ch[i][inner[i]]
        depth[kids] = depth[i] + 1
        behind[kids] = behind[i] + fan[i] - 1
    assert bvh.depth == int(depth.max())
    assert bvh.stack_bound == int((behind + fan).max())
    assert bvh.stack_bound <= 1 + bvh.depth * (width - 1)


def reference_stack_walk(bvh: WideBvh) -> int:
    """The deepest stack of a traversal that visits every node (every box hit), pushing all children."""
    stack, most = [0], 1
    while stack:
        node = stack.pop()
        if node < 0:
            continue
        kids = [int(c) for c, f in zip(bvh.child[node], np.isfinite(bvh.box[node, 0])) if f]
        stack.extend(kids)
        most = max(most, len(stack))
    return most


@pytest.mark.parametrize("k", [1, 2, 3, 7, 9, 64, 65, 1000, 20000])
@pytest.mark.parametrize("width,max_leaf", [(8, 2), (4, 2), (8, 1), (8, 4), (2, 3)])
def test_random_soup(k, width, max_leaf):
    rng = np.random.default_rng(k * 31 + width * 7 + max_leaf)
    p, t = soup(rng, k)
    bvh = build_wide(p, t, width=width, max_leaf=max_leaf)
    check(bvh, p, t, width, max_leaf)
    if k <= 1000:
        assert reference_stack_walk(bvh) <= bvh.stack_bound


def test_single_triangle_gets_a_root():
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float32)
    bvh = build_wide(p, np.array([[0, 1, 2]]))
    check(bvh, p, np.array([[0, 1, 2]]), 8, 2)
    assert bvh.num_nodes == 1 and bvh.depth == 1 and bvh.stack_bound == 1
    assert bvh.child[0, 0] == -(0 * 8 + 1) - 1 and (bvh.child[0, 1:] == 0).all()
    assert np.array_equal(bvh.box[0, :, 0], [0, 0, 0, 1, 1, 0])


def test_leaf_sized_mesh_is_one_root_with_one_leaf():
    rng = np.random.default_rng(0)
    p, t = soup(rng, 2)
    bvh = build_wide(p, t, max_leaf=2)
    check(bvh, p, t, 8, 2)
    assert bvh.num_nodes == 1 and bvh.child[0, 0] == -(0 * 8 + 2) - 1


def test_degenerate_triangles_are_kept():
    rng = np.random.default_rng(1)
    p, t = soup(rng, 500)
    # points (all three vertices equal), segments (collinear), and triangles reusing one vertex twice
    t[:100, 1] = t[:100, 0]
    t[:100, 2] = t[:100, 0]
    p[t[100:200, 2]] = 0.5 * (p[t[100:200, 0]] + p[t[100:200, 1]])
    t[200:250, 2] = t[200:250, 1]
    bvh = build_wide(p, t)
    check(bvh, p, t, 8, 2)


def test_all_degenerate_at_one_point():
    p = np.zeros((3, 3))
    t = np.zeros((5000, 3), dtype=np.int64)
    bvh = build_wide(p, t)
    check(bvh, p, t, 8, 2)
    assert bvh.depth <= 6                                     # balanced, not a chain


@pytest.mark.parametrize("copies", [2, 3, 1000, 20000])
def test_many_coincident_triangles(copies):
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype=np.float32)
    t = np.tile([[0, 1, 2]], (copies, 1))
    bvh = build_wide(p, t)
    check(bvh, p, t, 8, 2)
    assert bvh.depth <= int(np.ceil(np.log(max(copies / 2, 1)) / np.log(8))) + 2


def test_coincident_pile_inside_a_soup():
    rng = np.random.default_rng(2)
    p, t = soup(rng, 3000)
    t = np.concatenate([t, np.tile(t[:1], (5000, 1))])
    bvh = build_wide(p, t)
    check(bvh, p, t, 8, 2)
    assert bvh.stack_bound <= 64


@pytest.mark.parametrize("scale", [1e-30, 1e-8, 1.0, 1e8, 1e30, 3e38])
def test_huge_and_tiny_coordinates(scale):
    rng = np.random.default_rng(3)
    p, t = soup(rng, 2000, size=0.01, spread=1.0)
    p = (p - 0.5) * 1.5 * scale                               # spans [-0.75 scale, 0.75 scale] or so
    p = np.clip(p, -np.finfo(np.float32).max, np.finfo(np.float32).max)
    bvh = build_wide(p, t)
    check(bvh, p, t, 8, 2)


def test_float64_points_are_contained_after_rounding():
    """Vertices not representable in float32: the float32 boxes must still contain them."""
    rng = np.random.default_rng(4)
    p, t = soup(rng, 3000, size=1e-3, spread=1.0)
    p = p + 1.0 / 3.0                                         # float64 values between float32s
    bvh = build_wide(p, t)
    check(bvh, p, t, 8, 2)


def test_mixed_sizes_and_flat_mesh():
    rng = np.random.default_rng(5)
    p1, t1 = grid_mesh(60)                                    # connected, nearly flat
    p2, t2 = soup(rng, 200, size=30.0)                        # big overlapping triangles
    p = np.concatenate([p1, p2])
    t = np.concatenate([t1, t2 + len(p1)])
    bvh = build_wide(p, t)
    check(bvh, p, t, 8, 2)
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=np.float32)
    pf = (flat[None] + rng.uniform(0, 50, (500, 1, 3)) * [1, 1, 0]).reshape(-1, 3)
    tf = (np.arange(500)[:, None] * 4 + [[0, 1, 2]])
    bvh = build_wide(pf, tf)
    check(bvh, pf, tf, 8, 2)


def test_unused_points_are_ignored():
    p = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [np.nan, 0, 0]])
    bvh = build_wide(p, np.array([[0, 1, 2]]))
    assert bvh.num_nodes == 1


def test_deterministic():
    rng = np.random.default_rng(6)
    p, t = soup(rng, 5000)
    a, b = build_wide(p, t), build_wide(p, t)
    assert np.array_equal(a.box, b.box) and np.array_equal(a.child, b.child) and np.array_equal(a.order, b.order)


def test_sah_beats_a_median_split_on_clusters():
    """Far-apart clusters: the first level's children should not straddle two clusters."""
    rng = np.random.default_rng(7)
    centres = np.array([[0, 0, 0], [100, 0, 0], [0, 100, 0], [0, 0, 100]], dtype=float)
    k = 4000
    c = centres[rng.integers(0, 4, k)][:, None, :] + rng.normal(scale=1.0, size=(k, 1, 3))
    p = (c + rng.normal(scale=0.05, size=(k, 3, 3))).reshape(-1, 3)
    t = np.arange(3 * k).reshape(k, 3)
    bvh = build_wide(p, t)
    check(bvh, p, t, 8, 2)
    ext = (bvh.box[0, 3:6] - bvh.box[0, 0:3])[:, np.isfinite(bvh.box[0, 0, :])]
    assert (ext.max(axis=0) < 20).all(), "a root child spans two clusters"


@pytest.mark.parametrize(
    "points,tris,kwargs,match",
    [
        (np.zeros((3, 3)), np.zeros((0, 3), dtype=int), {}, "no triangles"),
        (np.zeros((3, 2)), np.zeros((1, 3), dtype=int), {}, "points must be"),
        (np.zeros((3, 3), dtype=int), np.zeros((1, 3), dtype=int), {}, "points must be"),
        (np.zeros((3, 3)), np.zeros((1, 4), dtype=int), {}, "tris must be"),
        (np.zeros((3, 3)), np.zeros((1, 3)), {}, "tris must be"),
        (np.zeros((3, 3)), np.array([[0, 1, 3]]), {}, "indices"),
        (np.zeros((3, 3)), np.array([[0, -1, 2]]), {}, "indices"),
        (np.array([[0, 0, 0], [1, 0, 0], [np.inf, 0, 0]]), np.array([[0, 1, 2]]), {}, "finite"),
        (np.array([[0, 0, 0], [1, 0, 0], [np.nan, 0, 0]]), np.array([[0, 1, 2]]), {}, "finite"),
        (np.array([[0, 0, 0], [1, 0, 0], [1e39, 0, 0]]), np.array([[0, 1, 2]]), {}, "float32 range"),
        (np.zeros((3, 3)), np.array([[0, 1, 2]]), {"width": 1}, "width"),
        (np.zeros((3, 3)), np.array([[0, 1, 2]]), {"max_leaf": 0}, "max_leaf"),
        (np.zeros((3, 3)), np.array([[0, 1, 2]]), {"max_leaf": 8}, "max_leaf"),
    ],
)
def test_validation(points, tris, kwargs, match):
    with pytest.raises(ValueError, match=match):
        build_wide(points, tris, **kwargs)


# ---------------------------------------------------------------------------------------------
# The compiled builder (accel/wide_build.py) against the numpy one


@pytest.mark.parametrize("width", [8, 4, 3])
def test_kernel_collapse_equals_the_numpy_collapse(width):
    """The same binary tree collapsed by the kernel and by wide_bvh._collapse: the same wide tree,
    array for array (the kernel replaces the numpy collapse, whose rules are the reference)."""
    from warp_spt.accel.wide_build import build_binary, collapse
    from warp_spt.accel.wide_bvh import _collapse, _triangle_boxes
    p, t = soup(np.random.default_rng(5), 3000)
    p = np.concatenate([p, np.repeat(p[:3], 20, axis=0)])          # a pile of coincident triangles
    t = np.concatenate([t, np.arange(3 * 3000, 3 * 3000 + 60).reshape(-1, 3)])
    lo, hi = _triangle_boxes(p, t)
    start, count, left, right, nlo, nhi, order = build_binary(lo, hi, 2, 48)
    a = collapse(start, count, left, nlo, nhi, width)
    b = _collapse(start, count, left, right, nlo, nhi, width)
    assert np.array_equal(a[0], b[0]) and np.array_equal(a[1], b[1]) and a[2:] == b[2:]


@pytest.mark.parametrize("builder", ["warp", "numpy"])
def test_both_builders_hold_every_invariant(builder):
    rng = np.random.default_rng(11)
    p, t = soup(rng, 2000)
    check(build_wide(p, t, builder=builder), p, t, 8, 2)
    p, t = grid_mesh(30)
    check(build_wide(p, t, builder=builder), p, t, 8, 2)


def test_the_kernel_build_is_no_worse_than_numpy_by_sah():
    """SAH cost (node areas over the root's, as benchmarks/bench_wide_build.py) of the kernel's tree
    within 5% of the numpy build's on a soup and a wavy grid: the faster build does not buy a worse tree."""
    def cost(bvh):
        lo, hi = bvh.box[:, 0:3].astype(np.float64), bvh.box[:, 3:6].astype(np.float64)
        filled = np.isfinite(lo).all(axis=1)
        d = np.where(filled[:, None, :], hi - lo, 0.0)
        area = d[:, 0] * d[:, 1] + d[:, 1] * d[:, 2] + d[:, 2] * d[:, 0]
        n = np.where(bvh.child < 0, (-bvh.child.astype(np.int64) - 1) & 7, 1)
        return float((area * np.where(filled, n, 0)).sum())
    for p, t in (soup(np.random.default_rng(2), 20000), grid_mesh(100)):
        assert cost(build_wide(p, t, builder="warp")) <= 1.05 * cost(build_wide(p, t, builder="numpy"))


def test_unknown_builder_is_refused():
    with pytest.raises(ValueError, match="builder"):
        build_wide(np.eye(3), np.array([[0, 1, 2]]), builder="fast")
