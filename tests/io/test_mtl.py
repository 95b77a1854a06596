"""MTL reader: the seed's tags and defaults (SEMANTICS §6), the standard tags' mapping, errors."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from warp_spt.io.mtl import builtin_checker, load_mtl, parse_mtl_bytes
from warp_spt.scene.errors import SceneError
from warp_spt.scene.model import CHECKER_NAME, TextureRef

# SEMANTICS §6.2, written out independently of the Material defaults
SEED_DIFFUSE = (0x9F / 256, 0x8F / 256, 0x7C / 256)
SEED_REFLECT = (0xAF / 256, 0xBF / 256, 0xCF / 256)
SEED_REFRACT = (0xBB / 256, 0xBC / 256, 0xB1 / 256)
ROOT = Path(__file__).resolve().parents[2]


def mtl(text: str, path: str = "lib/m.mtl"):
    return parse_mtl_bytes(text.encode("utf-8"), path)


def one(text: str):
    """The material of a standard file (the pbr kind)."""
    (m,) = mtl("newmtl m\n" + text).values()
    return m


def seed_one(text: str):
    """The same material in a file of the seed's dialect (another material uses a seed tag)."""
    return mtl("newmtl m\n" + text + "newmtl zz\nKl 0 0 0\n")["m"]


def test_defaults_of_a_new_material():
    m = mtl("newmtl m\nnewmtl seed\nFuzz 0.5\n")["m"]      # a seed tag anywhere: the seed's dialect
    assert m.seed_dialect
    assert m.name == "m" and m.source == "lib/m.mtl" and m.line == 1
    assert m.diffuse == pytest.approx(SEED_DIFFUSE) and m.diffuse == pytest.approx((0.62109375, 0.55859375, 0.484375))
    assert m.reflect == pytest.approx(SEED_REFLECT)
    assert m.refract == pytest.approx(SEED_REFRACT)
    assert m.emission == (0, 0, 0)
    assert (m.roughness, m.fuzz, m.ior, m.refractable, m.checker) == (0.85, pytest.approx(0.62), 1.0, False, False)
    assert m.diffuse_map is m.reflect_map is m.refract_map is m.emission_map is None


def test_builtin_checker():
    c = builtin_checker()
    assert c.name == CHECKER_NAME and c.checker
    assert (c.roughness, c.fuzz, c.ior, c.refractable) == (0.75, pytest.approx(0.62), 1.0, False)
    assert c.refract == pytest.approx(SEED_REFRACT) and c.emission == (0, 0, 0)


def test_seed_tags():
    m = one("Kd 0.1 0.2 0.3\nKl 1.8 1.8 1.8\nKt 0.4 0.5 0.6\nRoughness 0.13\nFuzz 0.18\nKn 1.62\nRefractable\n")
    assert m.diffuse == m.reflect == (0.1, 0.2, 0.3)
    assert m.emission == (1.8, 1.8, 1.8) and m.refract == (0.4, 0.5, 0.6)
    assert (m.roughness, m.fuzz, m.ior, m.refractable) == (0.13, 0.18, 1.62, True)


def test_kd_sets_reflect_and_kr_only_reflect_in_line_order():
    assert one("Kd 1 0 0\nKr 0 1 0\n").diffuse == (1, 0, 0) and one("Kd 1 0 0\nKr 0 1 0\n").reflect == (0, 1, 0)
    m = one("Kr 0 1 0\nKd 1 0 0\n")
    assert m.reflect == (1, 0, 0)


def test_texture_tags_and_map_kt():
    m = one("map_Kd tex/a.png\nmap_Kl glow.png\nmap_Kt t.png\n")
    assert m.diffuse_map == m.reflect_map == TextureRef("tex/a.png", "lib/m.mtl", 2)
    assert m.emission_map == TextureRef("glow.png", "lib/m.mtl", 3)
    assert m.refract_map == TextureRef("t.png", "lib/m.mtl", 4)
    m2 = one("map_Kd a.png\nmap_Kr r.png\n")
    assert m2.diffuse_map.path == "a.png" and m2.reflect_map.path == "r.png"


