"""The pbr material kind in the renderer, against results that do not come from the code under test.

* White furnace: a convex object in a uniform sky of radiance 1 sees the sky once per bounce, so a
  pixel's expectation is the material's directional albedo. A white conductor (metallic 1, base 1)
  with multiple-scattering compensation and the white dielectric (a specular layer over a white
  base) reflect everything: 1 at every roughness, within 1% and the sample's standard error. Smooth
  glass is exactly 1. Without compensation the rough metal loses the single-scattering energy that
  an independent numpy integration of the GGX lobe (F = 1) predicts.
* The mixture's sampling: chi-square of the pbr kind's sampled directions against its own ``pdf``,
  and its weights against ``eval / pdf`` (the lobe-level tests are tests/bsdfs/test_microfacet.py).
* Normal maps: a map holding one constant tilted normal turns the shading normal (the denoiser's
  normal buffer) by exactly that tilt, along the uv's u direction (MikkTSpace's convention).
* Texture decoding: a standard file's colour map is decoded from sRGB (IEC 61966-2-1), its data maps
  and the seed's dialect keep the stored values.
* Kernels: a scene of the seed's kind alone compiles no pbr code and keeps its feature set.
"""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.bsdfs import make_materials
from warp_spt.device.structs import Materials, Textures
from warp_spt.accel.surface import Surface
from warp_spt.io.loader import load_scene
from warp_spt.rendering import tiles as R
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

from tests.support.scenes import material, quad_obj, write_scene_files

CAM = Camera(position=(0, -6, 0), direction=(0, 1, 0), fov=22.0, aperture=0.0, focus=6.0)
UNIFORM = Sky.constant(1.0, 1.0, 1.0)


def _sphere_scene(folder, name: str, mtl: str) -> DeviceScene:
    objs, mtls = write_scene_files(folder, name, "usemtl m\nb 0 0 0 1\n", "newmtl m\n" + mtl)
    return DeviceScene(load_scene(objs, mtls))


def _disc_mean(dev: DeviceScene, spp: int = 64, integrator: str = "nee", sampler: str = "sobol", seed: int = 1):
    """Mean and standard error over the pixels well inside the sphere's disc (24x24 image)."""
    res = R.render_scene(dev, CAM, RenderSettings(width=24, height=24, spp=spp, max_depth=8, seed=seed,
                                                  integrator=integrator, sampler=sampler, sky=UNIFORM))
    c = res.image[7:17, 7:17].reshape(-1, 3).astype(np.float64)
    return c.mean(0), c.std(0, ddof=1) / np.sqrt(len(c))


@pytest.mark.parametrize("rough", [0.0, 0.25, 0.5, 0.75, 1.0])
@pytest.mark.parametrize("metallic", [1.0, 0.0])
def test_white_furnace_is_one_at_every_roughness(scene_dir, rough, metallic):
    dev = _sphere_scene(scene_dir, f"furnace_{metallic}_{rough}", f"Kd 1 1 1\nPm {metallic}\nPr {rough}\n")
    mean, se = _disc_mean(dev)
    assert np.all(np.abs(mean - 1.0) < 0.01 + 4 * se), (mean, se)


def test_white_furnace_every_integrator_and_sampler(scene_dir):
    dev = _sphere_scene(scene_dir, "furnace_mix", "Kd 1 1 1\nPm 0.5\nPr 0.4\n")
    for integrator, sampler in (("seed", "independent"), ("nee", "independent"), ("seed", "sobol")):
        mean, se = _disc_mean(dev, integrator=integrator, sampler=sampler)
        assert np.all(np.abs(mean - 1.0) < 0.01 + 4 * se), (integrator, sampler, mean, se)


def test_smooth_glass_furnace_is_exactly_one(scene_dir):
    dev = _sphere_scene(scene_dir, "furnace_glass", "Kd 1 1 1\nPr 0\nd 0\nNi 1.5\n")
    mean, se = _disc_mean(dev, spp=8)
    np.testing.assert_allclose(mean, 1.0, atol=1e-5)


