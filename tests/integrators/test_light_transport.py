"""Light transport against independent checks (issue 8).

* NEE alone against closed-form direct lighting: a diffuse plane under a small square emitter
  (Lambert's polygon irradiance, integrated over each pixel's footprint in numpy) and under a
  uniform sky (reflected radiance = albedo x sky).
* Furnaces per integrator: a closed box whose walls all emit E and reflect A gives E * sum A^k.
* Every light's and every lobe's pdf integrates to 1 over the sphere (quadrature of the evaluated
  pdf), sampling agrees with evaluating (the density ``sample`` reports is the one ``pdf`` gives for
  that direction) and the samples follow it (E[g / pdf] = integral of g).
* Every integrator x sampler converges to the same image (per-block Student-t over several seeds).

One kernel per (integrator, sampler) serves every scene here (Features.general(), shared with the
stability suite); images are tiny.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp
from PIL import Image

from warp_spt.upload.device_scene import Geometry, Materials, Textures
from warp_spt.accel.ray_queries import KIND_MISS, NO_HIT, make_closest_hit
from warp_spt.emitters import Lights, light_table, make_lights
from warp_spt.bsdfs import make_materials
from warp_spt.accel.surface import Surface, make_surface
from warp_spt.rendering.settings import RenderSettings
from warp_spt.samplers import SAMPLERS
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

from tests.support.combos import every_pair
from tests.support.scenes import box_obj, material
from tests.support.stability_scenes import (
    GENERAL,
    R,
    assert_same_image,
    cornell_camera,
    cornell_files,
    load,
    quads_obj,
    render_checked,
    scene_from_text,
    sky,
    t_quantile,
)

COMBOS = every_pair()      # a covering set in the default tier, the other pairs slow (tests/support/combos.py)


def seed_batches(scene, camera, batches: int, spp: int, first_seed: int, **kw) -> np.ndarray:
    """(K, H, W, 3): K independent renders (different seeds: Sobol' batches of one seed are not independent)."""
    return np.stack([render_checked(scene, camera, spp=spp, seed=first_seed + k, **kw) for k in range(batches)])


def assert_matches_expected(batches: np.ndarray, expected: np.ndarray, rel_slack: float = 0.0,
                            alpha: float = 1e-4) -> None:
    """Every pixel's mean over the batches equals ``expected`` within a Student-t bound (Bonferroni
    over pixels and channels) plus ``rel_slack`` of the expectation (the reference's own error)."""
    k = batches.shape[0]
    mean = batches.mean(axis=0)
    se = batches.std(axis=0, ddof=1) / math.sqrt(k)
    bound = t_quantile(alpha / (2 * mean.size), k - 1)
    err = np.abs(mean - expected)
    ok = err <= bound * se + rel_slack * np.abs(expected) + 1e-6
    assert ok.all(), (f"{(~ok).sum()} pixel channels off; worst |err| / se = "
                      f"{np.max((err - rel_slack * np.abs(expected)) / np.maximum(se, 1e-12)):.2f} (bound {bound:.2f})")


# --------------------------------------------------------------------------------------------
# NEE against analytic direct lighting

FLOOR = [(-30.0, -30.0, 0.0), (30.0, -30.0, 0.0), (30.0, 30.0, 0.0), (-30.0, 30.0, 0.0)]
LAMP_Z, LAMP_HALF, LAMP_L, ALBEDO = 2.0, 0.5, 10.0, 0.6
# the lamp's winding faces UP: the floor sees its back face (two-sided emitters, as in the seed)
LAMP = [(-LAMP_HALF, -LAMP_HALF, LAMP_Z), (LAMP_HALF, -LAMP_HALF, LAMP_Z), (LAMP_HALF, LAMP_HALF, LAMP_Z),
        (-LAMP_HALF, LAMP_HALF, LAMP_Z)]
FLOOR_CAM = Camera(position=(0.0, -3.0, 2.5), direction=(0.0, 3.0, -2.5), fov=36.0, aperture=0.0, focus=4.0)


def polygon_irradiance(x: np.ndarray, n: np.ndarray, verts: np.ndarray) -> np.ndarray:
    """Irradiance at points x (N, 3) with normal n from a polygon of unit radiance (Lambert's
    formula: half the sum over edges of the edge's angle times the cosine of its plane's normal)."""
    total = np.zeros(len(x))
    for i in range(len(verts)):
        a = verts[i] - x
        b = verts[(i + 1) % len(verts)] - x
        a /= np.linalg.norm(a, axis=1, keepdims=True)
        b /= np.linalg.norm(b, axis=1, keepdims=True)
        c = np.cross(a, b)
        theta = np.arccos(np.clip((a * b).sum(1), -1, 1))
        total += theta * (c @ n) / np.linalg.norm(c, axis=1)
    return np.abs(total) / 2


def floor_points(cam: Camera, w: int, h: int, sub: int) -> np.ndarray:
    """Where sub x sub jittered-grid rays of each pixel meet the plane z = 0: (h, w, sub*sub, 3)."""
    f = cam.frame(w, h)
    o = np.asarray(f["origin"], float)
    s = (np.arange(sub) + 0.5) / sub
    x = np.arange(w)[None, :, None, None] + s[None, None, :, None]
    y = np.arange(h)[:, None, None, None] + s[None, None, None, :]
    x, y = np.broadcast_arrays(x, y)
    p = f["upper_left"] + x[..., None] * f["x_step"] - y[..., None] * f["y_step"]
    d = (p - o).reshape(h, w, sub * sub, 3)
    t = -o[2] / d[..., 2]
    assert (t > 0).all(), "every ray must go down to the floor"
    at_lamp = o + (LAMP_Z - o[2]) / d[..., 2, None] * d
    assert (np.abs(at_lamp[..., :2]).max(axis=-1) > LAMP_HALF).all(), "no ray may pass the lamp"
    return o + t[..., None] * d


def test_nee_matches_polygon_irradiance(scene_dir):
    # Direct light only (depth 2: floor, then lamp), black sky. Expected pixel = mean over its
    # footprint of albedo / pi * L * E(x), E from the closed form; 8x8 points per pixel.
    obj = quads_obj([("floor", FLOOR), ("lamp", LAMP)])
    mtl = material("floor", Kd=(ALBEDO,) * 3, Roughness=1) + material("lamp", Kd=(0, 0, 0), Kl=(LAMP_L,) * 3)
    dev = scene_from_text(scene_dir, "lamp_floor", obj, mtl)
    w, h = 12, 10
    pts = floor_points(FLOOR_CAM, w, h, 8)
    e = polygon_irradiance(pts.reshape(-1, 3), np.array([0.0, 0.0, 1.0]), np.array(LAMP)).reshape(h, w, -1)
    expected = np.repeat((ALBEDO / np.pi * LAMP_L * e.mean(axis=2))[..., None], 3, axis=2)
    coarse = floor_points(FLOOR_CAM, w, h, 4)
    e4 = polygon_irradiance(coarse.reshape(-1, 3), np.array([0.0, 0.0, 1.0]), np.array(LAMP)).reshape(h, w, -1)
    ref_err = np.max(np.abs(e4.mean(axis=2) - e.mean(axis=2)) / e.mean(axis=2))   # footprint quadrature error
    for sampler in sorted(SAMPLERS):
        b = seed_batches(dev, FLOOR_CAM, 8, 16, 0, width=w, height=h, max_depth=2, sky=sky(0.0),
                         integrator="nee", sampler=sampler, features=GENERAL)
        assert_matches_expected(b, expected, rel_slack=ref_err)
    assert expected.max() > 3 * expected.min() > 0        # the lighting really varies over the image


def test_nee_with_a_light_too_unlikely_to_share_its_pick_number(scene_dir):
    # A tiny bright lamp (each triangle chosen with probability < 2**-12) beside a dim sky that the
    # table weighs heavily (a 600-unit floor makes the scene's radius large): Sobol' NEE must then
    # draw the lamp's point from a dimension of its own (lights.reuse_pick < 0). The lamp subtends
    # ~1e-4 sr, so NEE, not BSDF sampling, carries its light (MIS weight ~1). It stands in the plane
    # x = 0, which holds the camera, so no camera ray sees it (edge-on). A floor point receives
    # S (pi - P) + L P, P the lamp's projected solid angle (Lambert's polygon formula, unit radiance).
    # Checked by breaking it: the -1 sentinel used as the point's coordinate fails by 1e9 standard
    # errors. Where on so small a lamp the point lands barely matters (the light's radiance hardly
    # varies over it), so the distribution of the extra number is left to tests/samplers/test_sobol.py.
    sky_l, lamp_l, half, z0 = 0.0045, 2.0e4, 0.005, 0.8
    lamp = [(0.0, -half, z0), (0.0, half, z0), (0.0, half, z0 + 2 * half), (0.0, -half, z0 + 2 * half)]
    obj = quads_obj([("floor", [(10 * x, 10 * y, z) for x, y, z in FLOOR]), ("lamp", lamp)])
    mtl = material("floor", Kd=(ALBEDO,) * 3, Roughness=1) + material("lamp", Kd=(0, 0, 0), Kl=(lamp_l,) * 3)
    dev = scene_from_text(scene_dir, "tiny_lamp_floor", obj, mtl)
    prob = light_table(dev, sky(sky_l)).entry_prob.numpy()
    assert len(prob) == 3 and (prob[:2] < 2.0**-12).all() and (prob[:2] > 2.0**-13).all()   # the branch under test
    w, h, spp, batches = 4, 2, 1 << 14, 12

    def expected_at(sub):
        pts = floor_points(FLOOR_CAM, w, h, sub)
        p = polygon_irradiance(pts.reshape(-1, 3), np.array([0.0, 0.0, 1.0]), np.array(lamp)).reshape(h, w, -1)
        return (ALBEDO / np.pi * (sky_l * (np.pi - p) + lamp_l * p)).mean(axis=2)

    e8, e4 = expected_at(8), expected_at(4)
    assert e8.min() > 3 * ALBEDO * sky_l            # the lamp's light dominates every pixel
    for sampler in sorted(SAMPLERS):
        b = seed_batches(dev, FLOOR_CAM, batches, spp, 0, width=w, height=h, max_depth=2, sky=sky(sky_l),
                         integrator="nee", sampler=sampler, features=GENERAL)
        assert_matches_expected(b, np.repeat(e8[..., None], 3, axis=2), rel_slack=np.max(np.abs(e4 - e8) / e8))


@pytest.mark.parametrize("integrator,sampler", COMBOS)
def test_diffuse_plane_under_a_uniform_sky(scene_dir, integrator, sampler):
    # Every floor point sees the sky over its whole upper hemisphere: radiance = albedo * L exactly.
    dev = scene_from_text(scene_dir, "floor_only", quads_obj([("floor", FLOOR)]),
                          material("floor", Kd=(0.3, 0.5, 0.7), Roughness=1))
    b = seed_batches(dev, FLOOR_CAM, 8, 8, 0, width=8, height=8, max_depth=2, sky=sky(2.0),
                     integrator=integrator, sampler=sampler, features=GENERAL)
    assert_matches_expected(b, np.broadcast_to(2.0 * np.array([0.3, 0.5, 0.7]), b.shape[1:]))


# --------------------------------------------------------------------------------------------
# Furnaces

INSIDE = Camera(position=(0.1, -0.3, 0.2), direction=(0.3, 1.0, 0.1), fov=120.0, aperture=0.0, focus=1.0)


@pytest.mark.parametrize("integrator,sampler", COMBOS)
@pytest.mark.parametrize("roughness", [1.0, 0.6])
def test_furnace_per_integrator(scene_dir, integrator, sampler, roughness):
    # Every wall emits E and reflects A (diffuse, or diffuse + a mirror of the same colour): every
    # path hits exactly `depth` walls and the expected radiance is E (1 - A^depth) / (1 - A).
    a, e, depth = np.array([0.5, 0.7, 0.9]), np.array([0.2, 0.1, 0.3]), 5
    mtl = material("wall", Kd=tuple(a), Kr=tuple(a), Kl=tuple(e), Roughness=roughness, Fuzz=0.0)
    dev = scene_from_text(scene_dir, f"furnace_{roughness}", box_obj(subdivide=2), mtl)
    b = seed_batches(dev, INSIDE, 8, 4, 0, width=6, height=5, max_depth=depth, sky=sky(100.0),
                     integrator=integrator, sampler=sampler, features=GENERAL)
    expected = np.broadcast_to(e * (1 - a**depth) / (1 - a), b.shape[1:])
    if integrator == "seed":
        assert np.allclose(b, expected, rtol=2e-5, atol=0)     # every path gives exactly the series
    else:
        assert_matches_expected(b, expected)


# --------------------------------------------------------------------------------------------
# Pdfs: integrate to 1, sampling agrees with evaluating

_KERNELS: dict = {}


def _pdf_kernels():
    """Test kernels over the general feature set: evaluate light pdfs along directions, sample lights,
    sample and evaluate a material."""
    if _KERNELS:
        return _KERNELS
    closest_hit = make_closest_hit(GENERAL)
    surface_at = make_surface(GENERAL)
    mat = make_materials(GENERAL)
    light = make_lights(GENERAL, surface_at, mat.emission)

    @wp.func
    def pdf_along(geo: Geometry, lights: Lights, x: wp.vec3, d: wp.vec3) -> float:
        h = closest_hit(geo, x, d, NO_HIT)
        if h.kind == KIND_MISS:
            return light.pdf_miss(lights, d)
        return light.pdf_li(geo, lights, h, x, d)

    @wp.kernel(module="unique")
    def evaluate(geo: Geometry, lights: Lights, x: wp.vec3, dirs: wp.array(dtype=wp.vec3),
                 out: wp.array(dtype=float)):
        i = wp.tid()     # the sky's density counts behind the emitters too: it is sampled there
        h = closest_hit(geo, x, dirs[i], NO_HIT)
        p = light.pdf_miss(lights, dirs[i])
        if h.kind != KIND_MISS:
            p += light.pdf_li(geo, lights, h, x, dirs[i])
        out[i] = p

    @wp.kernel(module="unique")
    def sample(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, x: wp.vec3,
               u: wp.array(dtype=wp.vec3), dirs: wp.array(dtype=wp.vec3), pdf: wp.array(dtype=float),
               pdf_eval: wp.array(dtype=float), visible: wp.array(dtype=int)):
        i = wp.tid()
        ls = light.sample(geo, mats, tex, lights, x, u[i][0], wp.vec2(u[i][1], u[i][2]))
        dirs[i] = ls.dir
        pdf[i] = ls.pdf
        h = closest_hit(geo, x, ls.dir, NO_HIT)
        seen = int(0)
        if h.kind == KIND_MISS:
            seen = int(ls.t_max >= NO_HIT)           # the sky was chosen and is what this direction sees
        elif h.t >= ls.t_max and ls.t_max < NO_HIT:
            seen = 1                                 # the chosen emitter is the first thing along it
        visible[i] = seen
        pdf_eval[i] = pdf_along(geo, lights, x, ls.dir)

    @wp.kernel(module="unique")
    def bsdf(mats: Materials, tex: Textures, sf: Surface, d: wp.vec3, u: wp.array(dtype=wp.vec4),
             dirs: wp.array(dtype=wp.vec3), out: wp.array(dtype=wp.vec4), evals: wp.array(dtype=wp.vec3)):
        """out = (pdf reported by sample, pdf evaluated for its direction, singular, alive)."""
        i = wp.tid()
        s = mat.sample(mats, tex, sf, u[i][0], wp.vec2(u[i][1], u[i][2]), u[i][3])
        dirs[i] = s.dir
        out[i] = wp.vec4(s.pdf, mat.pdf(mats, tex, sf, s.dir), float(s.singular), float(s.alive))
        evals[i] = mat.eval(mats, tex, sf, s.dir) - s.weight * s.pdf    # 0 for diffuse samples

    @wp.kernel(module="unique")
    def bsdf_pdf(mats: Materials, tex: Textures, sf: Surface, dirs: wp.array(dtype=wp.vec3), out: wp.array(dtype=float)):
        i = wp.tid()
        out[i] = mat.pdf(mats, tex, sf, dirs[i])

    _KERNELS.update(evaluate=evaluate, sample=sample, bsdf=bsdf, bsdf_pdf=bsdf_pdf)
    return _KERNELS


def sphere_directions(n: int) -> np.ndarray:
    """n nearly uniform unit vectors (Fibonacci lattice): quadrature weight 4 pi / n each."""
    k = np.arange(n) + 0.5
    z = 1 - 2 * k / n
    phi = np.pi * (1 + 5**0.5) * k
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)


