"""The built-in demo in renderRes/: what the issue asks of it, checked with a parser written here."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from warp_spt.demo import DEMO_MTLS, DEMO_OBJS, demo_dir, demo_files

REPO = Path(__file__).resolve().parents[2]
RES = REPO / "renderRes"
# The seed's balls (SEMANTICS §16): centre and radius.
SEED_BALLS = [((12.5409, 15.4094, 8.5959), 6.7822), ((-5.1149, -5.4793, 6.6618), 4.2782),
              ((6.7154, -0.303, 17.1339), 3.815)]


def parse_obj(path: Path) -> dict:
    """A minimal OBJ reader: vertices, vt/vn counts, faces as lists of corner strings, spheres, usemtl."""
    data = {"v": [], "vt": 0, "vn": [], "faces": [], "spheres": [], "usemtl": []}
    for line in path.read_text().splitlines():
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        if tok[0] == "v":
            data["v"].append([float(x) for x in tok[1:4]])
        elif tok[0] == "vt":
            data["vt"] += 1
        elif tok[0] == "vn":
            data["vn"].append([float(x) for x in tok[1:4]])
        elif tok[0] == "f":
            data["faces"].append(tok[1:])
        elif tok[0] == "b":
            data["spheres"].append([float(x) for x in tok[1:5]])
        elif tok[0] == "usemtl":
            data["usemtl"].append(tok[1])
    data["v"] = np.array(data["v"]).reshape(-1, 3)
    data["vn"] = np.array(data["vn"]).reshape(-1, 3)
    return data


def parse_mtl(path: Path) -> dict[str, dict[str, list[str]]]:
    materials: dict[str, dict[str, list[str]]] = {}
    current = None
    for line in path.read_text().splitlines():
        tok = line.split()
        if not tok or tok[0].startswith("#"):
            continue
        if tok[0] == "newmtl":
            current = materials.setdefault(tok[1], {})
        elif current is not None:
            current[tok[0]] = tok[1:]
    return materials


@pytest.fixture(scope="module")
def objs():
    return {name: parse_obj(RES / name) for name in DEMO_OBJS}


@pytest.fixture(scope="module")
def mtl():
    return parse_mtl(RES / "demo.mtl")


def triangles(faces: list[list[str]]) -> int:
    return sum(len(f) - 2 for f in faces)


def test_the_model_has_at_least_50000_triangles_with_uvs_and_normals(objs):
    vase = objs["sculpture.obj"]
    assert triangles(vase["faces"]) >= 50_000
    assert vase["vt"] > 0 and len(vase["vn"]) > 0
    assert all(corner.count("/") == 2 and "//" not in corner for face in vase["faces"] for corner in face)
    np.testing.assert_allclose(np.linalg.norm(vase["vn"], axis=1), 1.0, atol=2e-3)


def test_the_models_normals_point_away_from_its_axis(objs):
    vase = objs["sculpture.obj"]
    centre = vase["v"][:, :2].mean(axis=0)
    radial = vase["v"][:, :2] - centre
    assert ((radial * vase["vn"][:, :2]).sum(axis=1) > 0).mean() > 0.99


def test_every_face_index_is_in_range(objs):
    for data in objs.values():
        for face in data["faces"]:
            assert len(face) >= 3
            assert all(1 <= int(c.split("/")[0]) <= len(data["v"]) for c in face)


def test_textures_exist_and_are_images(mtl):
    maps = [m["map_Kd"][0] for m in mtl.values() if "map_Kd" in m]
    assert maps, "no image texture"
    for name in maps:
        with Image.open(RES / name) as im:
            assert im.mode == "RGB" and im.size[0] >= 64 and im.size[1] >= 64


def test_every_used_material_is_defined(objs, mtl):
    used = {name for data in objs.values() for name in data["usemtl"]}
    assert used <= set(mtl)


def test_an_emitter_lights_the_room_from_under_the_ceiling(objs, mtl):
    emitters = {name for name, m in mtl.items() if "Kl" in m and max(map(float, m["Kl"])) > 0}
    assert emitters & set(objs["cornell.obj"]["usemtl"])
    ceiling = objs["cornell.obj"]["v"][:, 2].max()
    assert ceiling == pytest.approx(32.928)


def test_spheres_follow_the_seeds_arrangement_glossy_and_glass(objs, mtl):
    spheres = objs["spheres.obj"]["spheres"]
    assert len(spheres) == 3
    for (centre, radius), got in zip(SEED_BALLS, spheres):
        assert got == pytest.approx([*centre, radius], abs=1e-4)
    names = objs["spheres.obj"]["usemtl"]
    assert "Refractable" in mtl[names[1]] and float(mtl[names[1]]["Kn"][0]) == 1.5 and names[1] == names[2]
    assert "Refractable" not in mtl[names[0]] and float(mtl[names[0]]["Roughness"][0]) < 0.5


def test_the_model_stands_clear_of_the_spheres_inside_the_room(objs):
    v = objs["sculpture.obj"]["v"]
    for centre, radius in SEED_BALLS:
        assert np.linalg.norm(v - np.array(centre), axis=1).min() > radius
    room = objs["cornell.obj"]["v"]
    assert (v.min(axis=0) > room.min(axis=0)).all() and (v.max(axis=0) < room.max(axis=0)).all()
    assert v[:, 2].min() >= 0.0 and v[:, 2].max() - v[:, 2].min() > 12.0


def test_the_front_is_open(objs):
    v = objs["cornell.obj"]["v"]
    front = v[:, 1].min()
    for face in objs["cornell.obj"]["faces"]:
        ys = [v[int(c.split("/")[0]) - 1, 1] for c in face]
        assert not all(abs(y - front) < 1e-6 for y in ys), "a face closes the front"


def test_assets_stay_small():
    assert sum(p.stat().st_size for p in RES.iterdir()) < 5_000_000


def test_the_generator_reproduces_the_committed_files(tmp_path):
    subprocess.run([sys.executable, str(REPO / "scripts" / "make_demo.py"), "--out", str(tmp_path)],
                   check=True, capture_output=True, timeout=120)
    made = sorted(p.name for p in tmp_path.iterdir())
    assert made == sorted(p.name for p in RES.iterdir())
    for name in made:
        assert (tmp_path / name).read_bytes() == (RES / name).read_bytes(), name


def test_demo_files_are_located():
    objs, mtls = demo_files()
    assert [Path(p).name for p in objs] == list(DEMO_OBJS) and [Path(p).name for p in mtls] == list(DEMO_MTLS)
    assert all(Path(p).parent == demo_dir() and Path(p).is_file() for p in objs + mtls)
