"""Path guiding (issue 24, part 3): the guide's distribution, and the guided integrator's image.

* The directional quadtree's pdf integrates to 1 over the sphere (quadrature in the square, with
  the map's Jacobian), its sampling follows its pdf (chi-square over the quadtree's own cells and
  over a grid that cuts across them) and reports the density it evaluates, and the tree's host
  refinement keeps energies and structure consistent; the learnt alpha is above 0 where the
  learnt light is concentrated above the quadtree's horizon, 0 for cosine-shaped light.
* ``guided`` converges to the same image as ``nee`` (per-block Student t over seeds, the house
  style of tests/integrators/test_light_transport.py) on the Cornell box with its glass and glossy balls, with
  the learnt alpha and with the guide everywhere (alpha 0.5).
* Determinism: the same image bit for bit on 1 and 2 threads and on other tile sizes (learnt alpha
  and a fixed one); the spp budget (training passes included) is respected; renderers that cannot
  train over the whole image refuse it.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp

from warp_spt.integrators.guided.sd_tree import GuideTree, dir_to_square_np, guide_pdf, guide_sample, square_to_dir_np, upload_tree
from warp_spt.integrators import guided
from warp_spt.integrators.guided import tree as guiding_tree
from warp_spt.rendering.settings import RenderSettings

from tests.support.stability_scenes import R, assert_same_image, cornell_camera, cornell_files, load, sky

# --------------------------------------------------------------------------------------------
# The guide's distribution


@wp.kernel
def _sample_kernel(g: GuideTree, root: int, u: wp.array(dtype=wp.vec2), dirs: wp.array(dtype=wp.vec3),
                   pdfs: wp.array(dtype=float)):
    i = wp.tid()
    d, pdf = guide_sample(g, root, u[i])
    dirs[i] = d
    pdfs[i] = pdf
    if wp.abs(guide_pdf(g, root, d) - pdf) > 1.0e-3 * pdf:
        pdfs[i] = -1.0          # sampling and evaluating disagree


@wp.kernel
def _pdf_kernel(g: GuideTree, root: int, dirs: wp.array(dtype=wp.vec3), pdfs: wp.array(dtype=float)):
    i = wp.tid()
    pdfs[i] = guide_pdf(g, root, dirs[i])


def _trained_tree(seed: int = 3) -> guiding_tree.SDTree:
    """A sampling tree refined twice from made-up records: a bright spot, a band and some floor,
    on one spatial leaf (the six normal bins' quadtrees alike)."""
    rng = np.random.default_rng(seed)
    tree = guiding_tree.initial(np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]]))
    sampling = tree
    for k in range(3):
        # records: radiance over the square, evaluated at the centre of every leaf of every quadtree
        energy = np.zeros(tree.dir_nodes, np.int64)
        for root in tree.d_root:
            for n, (lo, size) in _leaves(tree, int(root)):
                c = lo + size / 2
                f = 50.0 * math.exp(-((c[0] - 0.8) ** 2 + (c[1] - 0.3) ** 2) / 0.002) + \
                    5.0 * (abs(c[1] - 0.7) < 0.05) + 0.2 + 0.1 * rng.random()
                energy[n] = int(f * size * size * guiding_tree.ENERGY_SCALE * 1000)
        hits = np.full(tree.dir_nodes, 10, np.int64)
        sampling, tree = guiding_tree.refine(tree, energy, hits, k, c=1e9)
    return sampling


def _leaves(tree, root):
    """(node, (lower corner, size)) of every leaf of the quadtree at ``root``."""
    out, todo = [], [(root, np.zeros(2), 1.0)]
    while todo:
        n, lo, size = todo.pop()
        c = tree.d_child[n]
        if c < 0:
            out.append((n, (lo, size)))
            continue
        h = size / 2
        todo += [(c + ix + 2 * iy, lo + np.array([ix * h, iy * h]), h) for iy in (0, 1) for ix in (0, 1)]
    return out


def test_refined_quadtree_is_consistent():
    tree = _trained_tree()
    assert tree.leaves == 1 and tree.d_root.size == 6
    inner = np.flatnonzero(tree.d_child >= 0)
    c = tree.d_child[inner]
    assert np.allclose(tree.d_energy[inner], sum(tree.d_energy[c + k] for k in range(4)))
    assert (c > inner).all()                               # children after their parent
    assert 50 < len(_leaves(tree, int(tree.d_root[0]))) < 2000