def _ggx_albedo_numpy(alpha: float, mu: float, n: int = 2_000_000) -> float:
    """Single-scattering directional albedo of isotropic GGX with F = 1 and height-correlated Smith
    masking, by Monte Carlo over uniformly sampled directions (independent of bsdfs.microfacet)."""
    rng = np.random.default_rng(7)
    wo = np.array([np.sqrt(1 - mu * mu), 0.0, mu])
    u = rng.random((n, 2))
    z = u[:, 0]
    r = np.sqrt(1 - z * z)
    wi = np.stack([r * np.cos(2 * np.pi * u[:, 1]), r * np.sin(2 * np.pi * u[:, 1]), z], 1)
    h = wi + wo
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    a2 = alpha * alpha
    d = 1.0 / (np.pi * a2 * ((h[:, 0] ** 2 + h[:, 1] ** 2) / a2 + h[:, 2] ** 2) ** 2)

    def lam(w):
        t2 = (w[..., 0] ** 2 + w[..., 1] ** 2) / np.maximum(w[..., 2] ** 2, 1e-12)
        return 0.5 * (-1 + np.sqrt(1 + a2 * t2))
    g = 1.0 / (1.0 + lam(wo) + lam(wi))
    return float((d * g / (4 * mu) * 2 * np.pi).mean())


def test_without_compensation_the_rough_metal_loses_the_single_scattering_energy(scene_dir):
    """A face-on view of a white metal quad (roughness 1) in a uniform sky: compensated 1, bare the
    GGX lobe's own albedo at normal incidence."""
    quad = quad_obj([(-3, 0, -3), (3, 0, -3), (3, 0, 3), (-3, 0, 3)], material="m")
    cam = Camera(position=(0, -4, 0), direction=(0, 1, 0), fov=10.0, aperture=0.0, focus=4.0)
    expected = _ggx_albedo_numpy(1.0, 1.0)
    assert 0.25 < expected < 0.4           # 2 (1 - ln 2) / 2 = 0.307 in closed form at alpha 1, mu 1
    for flag, want in ((True, 1.0), (False, expected)):
        objs, mtls = write_scene_files(scene_dir, f"bare_{flag}", quad, "newmtl m\nKd 1 1 1\nPm 1\nPr 1\n")
        scene = load_scene(objs, mtls)
        scene.materials.multiscatter[:] = flag
        dev = DeviceScene(scene)
        res = R.render_scene(dev, cam, RenderSettings(width=8, height=8, spp=256, max_depth=2, seed=3,
                                                      integrator="nee", sky=UNIFORM))
        c = res.image.reshape(-1, 3).astype(np.float64)
        mean, se = c.mean(), c.std(ddof=1) / np.sqrt(c.size)
        assert abs(mean - want) < 0.01 * want + 4 * se, (flag, mean, want, se)


def test_the_seed_kind_alone_compiles_no_pbr_code(scene_dir):
    objs, mtls = write_scene_files(scene_dir, "seedonly", "usemtl m\nb 0 0 0 1\n",
                                   material("m", Kd=(0.5, 0.5, 0.5), Roughness=0.5, Fuzz=0.1))
    f = DeviceScene(load_scene(objs, mtls)).features
    assert f.material_kinds == ("seed",)
    assert not f.needs("frame") and not any(x.startswith("pbr") for x in f.material_flags), f
    assert f.material_flags == ("dims.lobe", "seed.diffuse", "seed.specular")


def test_srgb_colour_maps_linear_data_maps_raw_seed(tmp_path):
    from PIL import Image

    Image.fromarray(np.full((2, 2, 3), 128, np.uint8)).save(tmp_path / "t.png")
    quad = quad_obj([(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)], material="m")
    (tmp_path / "q.obj").write_text(quad)
    (tmp_path / "std.mtl").write_text("newmtl m\nmap_Kd t.png\nmap_Pr t.png\n")
    (tmp_path / "seed.mtl").write_text("newmtl m\nmap_Kd t.png\nnewmtl z\nKl 0 0 0\n")
    std = load_scene([str(tmp_path / "q.obj")], [str(tmp_path / "std.mtl")])
    seed = load_scene([str(tmp_path / "q.obj")], [str(tmp_path / "seed.mtl")])
    c = 128 / 255
    srgb = ((c + 0.055) / 1.055) ** 2.4           # IEC 61966-2-1
    row = std.materials.names.index("m")
    base = std.textures[std.materials.tex[row, 4]]
    rough = std.textures[std.materials.tex[row, 6]]
    np.testing.assert_allclose(base, srgb, rtol=1e-6)
    np.testing.assert_allclose(rough, c, rtol=1e-6)
    np.testing.assert_allclose(seed.textures[0], c, rtol=1e-6)


