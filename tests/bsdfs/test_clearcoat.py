"""KHR_materials_clearcoat in the pbr kind, against what does not come from the code under test:

* the glTF specification's layering, f = (1 - c F(mu_o)) f_rest + c F(mu_o) D V mu_i (F Schlick's with
  F0 0.04 at the view angle, D GGX, V height-correlated Smith), evaluated in numpy for direction
  pairs and compared with the kernel's ``eval`` of a coated row minus its uncoated twin;
* a white furnace: the coat over the white dielectric (which reflects everything) loses exactly the
  coat's share of its single-scattering shortfall, F(mu) (1 - E(mu)) with E integrated in numpy (none
  for a smooth coat, 2.7% for roughness 1 at the centre of the disc);
* a scene without a coat compiles none of it (its features do not ask for it).
"""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from tests.bsdfs.test_materials import _disc_mean, _ggx_albedo_numpy, _sphere_scene, flat
from tests.support.format_files import CUBE_POSITIONS, CUBE_TRIANGLES, GltfBuilder
from tests.support.scenes import quad_obj, write_scene_files
from warp_spt.bsdfs import make_materials
from warp_spt.device.structs import Materials, Textures
from warp_spt.io.gltf import parse_gltf_bytes
from warp_spt.io.loader import load_scene
from warp_spt.upload.device_scene import DeviceScene


def _coated_gltf(coat: float, coat_rough: float) -> bytes:
    g = GltfBuilder()
    g.mesh(CUBE_POSITIONS, CUBE_TRIANGLES)
    prim = g.doc["meshes"][0]["primitives"][0]
    g.doc["meshes"][0]["primitives"] = [dict(prim, material=0), dict(prim, material=1)]
    base = {"pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.3, 0.2, 1], "metallicFactor": 0.3,
                                     "roughnessFactor": 0.5}}
    g.doc["materials"] = [dict(base, name="coated", extensions={"KHR_materials_clearcoat": {
        "clearcoatFactor": coat, "clearcoatRoughnessFactor": coat_rough}}), dict(base, name="bare")]
    g.doc["extensionsUsed"] = ["KHR_materials_clearcoat"]
    g.node(mesh=0)
    return g.gltf()[0]


def _eval_kernel(features, shaded: bool = False):
    """``eval`` of the materials at a flat shading point (normal +z, tangent +x) for given directions;
    ``shaded``: the point's maps applied first (``shade``), as the integrators do, at uv (0.5, 0.5)."""
    mat = make_materials(features)

    @wp.kernel(enable_backward=False, module="unique")
    def evaluate(m: Materials, t: Textures, wo: wp.vec3, row: int, dirs: wp.array(dtype=wp.vec3),
                 out: wp.array(dtype=wp.vec3)):
        i = wp.tid()
        sf = flat(row, wo)
        if wp.static(shaded):
            sf.uv = wp.vec2(0.5, 0.5)           # a texel's centre, away from the tile's edges in the atlas
            sf = mat.shade(m, t, sf)
        out[i] = mat.eval(m, t, sf, dirs[i])

    return evaluate


def eval_rows(evaluate, dev, rows, wo, wi) -> list[np.ndarray]:
    """The kernel ``evaluate`` (:func:`_eval_kernel`) of each material row at ``wo`` for directions ``wi``."""
    out = []
    for row in rows:
        o = wp.zeros(len(wi), dtype=wp.vec3)
        wp.launch(evaluate, dim=len(wi), inputs=[dev.materials, dev.textures(), wp.vec3(*wo), row,
                                                 wp.array(wi.astype(np.float32), dtype=wp.vec3), o])
        out.append(o.numpy().astype(np.float64))
    return out


