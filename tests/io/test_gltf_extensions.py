"""What exporters write into glTF files beyond the core: textures that cannot be read, extensions that
are not read, specular-glossiness materials (gltf/materials.py, gltf/document.py)."""

from __future__ import annotations

import base64
import json

import numpy as np
import pytest

from tests.support.format_files import NORMAL_2X2, gltf_textured_box, png_2x2
from warp_spt.io.gltf import load_gltf, parse_gltf_bytes
from warp_spt.io.loader import load_scene
from warp_spt.scene.errors import SceneError


def _write(tmp_path, g, name="scene.gltf"):
    (tmp_path / name).write_bytes(g.gltf()[0])
    return tmp_path / name


def _quiet(d):
    notes = []
    return load_scene([d], warn=notes.append), notes


def test_a_missing_texture_file_is_a_warning_and_a_neutral_texel(tmp_path):
    g = gltf_textured_box()
    g.doc["images"] = [{"uri": "textures/gone.png"}]
    d = load_gltf(_write(tmp_path, g))
    assert d.materials["scene.gltf: checker"].base_color_map is None          # the factor alone
    assert [w for w in d.warnings if "gone.png" in w] == [
        f"{tmp_path / 'scene.gltf'}: /images/0/uri: 'textures/gone.png' cannot be read "
        f"({tmp_path / 'textures/gone.png'}: no such file or directory): a neutral texel stands for it"]
    scene, _ = _quiet(d)
    assert len(scene.textures) == 0
    # what is unsafe stays refused: a file outside the glTF's folder
    g.doc["images"] = [{"uri": "../elsewhere.png"}]
    (tmp_path / "elsewhere.png").write_bytes(png_2x2())
    (tmp_path / "sub").mkdir()
    with pytest.raises(SceneError, match=r"scene.gltf: /images/0/uri: the file '../elsewhere.png' leads outside"):
        load_gltf(_write(tmp_path / "sub", g))


@pytest.mark.parametrize("embedded", [False, True])
@pytest.mark.parametrize("slot, texel", [("base colour", [1.0, 1.0, 1.0]), ("normal", [0.5, 0.5, 1.0])])
def test_an_unreadable_image_is_a_warning_and_a_neutral_texel(tmp_path, embedded, slot, texel):
    g = gltf_textured_box()
    broken = "data:image/png;base64," + base64.b64encode(b"not a png").decode() if embedded else "broken.png"
    (tmp_path / "broken.png").write_bytes(b"\x89PNG but not really")
    good = {"base colour": png_2x2(), "normal": png_2x2(NORMAL_2X2)}
    g.doc["images"] = [{"uri": broken if slot == s else "data:image/png;base64," + base64.b64encode(good[s]).decode()}
                       for s in ("base colour", "normal")]
    g.doc["textures"] = [{"source": 0}, {"source": 1}]
    g.doc["materials"][0]["normalTexture"] = {"index": 1}
    scene, notes = _quiet(load_gltf(_write(tmp_path, g)))
    said = [n for n in notes if "cannot read texture" in n]
    assert len(said) == 1 and said[0].endswith("a neutral texel stands for it"), notes
    assert [t.tolist() for t in scene.textures if t.shape == (1, 1, 3)] == [[[texel]]]


def test_an_ignored_extension_that_changes_the_look_is_named_once():
    g = gltf_textured_box()
    g.doc["extensionsUsed"] = ["KHR_texture_transform", "KHR_materials_unlit", "KHR_materials_iridescence",
                               "KHR_xmp_json_ld", "KHR_materials_unlit"]
    d = parse_gltf_bytes(g.gltf()[0], "scene.gltf")
    assert d.warnings == ["scene.gltf: /extensionsUsed/1: KHR_materials_unlit is not read: the file renders "
                          "without it",
                          "scene.gltf: /extensionsUsed/2: KHR_materials_iridescence is not read: the file renders "
                          "without it"]


