"""The light tree (issue 34, many lights): a floor under 160 small lamps, rendered by NEE choosing
among their 320 triangles with the tree, against Lambert's closed form summed over the lamps;
sampling and the density MIS evaluates agree (the pdf of a sampled direction is the pdf_li of the
hit it makes); and the tree's build is a proper binary tree whose leaves are the lights."""

from __future__ import annotations

import numpy as np

from warp_spt.emitters.light_tree import MIN_TREE_LIGHTS, build_tree
from warp_spt.emitters import light_table

from tests.support.scenes import material
from tests.support.stability_scenes import GENERAL, quads_obj, scene_from_text, sky
from tests.integrators.test_light_transport import (
    ALBEDO,
    FLOOR,
    FLOOR_CAM,
    assert_matches_expected,
    floor_points,
    polygon_irradiance,
    seed_batches,
)

LZ, HALF, L = 0.6, 0.06, 40.0
XS, YS = np.linspace(-4.0, 4.0, 16), np.linspace(-2.0, 6.0, 10)


def lamps():
    return [[(x - HALF, y - HALF, LZ), (x + HALF, y - HALF, LZ), (x + HALF, y + HALF, LZ), (x - HALF, y + HALF, LZ)]
            for x in XS.tolist() for y in YS.tolist()]


def test_many_lamps_over_a_floor_match_the_closed_form(scene_dir):
    quads = lamps()
    obj = quads_obj([("floor", FLOOR)] + [("lamp", q) for q in quads])
    mtl = material("floor", Kd=(ALBEDO,) * 3, Roughness=1) + material("lamp", Kd=(0, 0, 0), Kl=(L,) * 3)
    dev = scene_from_text(scene_dir, "many_lamps", obj, mtl)
    assert dev.features.lit("triangle.tree") and len(quads) * 2 >= MIN_TREE_LIGHTS
    table = light_table(dev, sky(0.0))
    assert table.num_entries == 1 and table.triangle.use_tree == 1      # the tree chooses the triangle
    w, h = 12, 10
    pts = floor_points(FLOOR_CAM, w, h, 8)
    # pixels whose camera rays may pass a lamp before the floor are left out (they see the lamp itself;
    # 0.05: a margin for the jittered rays between the 8x8 grid points, foreshortened along y)
    o = np.asarray(FLOOR_CAM.position, float)
    at = o + (pts - o) * ((LZ - o[2]) / (pts[..., 2] - o[2]))[..., None]
    near = np.min(np.maximum(np.abs(at[..., 0, None] - XS[None, None, None, :].repeat(len(YS), -1).reshape(1, 1, 1, -1)),
                             np.abs(at[..., 1, None] - np.tile(YS, len(XS))[None, None, None, :])), axis=-1)
    clear = (near > HALF + 0.05).all(axis=2)
    e = sum(polygon_irradiance(pts.reshape(-1, 3), np.array([0.0, 0.0, 1.0]), np.array(q)) for q in quads)
    expected = ALBEDO / np.pi * L * e.reshape(h, w, -1).mean(axis=2)
    b = seed_batches(dev, FLOOR_CAM, 12, 256, 0, width=w, height=h, max_depth=2, sky=sky(0.0),
                     integrator="nee", features=GENERAL)
    assert clear.sum() > 30
    assert_matches_expected(b[:, clear][:, :, None], np.repeat(expected[clear][:, None, None], 3, axis=2),
                            rel_slack=0.01)


def test_tree_sampling_density_is_what_mis_evaluates(scene_dir):
    # from points under the lamps (none hides another) every light sample's reported density equals
    # the density pdf_li gives the hit along its direction (the leaf's path recomputed from x), and
    # E[g / pdf] over the samples is the integral of g over the lamps' solid angles (quadrature)
    import warp as wp

    from tests.integrators.test_light_transport import _pdf_kernels, sphere_directions

    quads = lamps()
    obj = quads_obj([("lamp", q) for q in quads])
    dev = scene_from_text(scene_dir, "lamps_only", obj, material("lamp", Kd=(0, 0, 0), Kl=(L,) * 3))
    lights = light_table(dev, sky(0.0))
    assert lights.triangle.use_tree == 1
    k = _pdf_kernels()
    for where in [(0.1, 0.2, 0.0), (-3.0, 5.5, 0.4)]:
        x = wp.vec3(*where)
        n = 100_000
        u = np.random.default_rng(0).random((n, 3)).astype(np.float32)
        res = [wp.zeros(n, dtype=t) for t in (wp.vec3, float, float, int)]
        wp.launch(k["sample"], dim=n, inputs=[dev.geometry, dev.materials, dev.textures(), lights, x,
                                              wp.array(u, dtype=wp.vec3), *res])
        d, pdf, pdf_eval, vis = (r.numpy().astype(np.float64) for r in res)
        assert (vis > 0).mean() > 0.999 and (pdf > 0).all()
        assert np.allclose(pdf, pdf_eval, rtol=2e-3)
        dirs = sphere_directions(1_000_000)
        out = wp.zeros(len(dirs), dtype=float)
        wp.launch(k["evaluate"], dim=len(dirs), inputs=[dev.geometry, lights, x,
                                                        wp.array(dirs.astype(np.float32), dtype=wp.vec3), out])
        on = out.numpy() > 0
        g = 2 + d[:, 2] + d[:, 0] ** 2
        est = g / pdf
        covered = ((2 + dirs[:, 2] + dirs[:, 0] ** 2) * on).sum() * 4 * np.pi / len(dirs)
        # the quadrature's own error: lamps' edges cut the lattice (about 1% here)
        assert abs(est.mean() - covered) < 5 * est.std() / np.sqrt(n) + 0.02 * covered, (est.mean(), covered)


def test_tree_build_is_a_binary_tree_over_the_lights():
    rng = np.random.default_rng(1)
    corners = rng.uniform(-5, 5, size=(37, 3, 3))
    power = rng.uniform(0.1, 2.0, size=37)
    t = build_tree(corners, power)
    inner = t["left"] >= 0
    assert inner.sum() == 36 and (t["right"][inner] >= 0).all()
    assert sorted(t["entry"][~inner]) == list(range(37))
    assert np.allclose(t["power"][0], power.sum())
    for node in np.nonzero(inner)[0]:
        l, r = t["left"][node], t["right"][node]
        assert t["parent"][l] == node and t["parent"][r] == node
        assert np.isclose(t["power"][node], t["power"][l] + t["power"][r])
        assert (t["lower"][node] <= np.minimum(t["lower"][l], t["lower"][r])).all()
    assert (t["entry"][t["leaf"]] == np.arange(37)).all()