def test_constant_and_texture_replace_each_other():
    assert one("map_Kd a.png\nKd 1 1 1\n").base_color_map is None
    m = one("Kd 1 1 1\nmap_Kd a.png\n")
    assert m.base_color_map.path == "a.png" and m.base_color == (1, 1, 1)
    assert seed_one("map_Kd a.png\nKd 1 1 1\n").diffuse_map is None
    m = seed_one("Kd 1 1 1\nmap_Kd a.png\n")
    assert m.diffuse_map.path == "a.png" and m.diffuse == (1, 1, 1)


def test_texture_options_are_skipped_and_names_keep_spaces():
    m = one("map_Kd -s 2 2 1 -o 0.5 -clamp on -bm 0.3 dir\\my tex.png\n")
    assert m.base_color_map.path == "dir\\my tex.png"


def test_later_definition_wins_and_lines_before_newmtl_are_ignored():
    lib = mtl("Kd 0 0 0\nnewmtl a\nKd 1 0 0\nnewmtl b\nKd 0 1 0\nnewmtl a\nKd 0 0 1\n")
    assert set(lib) == {"a", "b"}
    assert lib["a"].base_color == (0, 0, 1) and lib["a"].line == 6 and lib["b"].base_color == (0, 1, 0)


def test_unknown_tags_comments_case_and_grey_colours():
    m = one("# c\nKa 1 1 1\nNs 100\nbump b.png\nfoo bar\nkd 0.5  # grey\nKE 2\n")
    assert m.base_color == (0.5, 0.5, 0.5) and m.emission == (2, 2, 2) and m.bump_map.path == "b.png"
    m = seed_one("# c\nKa 1 1 1\nNs 100\nbump b.png\nfoo bar\nkd 0.5  # grey\nKE 2\n")
    assert m.diffuse == m.reflect == (0.5, 0.5, 0.5) and m.emission == (2, 2, 2) and m.bump_map is None


def test_standard_tags():
    from warp_spt.scene.material_schema import KIND_PBR

    m = one("Kd 0.8 0.8 0.8\nKs 0.5 0.5 0.5\nKe 1 2 3\nNi 1.45\nTf 0.9 1 0.9\n")
    assert m.kind == KIND_PBR and not m.seed_dialect
    assert m.base_color == (0.8, 0.8, 0.8) and m.specular_color == (1.0, 1.0, 1.0)     # Blender's Ks 0.5 = F0 4%
    assert m.emission == (1, 2, 3) and m.ior == 1.45 and m.transmission == 0.0      # Tf tints transmission only
    assert one("map_Ke e.png\nmap_Ks s.png\n").emission_map.path == "e.png"
    assert one("Kd 1 1 1\n").ior == 1.5                                             # no Ni: glass's 1.5
    m = one("Pm 0.7\nPr 0.3\nmap_Pm m.png\nmap_Pr r.png\nnorm -bm 0.5 n.png\nmap_d a.png\naniso 0.4\nanisor 0.25\n")
    assert (m.metallic, m.roughness, m.anisotropy) == (0.7, 0.3, 0.4)
    assert m.anisotropy_rotation == pytest.approx(1.5707963)
    assert (m.metallic_map.path, m.roughness_map.path, m.normal_map.path, m.opacity_map.path) == (
        "m.png", "r.png", "n.png", "a.png")
    assert m.normal == 0.5
    m = seed_one("Kd 0.8 0.8 0.8\nKs 0.5 0.5 0.5\nKe 1 2 3\nNi 1.45\nTf 0.9 1 0.9\n")
    assert m.diffuse == (0.8, 0.8, 0.8) and m.reflect == (0.5, 0.5, 0.5)
    assert m.emission == (1, 2, 3) and m.ior == 1.45 and m.refract == (0.9, 1, 0.9)


@pytest.mark.parametrize("text, metallic, rough, transmission", [
    ("illum 2\n", 0.0, 1.0, 0.0),                 # no Ns, no Pr: matte
    ("illum 3\n", 1.0, 0.0, 0.0),                 # ray-traced reflection: a smooth metal
    ("illum 4\n", 0.0, 0.0, 1.0),                 # ray-traced refraction: smooth glass
    ("illum 7\nNs 98\n", 0.0, 0.02 ** 0.25, 1.0),  # Phong exponent: alpha = sqrt(2 / (Ns + 2))
    ("d 0.25\n", 0.0, 1.0, 0.75),
    ("Tr 0.75\n", 0.0, 1.0, 0.75),
    ("illum 4\nd 0.9\n", 0.0, 0.0, pytest.approx(0.1)),
    ("Pm 0.5\nPr 0.2\nNs 5\n", 0.5, 0.2, 0.0),   # Pr wins over Ns
])
def test_standard_illum_opacity_and_roughness(text, metallic, rough, transmission):
    m = one(text)
    assert (m.metallic, m.roughness, m.transmission) == (metallic, pytest.approx(rough), transmission)


