"""The device intersector against analytic ray-sphere and ray-triangle intersections computed in numpy."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from warp_spt.upload.device_scene import DeviceScene, Features, Geometry
from warp_spt.accel.ray_queries import SMALL_SCENE, make_closest_hit, make_occluded
from warp_spt.io.loader import load_scene

from tests.support.scenes import box_obj, write_scene_files

_closest = make_closest_hit(Features.general())
_occluded = make_occluded(Features.general())


@wp.kernel(enable_backward=False)
def _cast(s: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3),
          t: wp.array(dtype=float), kind: wp.array(dtype=int), index: wp.array(dtype=int)):
    i = wp.tid()
    h = _closest(s, o[i], d[i], 3.0e38)
    t[i] = h.t
    kind[i] = h.kind
    index[i] = h.index


@wp.kernel(enable_backward=False)
def _shadow(s: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3),
            t_max: wp.array(dtype=float), blocked: wp.array(dtype=int)):
    i = wp.tid()
    blocked[i] = wp.where(_occluded(s, o[i], d[i], t_max[i]), 1, 0)


def cast(scene: DeviceScene, o: np.ndarray, d: np.ndarray):
    n = len(o)
    t = wp.zeros(n, dtype=float)
    kind = wp.zeros(n, dtype=int)
    index = wp.zeros(n, dtype=int)
    wp.launch(_cast, dim=n, inputs=[scene.geometry, wp.array(o.astype(np.float32), dtype=wp.vec3),
                                    wp.array(d.astype(np.float32), dtype=wp.vec3), t, kind, index])
    return t.numpy(), kind.numpy(), index.numpy()


def _sphere_t(o, d, c, r):
    oc = o - c
    b = np.einsum("ij,ij->i", oc, d)
    disc = b * b - (np.einsum("ij,ij->i", oc, oc) - r * r)
    sq = np.sqrt(np.maximum(disc, 0))
    t0, t1 = -b - sq, -b + sq
    t = np.where(t0 > 0, t0, np.where(t1 > 0, t1, np.inf))
    return np.where(disc >= 0, t, np.inf)


def _triangle_t(o, d, p0, p1, p2):
    e1, e2 = p1 - p0, p2 - p0
    n = np.cross(e1, e2)
    denom = d @ n
    t = ((p0 - o) @ n) / np.where(denom == 0, np.nan, denom)
    p = o + t[:, None] * d
    # barycentric inside test by area signs
    c0 = np.cross(p1 - p0, p - p0) @ n
    c1 = np.cross(p2 - p1, p - p1) @ n
    c2 = np.cross(p0 - p2, p - p2) @ n
    inside = (c0 >= 0) & (c1 >= 0) & (c2 >= 0) & (t > 0)
    return np.where(inside, t, np.inf)


@pytest.fixture(scope="module")
def mixed(scene_dir):
    obj = ("v -3 4 -3\nv 3 4 -3\nv 0 4 3\nv 10 10 10\nv 11 10 10\nv 10 11 10\n"
           "f 1 2 3\nf 4 5 6\n"
           "b 0 8 0 1.5\nb 2 -6 1 0.5\nb -4 0 0 2\n")
    objs, _ = write_scene_files(scene_dir, "mixed", obj)
    return DeviceScene(load_scene(objs, []))


def _random_rays(rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Origins uniform in [-8, 8]^3 and uniformly distributed unit directions."""
    o = rng.uniform(-8, 8, size=(n, 3))
    d = rng.normal(size=(n, 3))
    return o, d / np.linalg.norm(d, axis=1, keepdims=True)


def test_random_rays_match_analytic_intersections(mixed):
    n = 20000
    o, d = _random_rays(np.random.default_rng(5), n)
    o32, d32 = o.astype(np.float32).astype(np.float64), d.astype(np.float32).astype(np.float64)
    spheres = [((0, 8, 0), 1.5), ((2, -6, 1), 0.5), ((-4, 0, 0), 2.0)]
    tri = [np.array(p, float) for p in ((-3, 4, -3), (3, 4, -3), (0, 4, 3))]
    tri2 = [np.array(p, float) for p in ((10, 10, 10), (11, 10, 10), (10, 11, 10))]
    cands = [_triangle_t(o32, d32, *tri), _triangle_t(o32, d32, *tri2)]
    cands += [_sphere_t(o32, d32, np.array(c, float), r) for c, r in spheres]
    ref = np.min(cands, axis=0)
    which = np.argmin(cands, axis=0)
    t, kind, index = cast(mixed, o, d)
    hit = np.isfinite(ref)
    assert hit.sum() > 1000      # enough hits for the comparison to mean something
    # rays passing within float32 rounding of an edge or silhouette may go either way: allow a few
    agree = (kind >= 0) == hit
    assert agree.mean() > 0.9995
    both = hit & (kind >= 0)
    assert np.allclose(t[both], ref[both], rtol=1e-4, atol=1e-4)
    expect_kind = np.where(which < 2, 0, 1)
    assert (kind[both] == expect_kind[both]).mean() > 0.9995
    sph = both & (kind == 1)
    assert (index[sph] == which[sph] - 2).mean() > 0.9995