@pytest.fixture(scope="module")
def light_scene(scene_dir):
    """Emitters only, around the origin, none hiding another: a bright textured quad (two
    triangles) above, a dim quad to the side, a glowing sphere behind; gradient sky."""
    tex = scene_dir / "glow.png"
    Image.fromarray(np.random.default_rng(3).integers(30, 256, (4, 4, 3), dtype=np.uint8)).save(tex)
    obj = quads_obj([("bright", [(-1.5, -1.5, 2.0), (1.5, -1.5, 2.0), (1.5, 1.5, 2.0), (-1.5, 1.5, 2.0)]),
                     ("dim", [(3.0, -0.5, -0.5), (3.0, 0.5, -0.5), (3.0, 0.5, 0.5), (3.0, -0.5, 0.5)])],
                    spheres=[("glow", (0.0, -4.0, 0.0), 1.5)])
    obj = obj.replace("v 1.5 1.5 2.0\n", "v 1.5 1.5 2.0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n", 1)
    obj = obj.replace("f 1 2 3\nf 1 3 4", "f 1/1 2/2 3/3\nf 1/1 3/3 4/4")
    mtl = (material("bright", Kd=(0, 0, 0), Kl=(1, 1, 1)) + f"map_Kl {tex}\n"
           + material("dim", Kd=(0, 0, 0), Kl=(0.5, 0.2, 0.1)) + material("glow", Kd=(0, 0, 0), Kl=(2, 2, 3)))
    return scene_from_text(scene_dir, "lights_only", obj, mtl)