def test_unmodelled_standard_tags_are_reported_once():
    said = []
    parse_mtl_bytes(b"newmtl a\nPs 0.5\nPc 1\nnewmtl b\nPs 0.2\nmap_Ks s.png\n", "x.mtl", said.append)
    assert len(said) == 1 and "Ps" in said[0] and "Pc" in said[0] and "map_Ks" in said[0], said


@pytest.mark.parametrize("text, rough, fuzz, refractable", [
    ("illum 2\n", 1.0, 0.62, False),              # standard files: no Ks, no specular lobe
    ("illum 3\n", 0.0, 0.0, False),
    ("illum 5\n", 0.0, 0.0, False),
    ("illum 4\n", 0.0, 0.0, True),
    ("illum 7\n", 0.0, 0.0, True),
    ("d 1\n", 1.0, 0.62, False),
    ("d 0.25\n", 0.25, 0.62, True),
    ("Tr 0.75\n", 0.25, 0.62, True),
    ("illum 3\nd 0.5\n", 0.0, 0.0, True),
    ("Roughness 0.4\nFuzz 0.1\nillum 7\n", 0.4, 0.1, True),   # explicit seed tags win
    ("d 0.2\nRoughness 0.6\n", 0.6, 0.62, True),
])
def test_illum_and_opacity_mapping(text, rough, fuzz, refractable):
    if "Roughness" not in text and "Fuzz" not in text:
        if text.startswith(("illum 2", "d 1")):
            return              # a standard Kd-only material: the pbr kind (test_standard_illum_opacity_and_roughness)
        m = seed_one(text)      # the seed's dialect keeps its mapping onto the seed's model
        assert (m.roughness, m.fuzz, m.refractable) == (pytest.approx(min(rough, 0.85) if rough else 0.0),
                                                       pytest.approx(fuzz), refractable)
        return
    m = one(text)
    assert (m.roughness, m.fuzz, m.refractable) == (pytest.approx(rough), pytest.approx(fuzz), refractable)


ERRORS = [
    ("newmtl\n", 1, "expected a material name after 'newmtl'"),
    ("newmtl a\nKd 1 1\n", 2, "expected 1 or 3 numbers after 'Kd', got 2"),
    ("newmtl a\nKd 1 x 1\n", 2, "expected a number after 'Kd', got 'x'"),
    ("newmtl a\n\nKl 1 nan 1\n", 3, "expected a number after 'Kl', got 'nan'"),
    ("newmtl a\nKd 1 -1 1\n", 2, "expected colour values in [0, 1] after 'Kd', got -1"),
    ("newmtl a\nRoughness 1.5\n", 2, "expected a value in [0, 1] after 'Roughness', got 1.5"),
    ("newmtl a\nRoughness\n", 2, "expected 1 number after 'Roughness', got 0"),
    ("newmtl a\nFuzz -0.1\n", 2, "expected a value >= 0 after 'Fuzz'"),
    ("newmtl a\nKn 0\n", 2, "expected a value in [0.001, 1000] after 'Kn', got 0"),
    ("newmtl a\nNi -1\n", 2, "expected a value in [0.001, 1000] after 'Ni'"),
    ("newmtl a\nd 2\n", 2, "expected a value in [0, 1] after 'd'"),
    ("newmtl a\nillum x\n", 2, "expected an integer illumination model, got 'x'"),
    ("newmtl a\nmap_Kd\n", 2, "expected a texture file name after 'map_Kd'"),
    ("newmtl a\nKt 1e400 1 1\n", 2, "expected a finite number after 'Kt'"),
]


@pytest.mark.parametrize("text, line, message", ERRORS)
def test_errors_name_file_line_and_expectation(text, line, message):
    with pytest.raises(SceneError) as info:
        mtl(text, path="x/bad.mtl")
    assert (info.value.path, info.value.line) == ("x/bad.mtl", line)
    assert message in info.value.message