def _spec_gloss(diffuse, specular, glossiness, **more):
    g = gltf_textured_box()
    g.doc["materials"] = [{"name": "sg", "pbrMetallicRoughness": {"baseColorFactor": [0, 1, 0, 1]},
                           "extensions": {"KHR_materials_pbrSpecularGlossiness": {
                               "diffuseFactor": diffuse, "specularFactor": specular, "glossinessFactor": glossiness,
                               **more}}}]
    g.doc["extensionsUsed"] = ["KHR_materials_pbrSpecularGlossiness"]
    g.doc["extensionsRequired"] = ["KHR_materials_pbrSpecularGlossiness"]
    return parse_gltf_bytes(g.gltf()[0], "scene.gltf")


def test_specular_glossiness_is_converted_to_metal_rough():
    # a dielectric: specular at F0 = 0.04 leaves the diffuse as base colour, metallic 0
    d = _spec_gloss([0.5, 0.25, 0.125, 0.75], [0.04, 0.04, 0.04], 0.7)
    m = d.materials["scene.gltf: sg"]
    assert m.metallic == 0.0 and m.roughness == pytest.approx(0.3)
    assert np.allclose(m.base_color, np.array([0.5, 0.25, 0.125]) * 0.96 / 0.96)
    assert m.base_color_map is None and d.extras.materials[0].base_color[3] == 0.75
    # a metal: black diffuse, coloured specular: metallic 1 and the specular as base colour
    m = _spec_gloss([0, 0, 0, 1], [1.0, 0.8, 0.4], 1.0).materials["scene.gltf: sg"]
    assert m.metallic == pytest.approx(1.0) and np.allclose(m.base_color, [1.0, 0.8, 0.4], atol=1e-6)
    assert m.roughness == 0.0 and not d.warnings


def test_specular_glossiness_reads_its_diffuse_texture_and_names_the_one_it_does_not():
    d = _spec_gloss([1, 1, 1, 1], [0.04, 0.04, 0.04], 0.5, diffuseTexture={"index": 0},
                    specularGlossinessTexture={"index": 0})
    m = d.materials["scene.gltf: sg"]
    assert m.base_color_map is not None and m.base_color_map.path == "images/0"
    assert d.warnings == ["scene.gltf: /materials/0/extensions/KHR_materials_pbrSpecularGlossiness/"
                          "specularGlossinessTexture is not read: the material's specular and glossiness factors "
                          "are converted to metal-rough, its texture not"]
    assert json.loads(json.dumps(d.extras.materials[0].extensions))          # kept as written


def test_the_clearcoat_normal_texture_is_read(tmp_path):
    """KHR_materials_clearcoat's clearcoatNormalTexture becomes the coat's normal map with its scale
    (the renderer's frame for it: tests/bsdfs/test_clearcoat.py); its other textures are still named."""
    g = gltf_textured_box()
    g.doc["images"].append({"uri": "data:image/png;base64," + base64.b64encode(png_2x2(NORMAL_2X2)).decode()})
    g.doc["textures"].append({"source": len(g.doc["images"]) - 1})
    g.doc["materials"][0]["extensions"] = {"KHR_materials_clearcoat": {
        "clearcoatFactor": 1.0, "clearcoatNormalTexture": {"index": len(g.doc["textures"]) - 1, "scale": 0.5},
        "clearcoatRoughnessTexture": {"index": 0}}}
    g.doc["extensionsUsed"] = ["KHR_materials_clearcoat"]
    d = load_gltf(_write(tmp_path, g))
    m = d.materials["scene.gltf: checker"]
    assert m.clearcoat == 1.0 and m.clearcoat_normal == 0.5 and m.clearcoat_normal_map is not None
    assert [w.split(": ", 1)[1] for w in d.warnings] == [
        "/materials/0/extensions/KHR_materials_clearcoat/clearcoatRoughnessTexture is not read: the coat has its "
        "factors alone"]
    scene, _ = _quiet(d)
    row = scene.materials.names.index("scene.gltf: checker")
    from warp_spt.scene.material_schema import COLUMN

    slot = scene.materials.tex[row][COLUMN["clearcoat_normal"].slot]
    assert slot >= 0 and np.allclose(scene.textures[slot][..., 2], 1.0, atol=0.2)     # a normal map, mostly +z