def _solid_angles(dev, x) -> np.ndarray:
    """Each emissive triangle's solid angle from x, in float64 (Van Oosterom-Strackee)."""
    out = []
    for m in dev.scene.meshes:
        e = m.positions[m.indices].astype(np.float64) - np.asarray(x, np.float64)
        n = np.linalg.norm(e, axis=2)
        num = np.einsum("ij,ij->i", e[:, 0], np.cross(e[:, 1], e[:, 2]))
        den = (n.prod(axis=1) + np.einsum("ij,ij->i", e[:, 0], e[:, 1]) * n[:, 2]
               + np.einsum("ij,ij->i", e[:, 1], e[:, 2]) * n[:, 0] + np.einsum("ij,ij->i", e[:, 2], e[:, 0]) * n[:, 1])
        out.append(np.abs(2 * np.arctan2(num, den)))
    return np.concatenate(out)


# Shading points: amid the emitters and 0.3 under the bright quad (its triangles sampled by solid angle,
# the dim quad's by area); far away (every triangle sampled by area, the quadrature too coarse).
POINTS = {"amid": (0.1, 0.2, -0.1), "near": (0.3, -0.2, 1.7), "far": (0.5, -0.3, 40.0)}


@pytest.mark.parametrize("where", sorted(POINTS))
@pytest.mark.parametrize("sky_", [Sky.gradient(), Sky.constant(0.0, 0.0, 0.0), Sky.gradient(up=(1, -2, 3))])
def test_light_pdfs_integrate_to_one_and_match_sampling(light_scene, sky_, where):
    from warp_spt.emitters import MAX_SPHERICAL, MIN_SPHERICAL
    k = _pdf_kernels()
    dev, x = light_scene, wp.vec3(*POINTS[where])
    omega = _solid_angles(dev, POINTS[where])            # the bright quad's two triangles, then the dim one's
    if where == "far":
        assert omega.max() < MIN_SPHERICAL
    else:
        assert MIN_SPHERICAL < omega[:2].min() and omega[:2].max() < MAX_SPHERICAL and omega[2:].max() < MIN_SPHERICAL
    lights = light_table(dev, sky_)
    assert lights.num_entries == 4 + 1 + int(sky_.kind == 1)       # 4 triangles, a sphere, the sky
    # quadrature of the evaluated pdfs: emitters (none hides another) plus the sky everywhere; from far
    # away the emitters are too small for the quadrature (the sampling check below covers them)
    dirs = sphere_directions(400_000)
    out = wp.zeros(len(dirs), dtype=float)
    wp.launch(k["evaluate"], dim=len(dirs), inputs=[dev.geometry, lights, x, wp.array(dirs.astype(np.float32),
                                                                                    dtype=wp.vec3), out])
    if where != "far":
        assert abs(out.numpy().astype(np.float64).sum() * 4 * np.pi / len(dirs) - 1) < 3e-3
    # sampling: the reported density is the evaluated one, and E[g / pdf] is the integral of g
    n = 200_000
    u = np.random.default_rng(0).random((n, 3)).astype(np.float32)
    res = [wp.zeros(n, dtype=t) for t in (wp.vec3, float, float, int)]
    wp.launch(k["sample"], dim=n, inputs=[dev.geometry, dev.materials, dev.textures(), lights, x,
                                          wp.array(u, dtype=wp.vec3), *res])
    d, pdf, pdf_eval, vis = (r.numpy().astype(np.float64) for r in res)
    seen = vis > 0
    # sky samples behind an emitter are hidden (the emitter covers them; near the bright quad, much)
    assert seen.mean() > (0.6 if where == "near" else 0.8)
    assert np.allclose(pdf[seen], pdf_eval[seen], rtol=2e-3)
    g = 2 + d[:, 2] + d[:, 0] ** 2                          # integral over the sphere: 8 pi + 4 pi / 3
    est = np.where(seen, g / np.where(pdf > 0, pdf, 1), 0)
    covered = 8 * np.pi + 4 * np.pi / 3
    if sky_.kind != 1:
        # without a sky only the emitters' solid angles are covered: quadrature of g there, or from far
        # away g at each emitter's centre times its solid angle (g varies by < 0.2% over each)
        on = out.numpy() > 0
        gd = 2 + dirs[:, 2] + dirs[:, 0] ** 2
        covered = (gd * on).sum() * 4 * np.pi / len(dirs)
        if where == "far":
            tri = np.concatenate([m.positions[m.indices] for m in dev.scene.meshes]).astype(np.float64)
            sph = dev.scene.spheres.reshape(-1, 4).astype(np.float64)
            cen = np.concatenate([tri.mean(axis=1), sph[:, :3]]) - POINTS[where]
            dist = np.linalg.norm(cen, axis=1)
            c = cen / dist[:, None]
            om = np.concatenate([omega, 2 * np.pi * (1 - np.sqrt(1 - (sph[:, 3] / dist[4:]) ** 2))])
            covered = float(((2 + c[:, 2] + c[:, 0] ** 2) * om).sum())
    assert abs(est.mean() - covered) < 5 * est.std() / math.sqrt(n) + 2e-3 * covered, (est.mean(), covered)