def test_missing_file(tmp_path):
    with pytest.raises(SceneError, match="cannot read MTL file"):
        load_mtl(tmp_path / "nope.mtl")


def test_crlf_and_utf8_names(tmp_path):
    p = tmp_path / "u.mtl"
    p.write_bytes("newmtl 红色 材质\r\nKd 1 0 0\r\n".encode("utf-8"))
    lib = load_mtl(p)
    assert lib["红色 材质"].base_color == (1, 0, 0)


def test_seed_demo_library(seed_demo):
    lib = load_mtl(seed_demo / "testMiku.mtl")
    assert set(lib) == {f"Texture{k}" for k in range(7)} | {
        "light", "white", "green", "red", "Box1", "Box2", "Ball1", "Ball2", "Floor", "BackWall"}
    assert lib["light"].emission == (1.8, 1.8, 1.8) and lib["light"].diffuse == (1, 1, 1)
    assert lib["Floor"].roughness == 0.7 and lib["Floor"].fuzz == 0.18
    b2 = lib["Ball2"]
    assert (b2.refract, b2.roughness, b2.fuzz, b2.ior, b2.refractable) == ((1, 1, 1), 0.0, 0.0, 0.5, True)
    assert lib["Texture3"].diffuse_map.path == "renderRes/face_MikuAp.png" and lib["Texture3"].emission == (0.15,) * 3
    assert lib["Texture2"].diffuse == pytest.approx((0.87, 0.783, 0.83955), abs=1e-6)
    alt = load_mtl(seed_demo / "testMiku_ior1.62.mtl")["Ball2"]
    assert (alt.ior, alt.fuzz) == (1.62, 0.18)


def test_a_kd_only_material_is_matte_in_a_standard_file_and_keeps_the_seed_lobe_in_the_seeds():
    standard = mtl("newmtl plain\nKd 0.8 0.8 0.8\nnewmtl shiny\nKd 0.5 0.5 0.5\nKs 0.5 0.5 0.5\nNs 98\n"
                   "newmtl blurred\nKd 0.5 0.5 0.5\nNs 18\n")
    assert standard["plain"].roughness == 1.0 and not standard["plain"].seed_dialect
    assert standard["plain"].metallic == 0.0 and standard["plain"].transmission == 0.0
    assert standard["shiny"].roughness == pytest.approx(0.02 ** 0.25)           # alpha = sqrt(2 / (Ns + 2))
    assert standard["blurred"].roughness == pytest.approx(0.1 ** 0.25)
    # the same Kd-only material in a file that uses one of the seed's own tags, before or after it
    for text in ("newmtl plain\nKd 0.8 0.8 0.8\nnewmtl lamp\nKl 1 1 1\n",
                 "newmtl lamp\nKl 1 1 1\nnewmtl plain\nKd 0.8 0.8 0.8\n"):
        seed = mtl(text)["plain"]
        assert seed.roughness == 0.85 and seed.fuzz == pytest.approx(0.62) and seed.seed_dialect


# ---------------------------------------------------------------------------------------------
# ``kind NAME`` and ``set FIELD VALUE...``: a material names its kind and any schema field by name


def test_kind_pbr_in_a_seed_file_reads_the_standard_mapping_and_leaves_the_dialect_alone():
    lib = mtl("newmtl gold\nkind pbr\nKd 1 0.8 0.3\nPr 0.4\nFuzz 0.2\nnewmtl old\nKd 0.5 0.5 0.5\nPr 0.3\n"
              "Refractable\n")
    gold, old = lib["gold"], lib["old"]
    assert gold.kind == 1 and gold.base_color == (1, 0.8, 0.3) and gold.roughness == 0.4   # Pr: roughness
    assert gold.seed_dialect            # the file's conventions: it uses the seed's tags
    assert old.kind == 0 and old.fuzz == 0.3 and old.refractable                    # Pr: fuzz
    warnings = []
    lib = parse_mtl_bytes(b"newmtl a\nkind pbr\nFuzz 0.2\nnewmtl b\nKd 1 0 0\n", "f.mtl", warnings.append)
    assert lib["b"].kind == 1 and not lib["b"].seed_dialect     # a seed tag under 'kind pbr': not the file's
    assert warnings == ["f.mtl: read but not supported (ignored): Fuzz"]