def test_guide_pdf_integrates_to_one_and_matches_its_sampling():
    tree = _trained_tree()
    g = upload_tree(tree, 0.5, "cpu")
    root = int(tree.d_root[2])
    # quadrature over the square: d omega = d area / jacobian (the map's, square_to_dir_np)
    m = 1024
    grid = (np.stack(np.meshgrid(np.arange(m), np.arange(m), indexing="ij"), axis=-1).reshape(-1, 2) + 0.5) / m
    grid_dirs, grid_jac = square_to_dir_np(grid)
    dirs = wp.array(grid_dirs.astype(np.float32), dtype=wp.vec3)
    pdfs = wp.zeros(m * m, dtype=float)
    wp.launch(_pdf_kernel, dim=m * m, inputs=[g, root, dirs, pdfs])
    assert abs((pdfs.numpy().astype(np.float64) / grid_jac).mean() - 1.0) < 2e-3

    # sampling: the pdf each sample reports is the pdf of its direction, and the samples follow it
    n = 400_000
    u = np.random.default_rng(1).random((n, 2)).astype(np.float32)
    out, spdf = wp.zeros(n, dtype=wp.vec3), wp.zeros(n, dtype=float)
    wp.launch(_sample_kernel, dim=n, inputs=[g, root, wp.array(u, dtype=wp.vec2), out, spdf])
    d = out.numpy().astype(np.float64)
    assert np.allclose(np.linalg.norm(d, axis=1), 1.0, atol=1e-5)
    # the density found while sampling is the one evaluated for the direction; the round trip
    # square -> direction -> square may cross a leaf's edge by a rounding error (1 in 400k here)
    assert (spdf.numpy() > 0).mean() > 1 - 1e-4
    s = dir_to_square_np(d)
    # chi-square over the quadtree's own leaves (expected counts: pdf x area) and over a grid
    leaves = _leaves(tree, root)
    expected = np.array([float(tree.d_energy[nd]) for nd, _ in leaves]) / float(tree.d_energy[root]) * n
    counts = np.zeros(len(leaves))
    for i, (_, (lo, size)) in enumerate(leaves):
        counts[i] = np.sum((s[:, 0] >= lo[0]) & (s[:, 0] < lo[0] + size) & (s[:, 1] >= lo[1]) & (s[:, 1] < lo[1] + size))
    _assert_chi2(counts, expected)
    cells = 24
    hist = np.histogram2d(s[:, 0], s[:, 1], bins=cells, range=[[0, 1], [0, 1]])[0].ravel()
    centers = (np.stack(np.meshgrid(np.arange(cells), np.arange(cells), indexing="ij"), -1).reshape(-1, 2) + 0.5) / cells
    fine = 16      # the expected count of each grid cell: the pdf integrated by a finer midpoint rule
    sub = (np.stack(np.meshgrid(np.arange(fine), np.arange(fine), indexing="ij"), -1).reshape(-1, 2) + 0.5) / (fine * cells)
    pts = (centers[:, None, :] - 0.5 / cells + sub[None, :, :]).reshape(-1, 2)
    pd = wp.zeros(len(pts), dtype=float)
    pts_dirs, pts_jac = square_to_dir_np(pts)
    wp.launch(_pdf_kernel, dim=len(pts), inputs=[g, root, wp.array(pts_dirs.astype(np.float32), dtype=wp.vec3), pd])
    exp_grid = (pd.numpy().astype(np.float64) / pts_jac).reshape(cells * cells, -1).mean(axis=1) / cells**2 * n
    _assert_chi2(hist, exp_grid)


def _assert_chi2(counts: np.ndarray, expected: np.ndarray) -> None:
    """Pearson's chi-square over the cells with an expected count >= 5 (the rest pooled), at 1e-4."""
    keep = expected >= 5
    c = np.append(counts[keep], counts[~keep].sum())
    e = np.append(expected[keep], expected[~keep].sum())
    if e[-1] < 5:
        c, e = c[:-1], e[:-1]
    chi2 = float(((c - e) ** 2 / e).sum())
    dof = len(c) - 1
    # Wilson-Hilferty: the 1e-4 upper quantile of chi-square with dof degrees of freedom
    z = 3.719
    bound = dof * (1 - 2 / (9 * dof) + z * math.sqrt(2 / (9 * dof))) ** 3
    assert chi2 < bound, f"chi-square {chi2:.1f} over {dof} degrees of freedom (bound {bound:.1f})"


# --------------------------------------------------------------------------------------------
# The guided integrator's image

SIZE, SPP, SEEDS = 16, 16, 10


@pytest.fixture(scope="module")
def cornell(scene_dir):
    return load(*cornell_files(scene_dir))


def _render(dev, **kw) -> "R.RenderResult":
    kw = {"width": SIZE, "height": SIZE, "spp": SPP, "max_depth": 5, "sky": sky(0.0), **kw}
    res = R.render_scene(dev, cornell_camera(), RenderSettings(**kw))
    assert res.stats.dropped_samples == 0
    return res