@pytest.mark.parametrize("roughness,tilt", [(1.0, 0.0), (0.4, 0.0), (0.7, 0.5)])
def test_lobe_pdf_integrates_to_its_probability_and_matches_sampling(scene_dir, roughness, tilt):
    # The diffuse lobe's density integrates to its probability (Roughness); singular lobes have none.
    # A tilted shading normal (smooth shading) cuts the lobe where it dips below the real surface.
    k = _pdf_kernels()
    dev = scene_from_text(scene_dir, f"mat_{roughness}", "usemtl m\nb 0 0 0 1\n",
                          material("m", Kd=(0.8, 0.5, 0.2), Kr=(0.9, 0.9, 0.9), Roughness=roughness, Fuzz=0.3))
    sf = Surface()
    sf.p, sf.ng, sf.front, sf.mat, sf.uv = wp.vec3(0.0, 0.0, 0.0), wp.vec3(0.0, 0.0, 1.0), 1, 1, wp.vec2(0.0, 0.0)
    ns = np.array([math.sin(tilt), 0.0, math.cos(tilt)])
    sf.ns = wp.vec3(*ns.astype(np.float32))
    d_in = wp.vec3(*(np.array([0.3, 0.2, -1.0]) / np.linalg.norm([0.3, 0.2, -1.0])).astype(np.float32))
    sf.wo = wp.vec3(-d_in[0], -d_in[1], -d_in[2])          # the material contract's outgoing direction
    dirs = sphere_directions(400_000)
    out = wp.zeros(len(dirs), dtype=float)
    wp.launch(k["bsdf_pdf"], dim=len(dirs), inputs=[dev.materials, dev.textures(), sf, wp.array(dirs.astype(np.float32),
                                                                                 dtype=wp.vec3), out])
    assert abs(out.numpy().astype(np.float64).sum() * 4 * np.pi / len(dirs) - roughness) < 2e-3
    n = 200_000
    u = np.random.default_rng(1).random((n, 4)).astype(np.float32)
    d, res, ev = wp.zeros(n, dtype=wp.vec3), wp.zeros(n, dtype=wp.vec4), wp.zeros(n, dtype=wp.vec3)
    wp.launch(k["bsdf"], dim=n, inputs=[dev.materials, dev.textures(), sf, d_in, wp.array(u, dtype=wp.vec4), d, res, ev])
    d, res, ev = d.numpy().astype(np.float64), res.numpy().astype(np.float64), ev.numpy()
    diffuse = res[:, 2] == 0
    assert abs(diffuse.mean() - roughness) < 5 * math.sqrt(roughness * (1 - roughness) / n) + 1e-9
    assert np.allclose(res[diffuse, 0], res[diffuse, 1], rtol=1e-5, atol=1e-7)   # reported = evaluated
    alive = diffuse & (res[:, 3] > 0)
    assert np.abs(ev[alive]).max() < 1e-5                                           # weight = eval / pdf
    # E[g / pdf] over live diffuse samples = integral of g where the lobe lives (above ns and ng)
    g = 1 + d[:, 2] + d[:, 0] ** 2
    est = np.where(alive, g / np.where(res[:, 0] > 0, res[:, 0], 1), 0)
    gd = 1 + dirs[:, 2] + dirs[:, 0] ** 2
    region = (dirs @ ns > 0) & (dirs[:, 2] > 0)
    want = (gd * region).sum() * 4 * np.pi / len(dirs)
    assert abs(est.mean() - want) < 5 * est.std() / math.sqrt(n) + 2e-3 * want, (est.mean(), want)


