"""load_scene and validate_scene: material resolution, textures, normals, warnings, the seed's demo."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from warp_spt.io.loader import load_scene, validate_scene
from warp_spt.scene.errors import SceneError
from warp_spt.scene.model import (
    CHECKER_NAME,
    SLOT_DIFFUSE,
    SLOT_EMISSION,
    SLOT_REFLECT,
    SLOT_REFRACT,
    TEX_CHECKER,
    TEX_NONE,
)

TRI = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"


def write(folder: Path, name: str, text: str) -> str:
    p = folder / name
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text, encoding="utf-8")
    return str(p)


def quiet(objs, mtls=()):
    got: list[str] = []
    return load_scene(objs, mtls, warn=got.append), got


def test_materials_resolve_after_all_files(tmp_path):
    obj = write(tmp_path, "a.obj", TRI + "usemtl red\nf 1 2 3\nusemtl ghost\nb 0 0 5 1\n")
    mtl = write(tmp_path, "m.mtl", "newmtl unused\nmap_Kd absent.png\nnewmtl red\nKd 1 0 0\nRoughness 0.5\n")
    scene, warned = quiet([obj], [mtl])
    t = scene.materials
    assert t.names == [CHECKER_NAME, "red"]
    np.testing.assert_allclose(t.diffuse[1], [1, 0, 0])
    np.testing.assert_allclose(t.reflect[1], [1, 0, 0])
    assert t.roughness[1] == 0.5 and t.roughness[0] == 0.75
    assert t.tex[0].tolist() == [TEX_CHECKER, TEX_CHECKER] + [TEX_NONE] * (t.tex.shape[1] - 2)
    assert scene.meshes[0].face_material.tolist() == [1] and scene.sphere_material.tolist() == [0]
    assert warned == scene.warnings and len(warned) == 1 and "unknown material 'ghost'" in warned[0]
    assert f"{obj}:9:" in warned[0]   # the usemtl line


def test_one_warning_per_unknown_name(tmp_path):
    a = write(tmp_path, "a.obj", TRI + "usemtl x\nf 1 2 3\nusemtl y\nf 1 2 3\nusemtl x\nf 1 2 3\n")
    b = write(tmp_path, "b.obj", TRI + "usemtl x\nf 1 2 3\n")
    scene, warned = quiet([a, b])
    assert sorted(w.split("unknown material ")[1].split(";")[0] for w in warned) == ["'x'", "'y'"]
    assert all(m.face_material.tolist() == [0] * len(m.face_material) for m in scene.meshes)


def test_default_warning_goes_through_warnings_module(tmp_path):
    obj = write(tmp_path, "a.obj", TRI + "usemtl nope\nf 1 2 3\n")
    with pytest.warns(UserWarning, match="unknown material 'nope'"):
        load_scene([obj])


def test_mtllib_relative_to_obj_and_explicit_mtl_overrides(tmp_path):
    obj = write(tmp_path, "sub/a.obj", "mtllib libs/own.mtl missing.mtl\n" + TRI + "usemtl m\nf 1 2 3\nusemtl k\nf 1 2 3\n")
    write(tmp_path, "sub/libs/own.mtl", "newmtl m\nKd 0 1 0\nnewmtl k\nKd 0 0 1\n")
    explicit = write(tmp_path, "x.mtl", "newmtl m\nKd 1 0 0\n")
    scene, warned = quiet([obj], [explicit])
    t = scene.materials
    np.testing.assert_allclose(t.base_color[t.names.index("m")], [1, 0, 0])      # standard files: pbr
    np.testing.assert_allclose(t.base_color[t.names.index("k")], [0, 0, 1])
    assert len(warned) == 1 and "missing.mtl not found" in warned[0]


def test_checker_name_is_reserved(tmp_path):
    obj = write(tmp_path, "a.obj", TRI + f"usemtl {CHECKER_NAME}\nf 1 2 3\n")
    mtl = write(tmp_path, "m.mtl", f"newmtl {CHECKER_NAME}\nKd 1 0 0\n")
    scene, warned = quiet([obj], [mtl])
    assert scene.materials.names == [CHECKER_NAME] and "built-in" in warned[0]
    assert scene.materials.roughness[0] == 0.75


def make_png(path: Path, pixels: np.ndarray, mode: str = "RGB") -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray(pixels.astype(np.uint8), mode).save(path)


def test_textures_loaded_once_for_used_materials(tmp_path):
    px = np.array([[[255, 0, 0, 10], [0, 51, 0, 255]], [[0, 0, 255, 0], [17, 34, 68, 128]],
                   [[1, 2, 3, 4], [5, 6, 7, 8]]])
    make_png(tmp_path / "tex/t.png", px, "RGBA")
    mtl = write(tmp_path, "m.mtl", "newmtl a\nmap_Kd tex/t.png\nnewmtl b\nmap_Kl tex\\t.png\nmap_Kt ./tex/t.png\n"
                                   "newmtl c\nmap_Kd nowhere.png\n")
    obj = write(tmp_path, "o.obj", TRI + "usemtl a\nf 1/1 2/2 3/3\nusemtl b\nf 1 2 3\n")
    scene, _ = quiet([obj], [mtl])
    assert len(scene.textures) == 1
    tex = scene.textures[0]
    assert tex.dtype == np.float32 and tex.shape == (3, 2, 3)
    np.testing.assert_allclose(tex, px[..., :3] / 255.0, rtol=1e-6)   # row 0 = top, alpha ignored, /255
    t = scene.materials
    a, b = t.names.index("a"), t.names.index("b")
    assert t.tex[a, SLOT_DIFFUSE] == t.tex[a, SLOT_REFLECT] == 0 and t.tex[a, SLOT_EMISSION] == TEX_NONE
    assert t.tex[b, SLOT_EMISSION] == t.tex[b, SLOT_REFRACT] == 0 and t.tex[b, SLOT_DIFFUSE] == TEX_NONE


def test_texture_falls_back_to_working_directory(tmp_path, monkeypatch):
    make_png(tmp_path / "cwd/res/t.png", np.full((1, 1, 3), 51))
    mtl = write(tmp_path, "lib/m.mtl", "newmtl a\nmap_Kd res/t.png\n")
    obj = write(tmp_path, "o.obj", TRI + "usemtl a\nf 1 2 3\n")
    monkeypatch.chdir(tmp_path / "cwd")
    scene, _ = quiet([obj], [mtl])
    np.testing.assert_allclose(scene.textures[0], ((0.2 + 0.055) / 1.055) ** 2.4, rtol=1e-6)  # a standard file: sRGB


def test_missing_texture_of_used_material_names_mtl_line_and_paths(tmp_path):
    mtl = write(tmp_path, "m.mtl", "newmtl a\nKd 1 1 1\nmap_Kd gone.png\n")
    obj = write(tmp_path, "o.obj", TRI + "usemtl a\nf 1 2 3\n")
    with pytest.raises(SceneError) as info:
        quiet([obj], [mtl])
    assert (info.value.path, info.value.line) == (mtl, 3)
    assert "gone.png" in info.value.message and str(tmp_path / "gone.png") in info.value.message


def test_unreadable_texture(tmp_path):
    (tmp_path / "bad.png").write_bytes(b"not a png")
    mtl = write(tmp_path, "m.mtl", "newmtl a\nmap_Kd bad.png\n")
    obj = write(tmp_path, "o.obj", TRI + "usemtl a\nf 1 2 3\n")
    with pytest.raises(SceneError, match="cannot read texture") as info:
        quiet([obj], [mtl])
    assert info.value.line == 2


def test_corner_uv_and_normals(tmp_path):
    text = ("v 0 0 0\nv 2 0 0\nv 0 2 0\nv 0 0 2\nvt 0.25 0.5\nvn 0 0 3\nvn 0 0 0\n"
            "f 1/1/1 2//1 3\nf 1 3 4\nf 1//2 2//1 4//1\n")
    scene, warned = quiet([write(tmp_path, "n.obj", text)])
    m = scene.meshes[0]
    np.testing.assert_allclose(m.corner_uv[0], [[0.25, 0.5], [0, 0], [0, 0]])
    np.testing.assert_allclose(m.corner_uv[1:], 0)
    n = m.corner_normal
    assert n.dtype == np.float32 and n.shape == (3, 3, 3)
    np.testing.assert_allclose(n[0], [[0, 0, 1]] * 3)              # given (normalised), given, geometric
    np.testing.assert_allclose(n[1], [[1, 0, 0]] * 3)              # no vn: cross((0,2,0), (0,0,2)) = +x
    np.testing.assert_allclose(n[2], [[0, -1, 0], [0, 0, 1], [0, 0, 1]], atol=1e-7)   # zero vn -> geometric
    assert any("zero-length normal" in w for w in warned)


def test_flat_obj_has_no_corner_normals_and_empty_obj_adds_nothing(tmp_path):
    a = write(tmp_path, "a.obj", TRI + "f 1 2 3\n")
    b = write(tmp_path, "b.obj", "# empty\n")
    scene, _ = quiet([a, b])
    assert len(scene.meshes) == 1 and scene.meshes[0].corner_normal is None and scene.meshes[0].name == "a.obj"


def test_degenerate_count_and_no_geometry(tmp_path):
    obj = write(tmp_path, "d.obj", TRI + "f 1 2 3\nf 1 1 2\n")
    scene, warned = quiet([obj])
    # counted, not warned about (issue 31: every UV sphere's poles gave a warning that was noise)
    assert scene.dropped_degenerate == 1 and scene.num_triangles == 1 and not warned
    with pytest.raises(SceneError, match="no geometry"):
        quiet([write(tmp_path, "e.obj", "v 0 0 0\n")])
    with pytest.raises(SceneError, match="no geometry"):
        quiet([])


def test_missing_explicit_files_are_errors(tmp_path):
    with pytest.raises(SceneError, match="cannot read OBJ"):
        quiet([tmp_path / "none.obj"])
    with pytest.raises(SceneError, match="cannot read MTL"):
        quiet([write(tmp_path, "a.obj", TRI + "f 1 2 3\n")], [tmp_path / "none.mtl"])


# ---------------------------------------------------------------- validate_scene


@pytest.fixture()
def good_scene(tmp_path):
    obj = write(tmp_path, "g.obj", TRI + "vn 0 0 1\nusemtl a\nf 1/1/1 2/2/1 3/3/1\nb 0 0 0 1\n")
    return quiet([obj], [write(tmp_path, "g.mtl", "newmtl a\nKd 1 1 1\n")])[0]


def _replace_mesh(scene, **fields):
    scene.meshes[0] = dataclasses.replace(scene.meshes[0], **fields)
    return scene


BREAKERS = {
    "nan position": lambda s: _replace_mesh(s, positions=np.full((3, 3), np.nan, np.float32)),
    "integer positions": lambda s: _replace_mesh(s, positions=s.meshes[0].positions.astype(np.int64)),
    "index out of range": lambda s: _replace_mesh(s, indices=np.array([[0, 1, 3]], np.int32)),
    "negative index": lambda s: _replace_mesh(s, indices=np.array([[0, -1, 2]], np.int32)),
    "uv shape": lambda s: _replace_mesh(s, corner_uv=np.zeros((1, 3, 3), np.float32)),
    "non-unit normal": lambda s: _replace_mesh(s, corner_normal=np.zeros((1, 3, 3), np.float32)),
    "face material": lambda s: _replace_mesh(s, face_material=np.array([7], np.int32)),
    "radius": lambda s: setattr(s, "spheres", np.array([[0, 0, 0, 0]], np.float32)),
    "sphere material": lambda s: setattr(s, "sphere_material", np.array([-1], np.int32)),
    "roughness": lambda s: s.materials.roughness.__setitem__(1, 1.5),
    "ior": lambda s: s.materials.ior.__setitem__(1, 0.0),
    "fuzz": lambda s: s.materials.fuzz.__setitem__(1, -1.0),
    "colour": lambda s: s.materials.emission.__setitem__((1, 0), np.inf),
    "negative colour": lambda s: s.materials.diffuse.__setitem__((1, 0), -0.5),
    "texture slot": lambda s: s.materials.tex.__setitem__((1, 0), 0),
    "texture values": lambda s: s.textures.append(np.full((2, 2, 3), 1.5, np.float32)),
    "row 0": lambda s: s.materials.names.__setitem__(0, "x"),
}


def test_validate_accepts_the_loaded_scene(good_scene):
    validate_scene(good_scene)


@pytest.mark.parametrize("name", sorted(BREAKERS))
def test_validate_rejects(good_scene, name):
    BREAKERS[name](good_scene)
    with pytest.raises(SceneError):
        validate_scene(good_scene)


# ---------------------------------------------------------------- the seed's demo


def test_seed_demo_scene(seed_demo):
    d = seed_demo
    scene, warned = quiet([d / "cornell_export.obj", d / "baller.obj"], [d / "testMiku.mtl"])
    assert scene.num_triangles == 42 and len(scene.spheres) == 3 and scene.textures == []
    t = scene.materials
    assert set(t.names) == {CHECKER_NAME, "light", "white", "Floor", "BackWall", "green", "red", "Box1", "Box2",
                            "Ball1", "Ball2"}
    assert [t.names[k] for k in scene.sphere_material] == ["Ball1", "Ball2", "Ball2"]
    light = t.names.index("light")
    np.testing.assert_allclose(t.emission[light], 1.8)
    assert t.ior[t.names.index("Ball2")] == 0.5 and t.refractable[t.names.index("Ball2")]
    assert len(warned) == 1 and "cornell_export.mtl not found" in warned[0]


def test_seed_utf8_cube_scene(seed_demo):
    scene, warned = quiet([seed_demo / "testUVW.obj"])
    assert scene.num_triangles == 12 and any("'Texture4'" in w for w in warned)
    with pytest.raises(SceneError) as info:   # Texture4's texture is not in the public copy
        quiet([seed_demo / "testUVW.obj"], [seed_demo / "testMiku.mtl"])
    assert info.value.line == 23 and "face_MikuApLove.png" in info.value.message