def test_training_passes_fit_the_budget():
    assert guided.training_passes(1) == [1]
    assert guided.training_passes(4) == [1, 1, 2]
    assert guided.training_passes(16) == [1, 1, 2, 4, 8]
    assert guided.training_passes(64) == [1, 1, 2, 4, 8, 16, 32]
    assert guided.training_passes(100) == [1, 1, 2, 4, 8, 16, 68]
    assert all(sum(guided.training_passes(n)) == n for n in range(1, 300))
    # every pass but the last is an aligned block of the sample sequence (a Sobol' net of its own)
    starts = np.cumsum([0] + guided.training_passes(64))[:-1]
    assert all(s % n == 0 for s, n in zip(starts, guided.training_passes(64)))


@pytest.mark.parametrize("alpha", [None, 0.5], ids=["learnt-alpha", "alpha-0.5"])
def test_guided_converges_to_the_same_image_as_nee(cornell, alpha):
    # the Cornell box of the stability suite: diffuse walls, a glossy and a glass ball, a ceiling light;
    # alpha None: learnt per quadtree (here mostly 0, and training stops); 0.5: the guide everywhere
    ref = np.stack([_render(cornell, integrator="nee", seed=500 + k).image for k in range(SEEDS)])
    out = np.stack([_render(cornell, integrator="guided", seed=700 + k, integrator_options={"alpha": alpha}).image
                    for k in range(SEEDS)])
    assert_same_image(ref, out, "guided vs nee")


@pytest.mark.parametrize("alpha", [None, 0.25], ids=["learnt-alpha", "alpha-0.25"])
def test_guided_is_deterministic_and_keeps_the_budget(cornell, alpha):
    opts = {"alpha": alpha}
    one = _render(cornell, integrator="guided", threads=1, spp=12, integrator_options=opts)
    two = _render(cornell, integrator="guided", threads=2, spp=12, tile_pixels=40, integrator_options=opts)
    assert np.array_equal(one.film.sum, two.film.sum)
    assert one.film.spp == 12 and one.stats.pixel_samples == SIZE * SIZE * 12
    if alpha:
        # the guide is used: without it (alpha 0) the same samples give another image
        off = _render(cornell, integrator="guided", threads=1, spp=12, integrator_options={"alpha": 0.0})
        assert not np.array_equal(one.film.sum, off.film.sum)


def test_learnt_alpha_follows_the_guides_benefit():
    # a quadtree whose learnt radiance is a bright spot gets the guide; one with a uniform sky does not
    tree = _trained_tree()
    hits = np.full(tree.dir_nodes, 1000, np.int64)
    alpha = guiding_tree.quadtree_alpha(tree, hits)
    assert alpha[4] > 0 and alpha[0] == 0     # the spot is above the +z bin's horizon (4), below +x's (0)
    flat = guiding_tree.SDTree(tree.lo, tree.hi, tree.s_axis, tree.s_child, tree.d_root, tree.d_child,
                               _cosine_energies(tree))
    assert (guiding_tree.quadtree_alpha(flat, hits) == 0).all()
    assert guiding_tree.quadtree_alpha(tree, np.zeros(tree.dir_nodes, np.int64)).max() == 0    # too few records


def _cosine_energies(tree) -> np.ndarray:
    """Energies of a constant radiance times the cosine to each quadtree's axis (what cosine sampling matches)."""
    node, q, corner, size = guiding_tree._quadtree_leaves(tree.d_child, tree.d_root)
    sub = 8
    grid = (np.stack(np.meshgrid(np.arange(sub), np.arange(sub), indexing="ij"), -1).reshape(-1, 2) + 0.5) / sub
    dirs, jac = square_to_dir_np(corner[:, None, :] + grid[None] * size[:, None, None])
    b = q % 6
    cos = np.maximum(dirs[np.arange(len(b))[:, None], np.arange(sub * sub)[None], b[:, None] // 2]
                     * np.where(b % 2 == 0, 1.0, -1.0)[:, None], 0.0)
    e = np.zeros(tree.dir_nodes)
    e[node] = (cos / jac).sum(axis=1) * (size * size / sub**2)
    return guiding_tree.summed(tree, e)


def test_renderers_that_split_the_image_refuse_guided(cornell):
    with pytest.raises(ValueError, match="whole image"):
        R.render_scene(cornell, cornell_camera(), RenderSettings(width=8, height=8, spp=2, integrator="guided"),
                       rows=(0, 4))
    from warp_spt.rendering.progressive import render_progressive
    with pytest.raises(ValueError, match="render_progressive cannot render it"):
        render_progressive(cornell, cornell_camera(), width=8, height=8, spp=4, integrator="guided")