def test_a_normal_map_tilts_the_shading_normal_along_u(tmp_path):
    """A constant normal map (tilted 30 degrees towards +u) on a quad facing -y whose u runs along
    +x, then along +z (uv rotated): the normal buffer shows the tilt, towards the world's u direction."""
    from PIL import Image

    from warp_spt.rendering.aux_buffers import feature_buffers

    tilt = np.radians(30.0)
    n = np.array([np.sin(tilt), 0.0, np.cos(tilt)])
    Image.fromarray(np.round((n * 0.5 + 0.5) * 255).astype(np.uint8)[None, None, :].repeat(4, 0).repeat(4, 1)).save(
        tmp_path / "n.png")
    stored = (np.round((n * 0.5 + 0.5) * 255) / 255) * 2 - 1
    stored /= np.linalg.norm(stored)
    corners = [(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)]
    cam = Camera(position=(0, -3, 0), direction=(0, 1, 0), fov=20.0, aperture=0.0, focus=3.0)
    x, z = np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 1.0])
    for uvs, u_world, v_world in ((((0, 0), (1, 0), (1, 1), (0, 1)), x, z), (((0, 0), (0, 1), (1, 1), (1, 0)), z, x)):
        (tmp_path / "q.obj").write_text("mtllib q.mtl\n" + quad_obj(corners, uvs=uvs, material="m"))
        (tmp_path / "q.mtl").write_text("newmtl m\nKd 0.5 0.5 0.5\nnorm n.png\n")
        dev = DeviceScene(load_scene([str(tmp_path / "q.obj")], [str(tmp_path / "q.mtl")]))
        assert dev.features.needs("frame.uv") and dev.features.needs("pbr.normal_map")
        _, normal = feature_buffers(dev, cam, 8, 8, spp=1)
        face = np.array([0.0, -1.0, 0.0])             # towards the camera
        want = stored[0] * u_world + stored[1] * v_world + stored[2] * face
        got = normal[2:6, 2:6].reshape(-1, 3)
        np.testing.assert_allclose(got, np.broadcast_to(want / np.linalg.norm(want), got.shape), atol=2e-3)


@wp.func
def flat(row: int, wo: wp.vec3) -> Surface:
    """A shading point of material ``row`` with normal +z and tangent +x, seen from ``wo``."""
    sf = Surface()
    sf.ng = wp.vec3(0.0, 0.0, 1.0)
    sf.ns = sf.ng
    sf.ns0 = sf.ng
    sf.t = wp.vec3(1.0, 0.0, 0.0)
    sf.b = wp.vec3(0.0, 1.0, 0.0)
    sf.front = 1
    sf.mat = row
    sf.wo = wo
    return sf


def _mixture_kernels(features):
    """Two kernels over the materials at a flat shading point (normal +z, tangent +x): ``draw``
    samples ``wo`` and returns each sample's direction, weight, pdf, and the pdf and eval at that
    direction; ``density`` evaluates ``pdf`` at given directions."""
    mat = make_materials(features)

    @wp.kernel(enable_backward=False, module="unique")
    def draw(m: Materials, t: Textures, wo: wp.vec3, row: int, u: wp.array(dtype=wp.vec4),
             d: wp.array(dtype=wp.vec3), w: wp.array(dtype=wp.vec3), p: wp.array(dtype=float),
             p2: wp.array(dtype=float), f: wp.array(dtype=wp.vec3), alive: wp.array(dtype=int)):
        i = wp.tid()
        sf = flat(row, wo)
        bs = mat.sample(m, t, sf, u[i][0], wp.vec2(u[i][1], u[i][2]), u[i][3])
        d[i] = bs.dir
        w[i] = bs.weight
        p[i] = bs.pdf
        alive[i] = wp.where(bs.alive != 0 and bs.singular == 0, 1, 0)
        p2[i] = mat.pdf(m, t, sf, bs.dir)
        f[i] = mat.eval(m, t, sf, bs.dir)

    @wp.kernel(enable_backward=False, module="unique")
    def density(m: Materials, t: Textures, wo: wp.vec3, row: int, dirs: wp.array(dtype=wp.vec3),
                out: wp.array(dtype=float)):
        i = wp.tid()
        out[i] = mat.pdf(m, t, flat(row, wo), dirs[i])

    return draw, density