def test_tiny_sphere_far_away_is_hit_at_the_right_distance(scene_dir):
    objs, _ = write_scene_files(scene_dir, "tiny", "b 0 1000 0 0.01\n")
    t, kind, _ = cast(DeviceScene(load_scene(objs, [])), np.array([[0.0, 0, 0]]), np.array([[0.0, 1, 0]]))
    assert kind[0] == 1
    assert abs(t[0] - 999.99) < 1e-3


def test_ray_from_inside_sphere_hits_far_side(scene_dir):
    objs, _ = write_scene_files(scene_dir, "inside", "b 0 0 0 2\n")
    t, kind, _ = cast(DeviceScene(load_scene(objs, [])), np.array([[0.5, 0, 0]]), np.array([[1.0, 0, 0]]))
    assert kind[0] == 1 and abs(t[0] - 1.5) < 1e-6


def test_any_hit_occlusion_agrees_with_the_closest_hit(mixed):
    # A shadow ray to distance t_max is blocked exactly when the closest hit lies before t_max.
    rng = np.random.default_rng(9)
    n = 20000
    o, d = _random_rays(rng, n)
    t, kind, _ = cast(mixed, o, d)
    t_max = rng.uniform(0.0, 25.0, size=n).astype(np.float32)
    blocked = wp.zeros(n, dtype=int)
    wp.launch(_shadow, dim=n, inputs=[mixed.geometry, wp.array(o.astype(np.float32), dtype=wp.vec3),
                                      wp.array(d.astype(np.float32), dtype=wp.vec3),
                                      wp.array(t_max, dtype=float), blocked])
    expected = (kind >= 0) & (t < t_max)
    clear = np.abs(t - t_max) > 1e-4 * np.maximum(1.0, t_max)     # ties at t == t_max may go either way
    got = blocked.numpy().astype(bool)
    assert expected[clear].sum() > 500 and (~expected[clear]).sum() > 500
    assert np.array_equal(got[clear], expected[clear])


# --- small scenes: the loop over items (no TLAS) against the TLAS traversal -------------------------

_loop_hit, _tlas_hit = make_closest_hit(Features.general()), make_closest_hit(Features.general(), small_scene=0)
_loop_occ, _tlas_occ = make_occluded(Features.general()), make_occluded(Features.general(), small_scene=0)


def _hit_kernel(closest, occluded):
    @wp.kernel(enable_backward=False, module="unique")
    def k(s: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), t_max: wp.array(dtype=float),
          tuv: wp.array(dtype=wp.vec3), ids: wp.array(dtype=wp.vec4i), normal: wp.array(dtype=wp.vec3)):
        i = wp.tid()
        h = closest(s, o[i], d[i], 3.0e38)
        tuv[i] = wp.vec3(h.t, h.u, h.v)
        ids[i] = wp.vec4i(h.kind, h.index, h.face, wp.where(occluded(s, o[i], d[i], t_max[i]), 1, 0))
        normal[i] = h.normal
    return k


_KERNELS = {}


def _loop_and_tlas(scene: DeviceScene, o: np.ndarray, d: np.ndarray, t_max: np.ndarray):
    """(t u v, kind index face occluded, normal) per ray from the item loop and from the TLAS."""
    n = len(o)
    args = [scene.geometry, wp.array(o.astype(np.float32), dtype=wp.vec3),
            wp.array(d.astype(np.float32), dtype=wp.vec3), wp.array(t_max.astype(np.float32), dtype=float)]
    results = []
    for fns in ((_loop_hit, _loop_occ), (_tlas_hit, _tlas_occ)):
        if fns not in _KERNELS:
            _KERNELS[fns] = _hit_kernel(*fns)
        outs = [wp.zeros(n, dtype=wp.vec3), wp.zeros(n, dtype=wp.vec4i), wp.zeros(n, dtype=wp.vec3)]
        wp.launch(_KERNELS[fns], dim=n, inputs=args + outs)
        results.append([a.numpy() for a in outs])
    return results