# --------------------------------------------------------------------------------------------
# Every integrator and sampler converges to the same image

BATCHES, SPP, SIZE = 12, 16, 12


@pytest.fixture(scope="module")
def mixed_scene(scene_dir):
    """Open scene: checker ground, glass and fuzzy-mirror balls, an emissive sphere, a textured
    emissive quad, gradient sky: every light kind and lobe at once."""
    tex = scene_dir / "screen.png"
    Image.fromarray(np.random.default_rng(5).integers(0, 256, (3, 5, 3), dtype=np.uint8)).save(tex)
    obj = quads_obj([("screen", [(-3.0, 3.0, 0.0), (3.0, 3.0, 0.0), (3.0, 3.0, 3.0), (-3.0, 3.0, 3.0)])],
                    spheres=[("Inner_CheckerTexture", (0.0, 0.0, -101.0), 100.0), ("glass", (0.0, 0.0, 0.0), 1.0),
                             ("lamp", (2.0, -1.0, 3.0), 0.5), ("mirror", (-2.2, 0.5, 0.2), 0.9)])
    lines = obj.splitlines()
    at = next(i for i, ln in enumerate(lines) if ln.startswith("usemtl screen"))
    lines[at:at] = ["vt 0 0", "vt 1 0", "vt 1 1", "vt 0 1"]
    obj = "\n".join(lines).replace("f 1 2 3\nf 1 3 4", "f 1/1 2/2 3/3\nf 1/1 3/3 4/4") + "\n"
    mtl = (material("screen", Kd=(0.2, 0.2, 0.2), Kl=(1, 1, 1), Roughness=0.8) + f"map_Kl {tex}\n"
           + material("glass", Kt=(0.9, 0.95, 1.0), Roughness=0, Kn=1.5, Refractable=True)
           + material("lamp", Kd=(0, 0, 0), Kl=(6, 5, 4))
           + material("mirror", Kd=(0.7, 0.3, 0.3), Kr=(0.9, 0.9, 0.9), Roughness=0.3, Fuzz=0.2))
    return scene_from_text(scene_dir, "mixed", obj, mtl)