def test_kind_seed_in_a_standard_file_reads_the_seeds_mapping():
    warnings = []
    lib = parse_mtl_bytes(b"newmtl s\nkind seed\nKd 0.2 0.3 0.4\nPr 0.3\nnorm n.png\nnewmtl p\nPr 0.3\n", "f.mtl",
                          warnings.append)
    s, p = lib["s"], lib["p"]
    assert s.kind == 0 and s.diffuse == s.reflect == (0.2, 0.3, 0.4) and s.fuzz == 0.3 and not s.seed_dialect
    assert p.kind == 1 and p.roughness == 0.3
    assert warnings == ["f.mtl: read but not supported (ignored): norm"]    # the seed's kind has no normal map


def test_set_writes_one_field_by_its_schema_name_and_wins_over_the_classic_tags():
    from warp_spt.scene.proctex_registry import ProcRef

    m = one("set roughness 0.3\nillum 3\nset base_color 0.5\nset thin on\nset metallic_map -s 2 2 m.png\n"
            "set emission_map proc:noise scale=3\nset multiscatter off\nset specular_color 2 2 2\nKd 1 0 0\n")
    assert (m.kind, m.roughness, m.metallic, m.thin, m.multiscatter) == (1, 0.3, 1.0, True, False)  # illum 3: metal
    assert m.base_color == (0.5, 0.5, 0.5) and m.specular_color == (2, 2, 2)          # Kd is later, set still wins
    assert m.metallic_map == TextureRef("m.png", "lib/m.mtl", 6)
    assert isinstance(m.emission_map, ProcRef) and m.emission_map.name == "noise"
    s = seed_one("set fuzz 0.1\nset diffuse 0 1 0\nset refractable 1\nset RoughNess 0.25\n")
    assert (s.kind, s.fuzz, s.diffuse, s.refractable, s.roughness) == (0, 0.1, (0, 1, 0), True, 0.25)
    assert s.reflect == pytest.approx(SEED_REFLECT)          # set names one field (Kd names two)
    warnings = []
    parse_mtl_bytes(b"newmtl m\nset base_color_map -s 2 2 a.png\n", "f.mtl", warnings.append)
    assert warnings == ["f.mtl: read but not supported (ignored): texture option -s"]


@pytest.mark.parametrize("text, line, message", [
    ("kind pbr\n", 1, "expected 'newmtl NAME' before 'kind'"),
    ("newmtl m\nKd 1 0 0\nkind pbr\n", 3, "expected 'kind' right after 'newmtl m' (line 1)"),
    ("newmtl m\nkind pbr\nkind seed\n", 3, "expected 'kind' right after 'newmtl m' (line 1)"),
    ("newmtl m\nkind\n", 2, "expected a material kind after 'kind' (seed, pbr), got ''"),
    ("newmtl m\nkind plastic\n", 2, "expected a material kind after 'kind' (seed, pbr), got 'plastic'"),
    ("newmtl m\nset\n", 2, "expected a material field after 'set' (diffuse, diffuse_map, reflect"),
    ("newmtl m\nset rough 1\n", 2, "got 'rough'"),
    ("newmtl m\nkind pbr\nset fuzz 1\n", 3, "expected a material field after 'set' (emission, emission_map"),
    ("newmtl m\nset kind 1\n", 2, "got 'kind'"),
    ("newmtl m\nset tex 1\n", 2, "got 'tex'"),
    ("newmtl m\nset roughness\n", 2, "expected a value after 'set roughness'"),
    ("newmtl m\nset roughness 1.5\n", 2, "expected a value in [0, 1] after 'set roughness', got 1.5"),
    ("newmtl m\nset roughness x\n", 2, "set roughness"),
    ("newmtl m\nset base_color 1 2\n", 2, "set base_color"),
    ("newmtl m\nset base_color 1 2 1\n", 2, "expected colour values in [0, 1] after 'set base_color', got 2"),
    ("newmtl m\nset emission -1\n", 2, "expected colour values in [0, 1e+30] after 'set emission', got -1"),
    ("newmtl m\nset thin yes\n", 2, "expected on or off after 'set thin', got 'yes'"),
    ("newmtl m\nset ior 0\n", 2, "expected a value in [0.001, 1000] after 'set ior'"),
    ("newmtl m\nset roughness_map proc:nope\n", 2, "unknown procedural texture 'nope' after 'set roughness_map'"),
    # the kind is the file's dialect, known at its end; the error still names the set line
    ("newmtl m\nset metallic 1\nnewmtl z\nKl 0 0 0\n", 2, "expected a field of material kind 'seed' after 'set'"),
    ("newmtl m\nset fuzz 0.5\n", 2, "expected a field of material kind 'pbr' after 'set'"),
])
def test_kind_and_set_errors_name_file_line_and_expectation(text, line, message):
    with pytest.raises(SceneError) as info:
        mtl(text)
    assert str(info.value).startswith(f"lib/m.mtl:{line}: ") and message in str(info.value), str(info.value)