@pytest.mark.parametrize("mtl", ["Kd 0.7 0.5 0.3\nPm 0.3\nPr 0.5\n", "Kd 0.9 0.9 0.9\nPr 0.35\nd 0.4\nNi 1.5\n",
                                 "Kd 0.8 0.6 0.2\nPm 0.8\nPr 0.6\naniso 0.7\nanisor 0.1\n",
                                 "Kd 0.7 0.5 0.3\nPm 0.3\nPr 0.5\nset clearcoat 0.8\nset clearcoat_roughness 0.3\n",
                                 "Kd 0.7 0.5 0.3\nPm 0.3\nPr 0.5\nset sheen_color 0.9 0.6 0.4\nset sheen_roughness 0.3\n"
                                 "set clearcoat 0.5\nset clearcoat_roughness 0.2\n",
                                 "Kd 0.7 0.5 0.3\nPm 0.3\nPr 0.5\nset clearcoat 0.8\nset clearcoat_roughness 0.3\n"
                                 "set clearcoat_normal_map tilt.png\n"])
def test_mixture_samples_follow_its_pdf_and_weights_are_eval_over_pdf(tmp_path, mtl):
    from PIL import Image

    # the coat's own normal map: a constant normal tilted 20 degrees towards +u
    tilt = np.array([np.sin(np.radians(20.0)), 0.0, np.cos(np.radians(20.0))])
    Image.fromarray(np.round((tilt * 0.5 + 0.5) * 255).astype(np.uint8)[None, None].repeat(2, 0).repeat(2, 1)).save(
        tmp_path / "tilt.png")
    quad = quad_obj([(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)], material="m")
    objs, mtls = write_scene_files(tmp_path, "mix", quad, "newmtl m\n" + mtl)
    dev = DeviceScene(load_scene(objs, mtls))
    row = dev.scene.materials.names.index("m")
    draw, density = _mixture_kernels(dev.features)
    n = 200_000
    rng = np.random.default_rng(5)
    for theta in (15.0, 60.0, 80.0):
        wo = wp.vec3(np.sin(np.radians(theta)), 0.0, np.cos(np.radians(theta)))
        u = wp.array(rng.random((n, 4)).astype(np.float32), dtype=wp.vec4)
        out = [wp.zeros(n, dtype=t) for t in (wp.vec3, wp.vec3, float, float, wp.vec3, int)]
        wp.launch(draw, dim=n, inputs=[dev.materials, dev.textures(), wo, row, u, *out])
        d, w, p, p2, f, alive = (a.numpy() for a in out)
        ok = alive == 1
        # the weight of a sample is eval / pdf at its direction, and sample's pdf is pdf's
        np.testing.assert_allclose(p[ok], p2[ok], rtol=2e-3)
        np.testing.assert_allclose(w[ok], f[ok] / p2[ok, None], rtol=3e-3, atol=1e-6)
        # chi-square: sampled directions against the pdf integrated over (cos theta, phi) bins
        nz, nphi, sub = 16, 24, 16
        zc = (np.arange(nz * sub) + 0.5) / (nz * sub) * 2 - 1
        pc = (np.arange(nphi * sub) + 0.5) / (nphi * sub) * 2 * np.pi
        zz, pp = np.meshgrid(zc, pc, indexing="ij")
        r = np.sqrt(1 - zz**2)
        dirs = np.stack([r * np.cos(pp), r * np.sin(pp), zz], -1).reshape(-1, 3).astype(np.float32)
        dens = wp.zeros(len(dirs), dtype=float)
        wp.launch(density, dim=len(dirs), inputs=[dev.materials, dev.textures(), wo, row,
                                                  wp.array(dirs, dtype=wp.vec3), dens])
        cell = (2.0 / (nz * sub)) * (2 * np.pi / (nphi * sub))
        expected = dens.numpy().reshape(nz, sub, nphi, sub).sum((1, 3)) * cell * n
        dz = d[ok]
        iz = np.clip(((dz[:, 2] + 1) / 2 * nz).astype(int), 0, nz - 1)
        ip = np.clip((np.mod(np.arctan2(dz[:, 1], dz[:, 0]), 2 * np.pi) / (2 * np.pi) * nphi).astype(int), 0, nphi - 1)
        observed = np.zeros((nz, nphi))
        np.add.at(observed, (iz, ip), 1)
        # the pdf integrates to the share of samples that are not singular (none here) or absorbed
        assert abs(expected.sum() / n - ok.mean()) < 0.01, (theta, expected.sum() / n, ok.mean())
        e, o = expected.ravel(), observed.ravel()
        order = np.argsort(e)
        e, o = e[order], o[order]
        small = np.cumsum(e) < 5 * 8            # pool the smallest expectations into one bin
        e = np.concatenate([[e[small].sum()], e[~small]]) if small.any() else e
        o = np.concatenate([[o[small].sum()], o[~small]]) if small.any() else o
        keep = e > 0
        stat = float((((o - e) ** 2)[keep] / e[keep]).sum()) + float(o[~keep].sum()) * 1e6
        dof = int(keep.sum()) - 1
        assert _chi2_sf(stat, dof) > 1e-4, (theta, stat, dof)