def upper_directions(rng, n: int) -> np.ndarray:
    """``n`` random directions above the surface, none within 3 degrees of the horizon."""
    z = rng.uniform(0.05, 1.0, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    return np.stack([np.sqrt(1 - z * z) * np.cos(phi), np.sqrt(1 - z * z) * np.sin(phi), z], 1)


def _coat_numpy(wo, wi, coat, rough):
    alpha = max(rough * rough, 1e-4)
    a2 = alpha * alpha
    h = (wo + wi) / np.linalg.norm(wo + wi, axis=-1, keepdims=True)
    d = 1.0 / (np.pi * a2 * ((h[..., 0] ** 2 + h[..., 1] ** 2) / a2 + h[..., 2] ** 2) ** 2)

    def lam(w):
        return 0.5 * (-1 + np.sqrt(1 + a2 * (w[..., 0] ** 2 + w[..., 1] ** 2) / w[..., 2] ** 2))
    v = 1.0 / (1.0 + lam(wo) + lam(wi)) / (4 * wo[..., 2] * wi[..., 2])
    fresnel = 0.04 + 0.96 * (1 - wo[..., 2]) ** 5
    return coat * fresnel, coat * fresnel * d * v * wi[..., 2]


@pytest.mark.parametrize("coat, rough", [(1.0, 0.3), (0.6, 0.7)])
def test_the_coat_is_the_gltf_specs_layer_over_the_rest(coat, rough):
    d = parse_gltf_bytes(_coated_gltf(coat, rough), "coat.gltf")
    assert not d.warnings
    dev = DeviceScene(load_scene([d]))
    names = dev.scene.materials.names
    rows = names.index("coat.gltf: coated"), names.index("coat.gltf: bare")
    assert dev.features.needs("pbr.clearcoat")
    evaluate = _eval_kernel(dev.features)
    rng = np.random.default_rng(3)
    for theta in (10.0, 45.0, 75.0):
        wo = np.array([np.sin(np.radians(theta)), 0.0, np.cos(np.radians(theta))])
        wi = upper_directions(rng, 64)
        f = eval_rows(evaluate, dev, rows, wo, wi)
        weight, coat_f = _coat_numpy(wo[None], wi, coat, rough)
        np.testing.assert_allclose(f[0], f[1] * (1 - weight[:, None]) + coat_f[:, None], rtol=2e-4, atol=1e-7)
    # a file whose coat is 0 compiles none of it
    assert not DeviceScene(load_scene([parse_gltf_bytes(_coated_gltf(0.0, rough), "bare.gltf")])).features.needs(
        "pbr.clearcoat")


@pytest.mark.parametrize("rough", [0.0, 0.3, 0.7, 1.0])
def test_white_furnace_of_the_coat_over_the_white_dielectric(scene_dir, rough):
    dev = _sphere_scene(scene_dir, f"coat_{rough}", f"Kd 1 1 1\nPr 0.4\nset clearcoat 1\n"
                                                   f"set clearcoat_roughness {rough}\n")
    assert dev.features.needs("pbr.clearcoat")
    mean, se = _disc_mean(dev)
    # the coat's loss F(mu) (1 - E(mu)), E its single-scattering albedo (numpy), over the disc's centre
    # (mu from about 0.7 to 1)
    loss = [(0.04 + 0.96 * (1 - mu) ** 5) * (1 - _ggx_albedo_numpy(max(rough * rough, 1e-4), mu, 400_000))
            for mu in (0.7, 0.85, 1.0)] if rough > 0 else [0.0]          # a smooth coat: a mirror, no loss
    assert np.all(mean <= 1.0 - min(loss) + 0.003 + 4 * se) and np.all(mean >= 1.0 - max(loss) - 0.003 - 4 * se), \
        (mean, se, loss)


def _tilted_png(path, degrees: float) -> np.ndarray:
    """A constant tangent-space normal map tilted ``degrees`` towards +u; the unit normal it stores
    (after 8-bit rounding) in the (t, b, n) frame."""
    from PIL import Image

    a = np.radians(degrees)
    code = np.round((np.array([np.sin(a), 0.0, np.cos(a)]) * 0.5 + 0.5) * 255)
    Image.fromarray(code.astype(np.uint8)[None, None, :].repeat(2, 0).repeat(2, 1)).save(path)
    n = code / 255 * 2 - 1
    return n / np.linalg.norm(n)


def _frame_about(n: np.ndarray) -> np.ndarray:
    """Rows t, b, n of an orthonormal frame whose z is unit ``n`` (isotropic lobes: any tangent)."""
    t = np.cross([0.0, 1.0, 0.0], n)
    t /= np.linalg.norm(t)
    return np.stack([t, np.cross(n, t), n])


def _coat_rows(tmp_path, coat_map: bool, base_map: bool):
    """A coated and a bare row of one base (the bare one without the coat's map); a coat normal map
    tilted 25 degrees and a base normal map tilted -35 degrees where asked."""
    n_coat = _tilted_png(tmp_path / "coat_n.png", 25.0)
    _tilted_png(tmp_path / "base_n.png", -35.0)
    base = "Kd 0.6 0.3 0.2\nPm 0.3\nPr 0.5\n" + ("norm base_n.png\n" if base_map else "")
    coat = "set clearcoat 0.8\nset clearcoat_roughness 0.3\n"
    coat += "set clearcoat_normal_map coat_n.png\n" if coat_map else ""
    quad = (quad_obj([(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1)], material="coated")
            + "v 3 0 0\nv 4 0 0\nv 4 0 1\nusemtl bare\nf -3 -2 -1\n")
    objs, mtls = write_scene_files(tmp_path, "coat", quad, f"newmtl coated\n{base}{coat}\nnewmtl bare\n{base}")
    dev = DeviceScene(load_scene(objs, mtls))
    names = dev.scene.materials.names
    return dev, (names.index("coated"), names.index("bare")), (n_coat if coat_map else np.array([0.0, 0.0, 1.0]))


@pytest.mark.parametrize("coat_map, base_map", [(True, False), (False, True), (True, True)])
def test_the_coat_has_a_normal_of_its_own(tmp_path, coat_map, base_map):
    """KHR_materials_clearcoat's clearcoatNormalTexture: the coat's layer is the spec's formula about
    the coat's normal, f = (1 - c F(wo.nc)) f_rest + c F(wo.nc) D V (wi.nc) in numpy in the coat's frame:
    its own map (tilted 25 degrees towards +u) about the interpolated normal, or, without one, the
    interpolated normal itself, even where the base has a normal map (here tilted -35 degrees)."""
    dev, rows, nc = _coat_rows(tmp_path, coat_map, base_map)
    assert dev.features.needs("pbr.coat_frame")
    evaluate = _eval_kernel(dev.features, shaded=True)
    frame = _frame_about(nc)
    rng = np.random.default_rng(4)
    for theta in (-40.0, 10.0, 45.0):
        wo = np.array([np.sin(np.radians(theta)), 0.0, np.cos(np.radians(theta))])
        wi = upper_directions(rng, 96)
        wi = wi[wi @ nc > 0.05]                                  # above the coat too
        f = eval_rows(evaluate, dev, rows, wo, wi)
        lit = f[1].max(axis=1) > 0             # above the base's (mapped) normal too: the rest is drawn
        assert lit.mean() > 0.4
        weight, coat_f = _coat_numpy((frame @ wo)[None], wi @ frame.T, 0.8, 0.3)
        np.testing.assert_allclose(f[0][lit], (f[1] * (1 - weight[:, None]) + coat_f[:, None])[lit], rtol=2e-5,
                                   atol=1e-6)


def test_a_coat_without_maps_keeps_the_shared_frame(tmp_path):
    """No map anywhere on a coated row: the coat shares the base's frame and compiles no frame of its own."""
    dev, _, _ = _coat_rows(tmp_path, False, False)
    assert dev.features.needs("pbr.clearcoat") and not dev.features.needs("pbr.coat_frame")


@pytest.mark.parametrize("rough", [0.0, 0.4])
def test_a_tilted_coat_over_the_white_dielectric_creates_no_light(scene_dir, rough):
    """A white furnace through a coat whose normal map tilts it 30 degrees: the layering never reflects
    more than comes in (at most 1, to the render's error), and loses little (directions between the
    coat's and the base's horizons, and the rough coat's single-scattering shortfall)."""
    _tilted_png(scene_dir / "tilt30.png", 30.0)
    dev = _sphere_scene(scene_dir, f"tilted_coat_{rough}", "Kd 1 1 1\nPr 0.4\nset clearcoat 1\n"
                        f"set clearcoat_roughness {rough}\nset clearcoat_normal_map tilt30.png\n")
    assert dev.features.needs("pbr.coat_frame")
    mean, se = _disc_mean(dev)
    assert np.all(mean <= 1.0 + 0.003 + 4 * se) and np.all(mean >= 0.98), (mean, se)
