"""Large Steps (warp_spt.diff.large_steps): the Laplacian, the conjugate-gradient solve, fusing the
copies of a seam, uniform Adam and its smoothing, without rendering (a stand-in for SceneParameters
holds the positions)."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from warp_spt.diff.large_steps import LargeSteps, cg_solve, edges, fuse, laplacian
from warp_spt.diff.shape_demo import icosphere


class Params:
    """What LargeSteps reads of SceneParameters: ``info``, ``scene.scene.meshes[k].indices`` and the
    mapping of one ``"<mesh>.positions"``."""

    def __init__(self, v, f):
        self.v = np.asarray(v, np.float32)
        self.scene = SimpleNamespace(scene=SimpleNamespace(meshes=[SimpleNamespace(indices=np.asarray(f))]))

    def info(self, name):
        return SimpleNamespace(kind="mesh", index=0, shape=self.v.shape)

    def __getitem__(self, name):
        return self.v.copy()

    def __setitem__(self, name, value):
        self.v = np.asarray(value, np.float32)


def split_sphere(sub=2):
    """An icosphere whose vertices with x > 0.3 are duplicated for the faces wholly on that side:
    the faces straddling x = 0.3 keep the originals, so a seam runs round the sphere (as a uv seam
    makes). Returns (positions, faces, pairs (original, copy))."""
    v, f = icosphere(sub)
    side = np.all(v[f][:, :, 0] > 0.3, axis=1)
    seam = np.unique(f[side])
    copy = {int(i): len(v) + k for k, i in enumerate(seam)}
    f2 = f.copy()
    f2[side] = np.vectorize(copy.get)(f[side])
    v2 = np.concatenate([v, v[seam]])
    # only the originals also used by straddling faces are on the seam itself
    on_seam = np.intersect1d(seam, np.unique(f[~side]))
    return v2, f2, np.array([(i, copy[int(i)]) for i in on_seam])


def test_the_laplacian_is_symmetric_and_its_rows_sum_to_zero():
    v, f = icosphere(2)
    a = laplacian(f, len(v)).dense()
    assert np.array_equal(a, a.T)
    assert np.abs(a.sum(axis=1)).max() == 0.0
    deg = np.bincount(edges(f).reshape(-1), minlength=len(v))
    assert np.array_equal(np.diag(a), deg) and set(deg) == {5, 6}      # the icosphere's valences
    assert np.sum(a != 0) == len(v) + 2 * len(edges(f)) == len(v) + 3 * len(f)


def test_cg_matches_a_dense_solve():
    v, f = icosphere(2)
    m = laplacian(f, len(v), lam=15.0, identity=1.0)
    b = np.random.default_rng(1).normal(size=(len(v), 3))
    x, it = cg_solve(m, b, tol=1e-10)
    ref = np.linalg.solve(m.dense(), b)
    assert np.abs(x - ref).max() < 1e-8 * np.abs(ref).max()
    assert 0 < it < len(v)
    # warm-started from the answer it takes no iteration; from near it, fewer
    assert cg_solve(m, b, ref, tol=1e-8)[1] == 0
    assert cg_solve(m, b, ref + 1e-6 * b, tol=1e-10)[1] < it
    x1, _ = cg_solve(m, b[:, 0], tol=1e-10)                    # a vector as well as columns
    assert np.abs(x1 - ref[:, 0]).max() < 1e-8 * np.abs(ref).max()


def test_fuse_joins_copies_and_only_them():
    v, f, pairs = split_sphere()
    rng = np.random.default_rng(2)
    point, first = fuse(v)
    assert len(first) == 162 and np.array_equal(point[:162], np.arange(162))
    assert np.array_equal(point[pairs[:, 0]], point[pairs[:, 1]])
    # copies a hair apart, placed either side of a cell's wall, are still one point
    w = v.copy()
    w[162:] += rng.uniform(-1, 1, size=(len(v) - 162, 3)) * 1e-7
    assert len(fuse(w, tol=1e-6)[1]) == 162
    # and points further apart than the tolerance are not
    w[162:] += 1e-5
    assert len(fuse(w, tol=1e-6)[1]) == len(v)
    with pytest.raises(ValueError, match=r"\(V, 3\)"):
        fuse(np.zeros((4, 2)))


def test_a_seam_does_not_open():
    """A gradient that differs on the two copies of each seam vertex: fused, the copies move as one
    point; the control without fusing lets them part."""
    v, f, pairs = split_sphere()
    rng = np.random.default_rng(3)
    gaps = {}
    for fused in (True, False):
        p = Params(v, f)
        opt = LargeSteps(p, "m.positions", lr=0.01, lam=10.0, fuse_seams=fused)
        for _ in range(10):
            g = rng.normal(size=v.shape)
            g[pairs[:, 1]] = -g[pairs[:, 0]] + 1.0        # the copies pulled different ways
            opt.step({"m.positions": g})
        gaps[fused] = np.abs(p.v[pairs[:, 0]] - p.v[pairs[:, 1]]).max()
    assert gaps[True] == 0.0
    assert gaps[False] > 1e-3, gaps


def test_uniform_adam_moves_every_vertex_by_the_same_step():
    """With lam = 0 (no filter) the first step is lr * g / max|g|: the same scale for every vertex,
    where Adam's per-entry second moment would move each entry by lr whatever its gradient."""
    v, f = icosphere(1)
    g = np.zeros(v.shape)
    g[:, 0] = np.linspace(0.1, 10.0, len(v))
    p = Params(v, f)
    opt = LargeSteps(p, "m.positions", lr=0.01, lam=0.0)
    opt.step({"m.positions": g})
    step = p.v.astype(np.float64) - v
    assert step[:, 0] == pytest.approx(-0.01 * g[:, 0] / 10.0, abs=2e-7)
    assert np.abs(step[:, 1:]).max() < 2e-7
    # a gradient along x alone moves every vertex along x by a step proportional to its gradient, and
    # the uniform norm makes the step size independent of the gradient's scale
    p2 = Params(v, f)
    LargeSteps(p2, "m.positions", lr=0.01, lam=0.0).step({"m.positions": 1000.0 * g})
    assert np.abs(p2.v - p.v).max() < 2e-7