def _chi2_sf(x: float, k: int) -> float:
    """Upper tail of the chi-square distribution (Wilson-Hilferty normal approximation, accurate to
    ~1e-3 in p for k >= 10: enough for a p > 1e-4 threshold)."""
    from math import erfc, sqrt
    z = ((x / k) ** (1 / 3) - (1 - 2 / (9 * k))) / sqrt(2 / (9 * k))
    return 0.5 * erfc(z / sqrt(2))


def _alpha_png(path, alpha: np.ndarray) -> None:
    from PIL import Image

    rgba = np.zeros(alpha.shape + (4,), np.uint8)
    rgba[..., :3] = 200
    rgba[..., 3] = alpha
    Image.fromarray(rgba, "RGBA").save(path)


def test_cutouts_are_holes_for_camera_rays_and_shadow_rays(tmp_path):
    """A leaf quad whose map_d alpha is 0 on its left half, over a green emitter: camera rays see the
    green through the hole and the leaf elsewhere. Shadow rays: a floor under a fully transparent roof
    renders as the floor with no roof, under a fully opaque one as under a plain roof (per-pixel
    means over seeds within 5 standard errors, the variance pooled over the image)."""
    half = np.zeros((8, 8), np.uint8)
    half[:, 4:] = 255
    _alpha_png(tmp_path / "half.png", half)
    _alpha_png(tmp_path / "clear.png", np.zeros((4, 4), np.uint8))
    _alpha_png(tmp_path / "solid.png", np.full((4, 4), 255, np.uint8))
    leaf = quad_obj([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)], material="leaf")
    back = "v -5 -5 -1\nv 5 -5 -1\nv 5 5 -1\nv -5 5 -1\nusemtl glow\nf 5 6 7\nf 5 7 8\n"
    (tmp_path / "a.obj").write_text(leaf + back)
    (tmp_path / "a.mtl").write_text("newmtl leaf\nKd 0.8 0.8 0.8\nmap_d half.png\nnewmtl glow\nKd 0 0 0\nKe 0 1 0\n")
    dev = DeviceScene(load_scene([str(tmp_path / "a.obj")], [str(tmp_path / "a.mtl")]))
    assert dev.features.needs("cutout")
    top = Camera(position=(0, 0, 3), direction=(0, 0, -1), fov=30.0, aperture=0.0, focus=3.0)
    img = R.render(dev, top, width=16, height=16, spp=4, max_depth=1, sky=Sky.constant(0, 0, 0))
    # the image's x runs along the world's -x or +x: find the hole's side from the leaf's u direction
    left, right = img[4:12, 2:6].reshape(-1, 3), img[4:12, 10:14].reshape(-1, 3)
    hole, solid = (left, right) if left[:, 1].mean() > right[:, 1].mean() else (right, left)
    np.testing.assert_array_equal(hole, np.broadcast_to(np.float32([0, 1, 0]), hole.shape))
    np.testing.assert_array_equal(solid, np.zeros_like(solid))

    floor = "v -6 -6 -1\nv 6 -6 -1\nv 6 6 -1\nv -6 6 -1\nusemtl floor\nf 5 6 7\nf 5 7 8\n"
    roof = quad_obj([(-4, -4, 0), (4, -4, 0), (4, 4, 0), (-4, 4, 0)], material="roof")
    under = Camera(position=(0.3, -0.2, -0.5), direction=(0.1, 0.05, -1), fov=60.0, aperture=0.0, focus=1.0)

    def floor_image(roof_mtl: str | None, seed: int) -> np.ndarray:
        obj = (roof if roof_mtl is not None else quad_obj([(50, 50, 50), (51, 50, 50), (51, 51, 50), (50, 51, 50)], material="roof")) + floor
        (tmp_path / "s.obj").write_text(obj)
        (tmp_path / "s.mtl").write_text(f"newmtl roof\nKd 0.5 0.5 0.5\n{roof_mtl or ''}\nnewmtl floor\nKd 0.6 0.6 0.6\n")
        d = DeviceScene(load_scene([str(tmp_path / "s.obj")], [str(tmp_path / "s.mtl")]))
        return R.render(d, under, width=8, height=8, spp=32, max_depth=2, seed=seed,
                        sky=Sky.constant(1.0, 1.0, 1.0)).astype(np.float64)

    def agree(a_mtl, b_mtl, seeds: int = 6):
        a = np.stack([floor_image(a_mtl, s) for s in range(seeds)])
        b = np.stack([floor_image(b_mtl, 10 + s) for s in range(seeds)])
        # per pixel, with the variance pooled over the image (a few seeds estimate one pixel's poorly)
        se = np.sqrt((a.var(0, ddof=1).mean() + b.var(0, ddof=1).mean()) / seeds)
        assert np.all(np.abs(a.mean(0) - b.mean(0)) < 5 * se), (np.abs(a.mean(0) - b.mean(0)).max(), se)
        return a.mean(), b.mean()

    clear, none = agree("map_d clear.png", None)
    opaque, plain = agree("map_d solid.png", "")
    assert opaque < 0.5 * clear            # the roof's shadow is there: the comparisons can fail


