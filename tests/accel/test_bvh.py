"""Top-level BVH: structure invariants, exact containment, ray coverage and SAH quality."""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.accel.tlas import Tlas, build_tlas, ray_query_reference


def random_boxes(rng: np.random.Generator, k: int, flat_fraction: float = 0.2):
    """Boxes of mixed sizes; a fraction are flat (zero thickness on one axis, like a single quad)."""
    centre = rng.normal(size=(k, 3)) * 10.0
    half = rng.exponential(0.5, size=(k, 3))
    flat = rng.random(k) < flat_fraction
    half[flat, rng.integers(0, 3, size=int(flat.sum()))] = 0.0
    return centre - half, centre + half


def clustered_boxes(rng: np.random.Generator, k: int):
    """A few tight clusters far apart: a median split cuts through clusters, SAH does not."""
    centres = rng.uniform(-100, 100, size=(6, 3))
    c = centres[rng.integers(0, 6, size=k)] + rng.normal(scale=0.5, size=(k, 3))
    h = rng.uniform(0.01, 0.1, size=(k, 1))
    return c - h, c + h


def check_structure(t: Tlas, k: int, max_leaf: int) -> None:
    n = len(t.left)
    for a in (t.lower, t.upper):
        assert a.dtype == np.float32 and a.shape == (n, 3)
    for a in (t.left, t.right, t.first, t.count, t.items):
        assert a.dtype == np.int32
    leaf = t.left < 0
    assert np.array_equal(leaf, t.right < 0)
    assert (t.first[~leaf] == -1).all() and (t.count[~leaf] == 0).all()
    assert ((t.count[leaf] >= 1) & (t.count[leaf] <= max_leaf)).all()
    # every item appears in exactly one leaf
    seen = np.concatenate([t.items[f:f + c] for f, c in zip(t.first[leaf], t.count[leaf])])
    assert np.array_equal(np.sort(seen), np.arange(k))
    # depth-first layout: each node's left child follows it; every non-root node has one parent
    inner = np.flatnonzero(~leaf)
    assert (t.left[inner] == inner + 1).all()
    children = np.concatenate([t.left[inner], t.right[inner]])
    assert np.array_equal(np.sort(children), np.arange(1, n))


def tree_depth(t: Tlas) -> int:
    depth = np.zeros(len(t.left), dtype=int)
    for node in range(len(t.left)):          # parents precede children in depth-first order
        if t.left[node] >= 0:
            depth[t.left[node]] = depth[t.right[node]] = depth[node] + 1
    return int(depth.max())


def check_containment(t: Tlas, lo: np.ndarray, hi: np.ndarray) -> None:
    inner = np.flatnonzero(t.left >= 0)
    for child in (t.left[inner], t.right[inner]):
        assert (t.lower[inner] <= t.lower[child]).all() and (t.upper[inner] >= t.upper[child]).all()
    for node in np.flatnonzero(t.left < 0):
        ids = t.items[t.first[node]:t.first[node] + t.count[node]]
        # float32 node box versus the caller's float64 item boxes: exact containment
        assert (t.lower[node].astype(np.float64) <= lo[ids]).all()
        assert (t.upper[node].astype(np.float64) >= hi[ids]).all()


def segment_hits_box(lo, hi, o, d, t_max) -> bool:
    """Independent float64 check: clip the segment [0, t_max] against each slab in turn."""
    t0, t1 = 0.0, t_max
    for a in range(3):
        if d[a] == 0.0:
            if o[a] < lo[a] or o[a] > hi[a]:
                return False
            continue
        ta, tb = sorted(((lo[a] - o[a]) / d[a], (hi[a] - o[a]) / d[a]))
        t0, t1 = max(t0, ta), min(t1, tb)
        if t0 > t1:
            return False
    return True