MIXED_CAM = Camera(position=(0.0, -8.0, 2.0), direction=(0.0, 1.0, -0.2), fov=50.0, aperture=0.0, focus=8.0)
SCENES = {"cornell": (lambda d: load(*cornell_files(d)), cornell_camera(), sky(0.0)),
          "mixed": (None, MIXED_CAM, Sky.gradient())}


@pytest.fixture(scope="module")
def references(scene_dir, mixed_scene):
    """The seed's estimator with independent numbers (the pre-restructure renderer) per scene."""
    out = {}
    for name, (make, cam, sky_) in SCENES.items():
        dev = mixed_scene if make is None else make(scene_dir)
        kw = dict(width=SIZE, height=SIZE, max_depth=5, sky=sky_, features=GENERAL)
        out[name] = (dev, cam, kw, seed_batches(dev, cam, BATCHES, SPP, 1000, integrator="seed",
                                                sampler="independent", **kw))
    return out


@pytest.mark.parametrize("scene", sorted(SCENES))
@pytest.mark.parametrize("integrator,sampler,roulette", every_pair(0) + [("nee", "sobol", 2)])
def test_integrators_and_samplers_converge_to_the_same_image(references, scene, integrator, sampler, roulette):
    dev, cam, kw, ref = references[scene]
    b = seed_batches(dev, cam, BATCHES, SPP, 2000, integrator=integrator, sampler=sampler,
                     roulette_depth=roulette, **kw)
    assert_same_image(ref, b, f"{scene}: {integrator} + {sampler} (roulette {roulette}) vs seed + independent")