# A probe kind with two columns of its own, written into the schema's source (its MATERIAL_KINDS line
# and two Column lines, as tests/scene/test_material_schema.py does); the MTL reader is not edited.
PROBE_KIND = textwrap.dedent('''
    import importlib.util, re, sys
    path, folder = sys.argv[1:3]
    src = open(path).read()
    line = 'MATERIAL_KINDS: tuple[str, ...] = ("seed", "pbr")'
    assert line in src
    src = src.replace(line, 'MATERIAL_KINDS: tuple[str, ...] = ("seed", "pbr", "probe")')
    end = src.index("\\n)\\n", src.index("COLUMNS: tuple[Column, ...] = (")) + 1
    NEXT_SLOT = len(re.findall(r"slot=[0-9]", src))       # the next free texture slot (they are 0..n-1)
    extra = (f'    Column("glow", COLOR, (0.0, 0.0, 0.0), 0.0, 1.0, "probe", slot={NEXT_SLOT}, kinds=("probe",)),\\n'
             '    Column("haze", SCALAR, 0.5, 0.0, 2.0, "probe", kinds=("probe",)),\\n')
    spec = importlib.util.spec_from_loader("warp_spt.scene.material_schema", loader=None)
    schema = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = schema
    exec(compile(src[:end] + extra + src[end:], path, "exec"), schema.__dict__)

    from warp_spt.io.loader import load_scene
    from warp_spt.io.mtl import parse_mtl_bytes
    from warp_spt.scene.errors import SceneError

    warnings = []
    lib = parse_mtl_bytes(open(folder + "/a.mtl", "rb").read(), "a.mtl", warnings.append)
    p = lib["p"]
    assert (p.kind, p.glow, p.haze, p.emission, p.ior) == (2, (0.5, 0.25, 1.0), 1.5, (2.0, 2.0, 2.0), 1.0), p
    assert p.glow_map.name == "noise" and p.interior is not None and not p.seed_dialect
    assert warnings == ["a.mtl: read but not supported (ignored): Kd"], warnings   # no reading of classic tags
    for text, message in ((b"newmtl q\\nkind probe\\nset haze 3\\n", "a.mtl:3: expected a value in [0, 2]"),
                          (b"newmtl q\\nkind probe\\nset metallic 1\\n", "a.mtl:3: expected a material field"),
                          (b"newmtl q\\nset glow 1\\n", "a.mtl:2: expected a field of material kind 'pbr'")):
        try:
            parse_mtl_bytes(text, "a.mtl")
            raise AssertionError(text)
        except SceneError as err:
            assert str(err).startswith(message), err
    scene = load_scene([folder + "/a.obj"], [folder + "/a.mtl"])           # the host table and its checks
    row = scene.materials.names.index("p")
    assert scene.materials.kind[row] == 2 and scene.materials.haze[row] == 1.5
    print("ok")
''')


def test_a_registered_kind_and_its_columns_are_named_from_an_mtl_file_with_no_parser_edit(tmp_path):
    (tmp_path / "a.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl p\nf 1 2 3\n")
    (tmp_path / "a.mtl").write_text("newmtl p\nkind probe\nset glow 0.5 0.25 1\nset glow_map proc:noise\n"
                                    "set haze 1.5\nset emission 2\nKd 1 0 0\nmedium_sigma_a 1\n")
    src = str(ROOT / "warp_spt" / "scene" / "material_schema.py")
    out = subprocess.run([sys.executable, "-c", PROBE_KIND, src, str(tmp_path)], capture_output=True, text=True,
                         cwd=ROOT, env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=300)
    assert out.returncode == 0 and out.stdout.strip().endswith("ok"), out.stderr[-3000:]