@pytest.mark.parametrize("k,max_leaf", [(1, 2), (2, 2), (3, 1), (57, 2), (500, 4), (3000, 2)])
def test_structure_and_containment(k, max_leaf):
    rng = np.random.default_rng(k)
    lo, hi = random_boxes(rng, k)
    t = build_tlas(lo, hi, max_leaf=max_leaf)
    check_structure(t, k, max_leaf)
    check_containment(t, lo, hi)
    assert t.depth == tree_depth(t)


def test_single_item_root_is_leaf():
    t = build_tlas(np.array([[0.0, 0.0, 0.0]]), np.array([[1.0, 0.0, 2.0]]))
    assert len(t.left) == 1 and t.left[0] == -1 and t.right[0] == -1
    assert t.first[0] == 0 and t.count[0] == 1 and t.items.tolist() == [0] and t.depth == 0
    # a flat box is kept, and a ray through it finds it
    assert ray_query_reference(t, (0.5, 0.0, -5.0), (0.0, 0.0, 1.0), 10.0) == [0]
    assert ray_query_reference(t, (0.5, -3.0, 1.0), (0.0, 1.0, 0.0), 10.0) == [0]


def test_float32_rounding_is_outward():
    lo = np.array([[0.1, -0.1, 1e-40], [1.0 / 3.0, 7.0, -2.0 / 3.0]])
    hi = lo + np.array([[0.2, 0.3, 0.0], [1e-9, 0.0, 1.0 / 7.0]])
    t = build_tlas(lo, hi, max_leaf=2)
    assert (t.lower[0].astype(np.float64) <= lo.min(0)).all()
    assert (t.upper[0].astype(np.float64) >= hi.max(0)).all()
    # and tight: one float32 step inward would no longer contain the bounds
    assert (np.nextafter(t.lower[0], np.float32(np.inf)).astype(np.float64) > lo.min(0)).all()
    assert (np.nextafter(t.upper[0], np.float32(-np.inf)).astype(np.float64) < hi.max(0)).all()


def random_ray(rng: np.random.Generator, target: np.ndarray):
    o = rng.normal(size=3) * 15.0
    d = target - o + rng.normal(size=3)    # aimed near an item, so most rays hit something
    zero = rng.random(3) < 0.15            # axis-parallel components exercise the d == 0 path
    d[zero] = 0.0
    if not d.any():
        d[2] = 1.0
    t_max = float(rng.choice([5.0, 30.0, np.inf]))
    return o, d, t_max


def test_reference_traversal_covers_brute_force():
    rng = np.random.default_rng(7)
    lo, hi = random_boxes(rng, 400, flat_fraction=0.3)
    t = build_tlas(lo, hi, max_leaf=2)
    nonempty = 0
    for _ in range(300):
        o, d, t_max = random_ray(rng, lo[rng.integers(len(lo))])
        truth = {i for i in range(len(lo)) if segment_hits_box(lo[i], hi[i], o, d, t_max)}
        found = ray_query_reference(t, o, d, t_max)
        assert len(found) == len(set(found))
        assert truth <= set(found)
        nonempty += bool(truth)
    assert nonempty > 80                    # the rays really hit things


def test_flat_boxes_are_found_by_rays_through_them():
    # a grid of axis-aligned quads in the plane z = 1 (zero thickness), like wall halves
    g = np.stack(np.meshgrid(np.arange(8.0), np.arange(8.0), indexing="ij"), -1).reshape(-1, 2)
    lo = np.column_stack([g, np.ones(len(g))])
    hi = np.column_stack([g + 0.9, np.ones(len(g))])
    t = build_tlas(lo, hi)
    for i in (0, 9, 63):
        o = (lo[i, 0] + 0.45, lo[i, 1] + 0.45, 5.0)
        assert i in ray_query_reference(t, o, (0.0, 0.0, -1.0), 100.0)
        assert i in ray_query_reference(t, o, (0.01, 0.02, -1.0), 100.0)