# --------------------------------------------------------------------------------------------
# Chosen by name: API and CLI


def test_integrator_and_sampler_are_chosen_by_name():
    from warp_spt.cli.common import EXIT_USAGE
    from warp_spt.cli.main import main
    from warp_spt.cli.options import parse_args
    opts = parse_args(["--integrator", "seed", "--sampler", "sobol"])
    assert (opts.integrator, opts.sampler) == ("seed", "sobol")
    assert (parse_args([]).integrator, parse_args([]).sampler) == (None, None)     # the renderer's defaults
    # names are checked against the registries once Warp is initialised (parsing stays Warp-free)
    assert main(["--integrator", "bidir", "--quiet", "-res", "2", "2"]) == EXIT_USAGE
    assert main(["--sampler", "halton", "--quiet", "-res", "2", "2"]) == EXIT_USAGE
    with pytest.raises(ValueError, match="unknown integrator"):
        R.render_scene(None, None, RenderSettings(integrator="bidir"))    # checked before any upload
    with pytest.raises(ValueError, match="unknown sampler"):
        R.render_scene(None, None, RenderSettings(sampler="halton"))


def test_reused_pick_number_is_uniform_per_light(light_scene):
    # NEE with sobol picks the light and the point on it from one 2D request: what is left of the
    # pick's number must be uniform on [0, 1) given the chosen light (an independent check: sorted
    # leftovers of an even grid of picks against their uniform quantiles).
    from warp_spt.emitters import pick_entry, reuse_pick

    @wp.kernel(module="unique")
    def leftovers(lights: Lights, u: wp.array(dtype=float), entry: wp.array(dtype=int), rest: wp.array(dtype=float)):
        i = wp.tid()
        entry[i] = pick_entry(lights, u[i])
        rest[i] = reuse_pick(lights, u[i])

    lights = light_table(light_scene, Sky.gradient())
    n = 1 << 18
    u = (np.arange(n) + 0.5) / n
    entry, rest = wp.zeros(n, dtype=int), wp.zeros(n, dtype=float)
    wp.launch(leftovers, dim=n, inputs=[lights, wp.array(u.astype(np.float32), dtype=float), entry, rest])
    entry, rest = entry.numpy(), rest.numpy().astype(np.float64)
    prob = lights.entry_prob.numpy()
    assert (prob >= 2.0**-12).all() and (rest >= 0).all() and (rest < 1).all()
    for e in range(lights.num_entries):
        r = np.sort(rest[entry == e])
        assert abs(len(r) / n - prob[e]) < 2.0 / n + 1e-6                        # chosen with its probability
        q = (np.arange(len(r)) + 0.5) / len(r)
        assert np.abs(r - q).max() < 2.0 / len(r) + 1e-5, e                      # the leftover is uniform