def test_a_high_frequency_gradient_is_damped():
    """White noise as the gradient: plain Adam's first step is lr * sign(g), as rough as the noise;
    Large Steps' is filtered twice by (I + lam L)^-1. Roughness is ||L x|| / ||x|| (about 6.5 for
    noise on this mesh); measured 0.046 for the filtered step at lam = 20, 0.23 at lam = 5. A smooth
    gradient (every vertex against its normal: descent grows the sphere) keeps its shape: the step is radial
    and even (spread 0.8% of its size, measured)."""
    v, f = icosphere(3)
    lap = laplacian(f, len(v))

    def roughness(x):
        return np.linalg.norm(lap @ x) / np.linalg.norm(x)

    g = np.random.default_rng(4).normal(size=v.shape)
    adam = roughness(np.sign(g))
    rough = {}
    for lam in (5.0, 20.0):
        p = Params(v, f)
        LargeSteps(p, "m.positions", lr=0.01, lam=lam).step({"m.positions": g})
        rough[lam] = roughness(p.v.astype(np.float64) - v)
    assert adam > 5.0
    assert rough[20.0] < 0.02 * adam and rough[20.0] < rough[5.0] < 0.1 * adam, (rough, adam)
    p = Params(v, f)
    LargeSteps(p, "m.positions", lr=0.01, lam=20.0).step({"m.positions": -v})   # descent: outwards
    step = p.v.astype(np.float64) - v
    size = np.linalg.norm(step, axis=1)
    assert size.mean() > 0.3 * 0.01 and size.std() < 0.03 * size.mean(), (size.mean(), size.std())
    assert np.all(np.sum(step * v, axis=1) > 0.99 * size)         # outwards along the normal


def test_bad_input_is_refused():
    v, f = icosphere(1)
    p = Params(v, f)
    with pytest.raises(ValueError, match="lam must be >= 0"):
        LargeSteps(p, "m.positions", lam=-1.0)
    opt = LargeSteps(p, "m.positions")
    with pytest.raises(ValueError, match=r"shape \(42, 3\)"):
        opt.step({"m.positions": np.zeros((5, 3))})
    with pytest.raises(ValueError, match=r"\(F, 3\)"):
        laplacian(np.zeros((4, 2), int), 4)