def sah_cost(lo, hi, nodes) -> float:
    """SAH cost (1 per traversal step, 1 per item test) of a tree given as (box_lo, box_hi, n_items|None)."""
    def area(a, b):
        e = b - a
        return e[0] * e[1] + e[1] * e[2] + e[2] * e[0]

    root = area(*nodes[0][:2])
    return sum(area(a, b) / root * (1.0 if n is None else n) for a, b, n in nodes)


def tlas_nodes(t: Tlas):
    return [(t.lower[i].astype(np.float64), t.upper[i].astype(np.float64),
             None if t.left[i] >= 0 else int(t.count[i])) for i in range(len(t.left))]


def median_nodes(lo, hi, max_leaf):
    """A naive tree: split at the median centroid along the widest centroid axis, recursively."""
    out, stack = [], [np.arange(len(lo))]
    while stack:
        ids = stack.pop()
        leaf = len(ids) <= max_leaf
        out.append((lo[ids].min(0), hi[ids].max(0), len(ids) if leaf else None))
        if not leaf:
            c = (lo[ids] + hi[ids]) / 2
            axis = int(np.argmax(c.max(0) - c.min(0)))
            ids = ids[np.argsort(c[:, axis], kind="stable")]
            stack += [ids[: len(ids) // 2], ids[len(ids) // 2:]]
    return out


def test_sah_beats_median_on_clusters():
    rng = np.random.default_rng(3)
    lo, hi = clustered_boxes(rng, 2000)
    ours = sah_cost(lo, hi, tlas_nodes(build_tlas(lo, hi, max_leaf=2)))
    naive = sah_cost(lo, hi, median_nodes(lo, hi, 2))
    assert ours < naive


@pytest.mark.parametrize("kind", ["identical", "exponential"])
def test_depth_bounded_for_adversarial_inputs(kind):
    k = 100_000
    lo = np.zeros((k, 3))
    if kind == "exponential":               # SAH peels one item at a time off a geometric chain
        lo[:, 0] = 2.0 ** (np.arange(k) % 120)
    t = build_tlas(lo, lo + 1.0, max_leaf=1)
    assert t.depth < 64 and tree_depth(t) == t.depth
    leaf = t.left < 0
    assert np.array_equal(np.sort(t.items), np.arange(k)) and (t.count[leaf] == 1).all()


def test_depth_guard_switches_to_median_splits(monkeypatch):
    # the geometric chain above gives depth 41 with SAH alone; a budget of 20 must be honoured
    import warp_spt.accel.tlas as bvh

    monkeypatch.setattr(bvh, "DEPTH_BUDGET", 20)
    k = 20_000
    lo = np.zeros((k, 3))
    lo[:, 0] = 2.0 ** (np.arange(k) % 120)
    t = build_tlas(lo, lo + 1.0, max_leaf=1)
    assert tree_depth(t) <= 20
    check_structure(t, k, 1)
    check_containment(t, lo, lo + 1.0)


def test_no_items_give_one_empty_leaf_that_no_ray_enters():
    t = build_tlas(np.zeros((0, 3)), np.zeros((0, 3)))     # an animation's frame that hides everything
    assert t.num_nodes == 1 and t.count[0] == 0 and len(t.items) == 0
    assert (t.lower[0] > t.upper[0]).all()


def test_invalid_input():
    with pytest.raises(ValueError, match="lower > upper"):
        build_tlas(np.array([[0.0, 0, 1]]), np.array([[1.0, 1, 0]]))
    with pytest.raises(ValueError, match="finite"):
        build_tlas(np.array([[np.nan, 0, 0]]), np.array([[1.0, 1, 1]]))
    with pytest.raises(ValueError, match="float32 range"):
        build_tlas(np.array([[0.0, 0, 0]]), np.array([[1e39, 1, 1]]))
    with pytest.raises(ValueError, match=r"\(K, 3\)"):
        build_tlas(np.zeros((4, 2)), np.zeros((4, 2)))