def _soup_obj(rng: np.random.Generator, n: int) -> str:
    """n random triangles in [-3, 3]^3 plus a closed box around them: one OBJ, so one mesh."""
    p = rng.uniform(-3, 3, size=(n, 1, 3)) + rng.normal(scale=0.6, size=(n, 3, 3))
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in p.reshape(-1, 3)]
    lines += [f"f {3 * k + 1} {3 * k + 2} {3 * k + 3}" for k in range(n)]
    box = [ln for ln in box_obj((-5, -5, -5), (5, 5, 5), subdivide=2).splitlines() if ln[:2] in ("v ", "f ")]
    shift = 3 * n
    lines += [ln for ln in box if ln.startswith("v ")]
    lines += ["f " + " ".join(str(int(v) + shift) for v in ln.split()[1:]) for ln in box if ln.startswith("f ")]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("which", ["one mesh", "mesh and spheres"])
def test_small_scene_loop_equals_the_tlas_traversal(scene_dir, mixed, which):
    # Small scenes skip the TLAS; every hit, and every shadow-ray answer, must be what the TLAS
    # traversal gives, bit for bit, for rays from inside and outside the scene.
    rng = np.random.default_rng(21)
    if which != "mesh and spheres":     # a large mesh: above the 100k triangles once traced by Warp's BVH only
        objs, _ = write_scene_files(scene_dir, "soup", _soup_obj(rng, 3000 if which == "one mesh" else 150_000))
        scene = DeviceScene(load_scene(objs, [], warn=lambda message: None))
        assert len(scene.scene.meshes) == 1 and len(scene.scene.spheres) == 0
    else:
        scene = mixed                  # one mesh of two triangles, three spheres
    assert 1 <= scene.tlas.items.shape[0] <= SMALL_SCENE       # the loop is what runs
    n = 40000
    o, d = _random_rays(rng, n)
    o[: n // 4] *= 3.0                  # a quarter start far outside (and outside the TLAS root box)
    (tuv, ids, nrm), (tuv_ref, ids_ref, nrm_ref) = _loop_and_tlas(scene, o, d, rng.uniform(0.0, 12.0, size=n))
    hits = ids_ref[:, 0] >= 0
    assert hits.sum() > 1000 and (~hits).sum() > 1000 and 500 < ids_ref[:, 3].sum() < n - 500
    # kind, index, occluded and t for every ray; the normal for every hit; face and barycentrics
    # for triangle hits (a sphere hit leaves them as they were: meaningless, and order-dependent)
    assert np.array_equal(ids[:, [0, 1, 3]], ids_ref[:, [0, 1, 3]]) and np.array_equal(tuv[:, 0], tuv_ref[:, 0])
    assert np.array_equal(nrm[hits], nrm_ref[hits])
    tri = ids_ref[:, 0] == 0
    assert tri.sum() > 500 and np.array_equal(ids[tri, 2], ids_ref[tri, 2]) and np.array_equal(tuv[tri], tuv_ref[tri])


# --- our wide BVHs against Warp's BVH (wp.mesh_query_ray) ---------------------------------------


@pytest.mark.parametrize("which", ["one mesh", "mesh and spheres", "a large mesh"])
def test_wide_bvh_answers_as_warps_bvh(scene_dir, mixed, which):
    # Meshes are traced through our wide BVHs (accel.wide_traversal), or through Warp's when larger than
    # the scene's limit (0 here: all of them). Same triangle test, so every hit, normal and shadow-ray
    # answer must agree bit for bit; only exact ties in t between two triangles may pick another face.
    rng = np.random.default_rng(5)
    if which != "mesh and spheres":     # a large mesh: above the 100k triangles once traced by Warp's BVH only
        objs, _ = write_scene_files(scene_dir, "soup", _soup_obj(rng, 3000 if which == "one mesh" else 150_000))
        host = load_scene(objs, [], warn=lambda message: None)
    else:
        host = mixed.scene
    wide, warp = DeviceScene(host), DeviceScene(host, wide_bvh_max_triangles=0)
    assert wide.features.bvh_stack > 0 and not wide.features.warp_meshes
    assert warp.features.bvh_stack == 0 and warp.features.warp_meshes
    n = 40000
    o, d = _random_rays(rng, n)
    o[: n // 4] *= 3.0
    t_max = rng.uniform(0.0, 12.0, size=n)
    got = [_loop_and_tlas(s, o, d, t_max) for s in (wide, warp)]
    for (tuv, ids, nrm), (tuv_ref, ids_ref, nrm_ref) in zip(got[0], got[1]):     # the item loop, then the TLAS
        tri = ids_ref[:, 0] == 0
        assert tri.sum() > 500 and np.array_equal(ids[:, [0, 1, 3]], ids_ref[:, [0, 1, 3]])
        assert np.array_equal(tuv[:, 0], tuv_ref[:, 0])
        same = tri & (ids[:, 2] == ids_ref[:, 2])
        assert (tri & ~same).sum() <= 2          # ties: the same t, another face
        assert np.array_equal(tuv[same], tuv_ref[same]) and np.array_equal(nrm[same], nrm_ref[same])