def test_a_normal_map_that_is_not_a_normal_map_is_refused_with_file_and_line(tmp_path):
    from PIL import Image

    from warp_spt.scene.errors import SceneError

    Image.fromarray(np.full((4, 4, 3), 128, np.uint8)).save(tmp_path / "grey.png")     # a height map
    (tmp_path / "q.obj").write_text("mtllib q.mtl\n" + quad_obj([(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)],
                                                              material="m"))
    (tmp_path / "q.mtl").write_text("newmtl m\nKd 0.5 0.5 0.5\nnorm grey.png\n")
    with pytest.raises(SceneError) as info:
        load_scene([str(tmp_path / "q.obj")])
    assert info.value.line == 3 and "not a tangent-space normal map" in info.value.message


@pytest.mark.parametrize("mtl, message", [("aniso 1.5\n", "after 'aniso'"), ("Pr -0.1\n", "after 'Pr'"),
                                          ("Pm 2\n", "after 'Pm'"), ("Ni 0\n", "after 'Ni'"),
                                          ("norm -bm x n.png\n", "after 'norm -bm'")])
def test_out_of_range_pbr_values_name_file_and_line(mtl, message):
    from warp_spt.io.mtl import parse_mtl_bytes
    from warp_spt.scene.errors import SceneError

    with pytest.raises(SceneError) as info:
        parse_mtl_bytes(("newmtl m\n" + mtl).encode(), "x.mtl")
    assert (info.value.path, info.value.line) == ("x.mtl", 2) and message in info.value.message, info.value.message
