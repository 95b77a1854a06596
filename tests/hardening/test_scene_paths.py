"""The path rule (warp_spt.io.paths, docs/limits.md): a file a scene file names lies in that file's
folder or below, links resolved first, for every reader: a glTF's buffers and images, an MTL's maps
and density grids, an OBJ's mtllib. Each way out (``..``, an absolute path, ``%2e%2e`` in a URI, a
link inside the folder that points outside) is a SceneError naming the file and the line or JSON
pointer; ``WARP_SPT_TRUST_PATHS=1`` (``--trust-paths``) reads the same scene. No kernel is compiled
here: every case stops at the loader."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest

from warp_spt.io.loader import load_scene
from warp_spt.io.paths import TRUST_ENV, confine, trusting
from warp_spt.scene.errors import SceneError

from tests.support.format_files import gltf_box, gltf_textured_box, png_2x2

OUTSIDE = ("../outside/{name}", "{abs}", "sub/../../outside/{name}")


@pytest.fixture
def tree(tmp_path, monkeypatch):
    """``scene/`` (where the scene files go, with ``sub/``) beside ``outside/`` (what must stay
    unread), and the working directory somewhere else."""
    scene, outside, cwd = tmp_path / "scene", tmp_path / "outside", tmp_path / "cwd"
    for d in (scene / "sub", outside, cwd):
        d.mkdir(parents=True)
    monkeypatch.chdir(cwd)
    monkeypatch.delenv(TRUST_ENV, raising=False)
    return scene, outside


def _names(outside: Path, name: str) -> list[str]:
    return [o.format(name=name, abs=outside / name) for o in OUTSIDE]


def _link_out(scene: Path, outside: Path, name: str) -> str:
    """A symbolic link inside the scene's folder to a file outside it; its name."""
    (scene / f"link_{name}").symlink_to(outside / name)
    return f"link_{name}"


def _refused(match: str, fn, *args):
    with pytest.raises(SceneError, match=match) as info:
        fn(*args)
    assert "--trust-paths" in str(info.value) and TRUST_ENV in str(info.value)
    return info.value


def test_gltf_buffers_and_images_stay_in_the_files_folder(tree, monkeypatch):
    scene, outside = tree
    doc, data = gltf_box().gltf("box.bin")
    (outside / "box.bin").write_bytes(data)
    (outside / "tex.png").write_bytes(png_2x2())
    js = json.loads(doc)
    names = _names(outside, "box.bin") + ["%2e%2e/outside/box.bin", _link_out(scene, outside, "box.bin")]
    for uri in names:
        js["buffers"][0]["uri"] = uri
        (scene / "m.gltf").write_text(json.dumps(js))
        err = _refused(r"/buffers/0/uri: ", load_scene, [str(scene / "m.gltf")])
        assert str(scene / "m.gltf") in str(err)
    # trusted, the same file reads its buffer from outside
    monkeypatch.setenv(TRUST_ENV, "1")
    assert len(load_scene([str(scene / "m.gltf")]).meshes[0].positions) == 8
    monkeypatch.delenv(TRUST_ENV)

    tex = json.loads(gltf_textured_box().gltf()[0])
    for uri in _names(outside, "tex.png") + ["%2E%2E/outside/tex.png", _link_out(scene, outside, "tex.png")]:
        tex["images"][0]["uri"] = uri
        (scene / "t.gltf").write_text(json.dumps(tex))
        _refused(r"/images/0/uri: ", load_scene, [str(scene / "t.gltf")])
    # inside the folder (a subfolder, a '..' that stays inside, an absolute name of a file in it) is read
    (scene / "sub" / "tex.png").write_bytes(png_2x2())
    for uri in ("sub/../sub/tex.png", str(scene / "sub" / "tex.png")):
        tex["images"][0]["uri"] = uri
        (scene / "t.gltf").write_text(json.dumps(tex))
        assert load_scene([str(scene / "t.gltf")]).textures


def _mtl_scene(scene: Path, mtl: str) -> list[str]:
    (scene / "q.obj").write_text("mtllib q.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                 "usemtl m\nf 1/1 2/2 3/3\n")
    (scene / "q.mtl").write_text(mtl)
    return [str(scene / "q.obj")]


def test_mtl_maps_and_grids_and_obj_mtllib_stay_in_their_folder(tree, monkeypatch):
    scene, outside = tree
    (outside / "tex.png").write_bytes(png_2x2())
    (outside / "grid.nvdb").write_bytes(b"not read")
    for name in _names(outside, "tex.png") + [_link_out(scene, outside, "tex.png")]:
        objs = _mtl_scene(scene, f"newmtl m\nKd 1 1 1\nmap_Kd {name}\n")
        err = _refused(r"q\.mtl:3: texture ", load_scene, objs)
        assert "outside" in str(err) or "absolute" in str(err)
    for name in _names(outside, "grid.nvdb") + [_link_out(scene, outside, "grid.nvdb")]:
        objs = _mtl_scene(scene, f"newmtl m\nKd 1 1 1\nmedium_density {name}\n")
        _refused(r"q\.mtl:3: density grid ", load_scene, objs)
    (outside / "lib.mtl").write_text("newmtl m\nKd 1 0 0\n")
    for name in _names(outside, "lib.mtl") + [_link_out(scene, outside, "lib.mtl")]:
        (scene / "r.obj").write_text(f"mtllib {name}\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl m\nf 1 2 3\n")
        _refused(r"r\.obj:1: mtllib ", load_scene, [str(scene / "r.obj")])
    # trusted: the map outside is read
    objs = _mtl_scene(scene, f"newmtl m\nKd 1 1 1\nmap_Kd {outside / 'tex.png'}\n")
    with trusting(True):
        assert load_scene(objs).textures
    assert TRUST_ENV not in os.environ          # put back after the block


def test_the_seeds_maps_relative_to_the_working_directory_still_load(tree, monkeypatch):
    """SEMANTICS.md: the seed's MTL names maps relative to the working directory (renderRes/x.png)."""
    scene, outside = tree
    work = scene.parent / "cwd"
    (work / "renderRes").mkdir()
    (work / "renderRes" / "x.png").write_bytes(png_2x2())
    objs = _mtl_scene(scene, "newmtl m\nKd 1 1 1\nmap_Kd renderRes/x.png\n")
    assert load_scene(objs).textures
    objs = _mtl_scene(scene, "newmtl m\nKd 1 1 1\nmap_Kd renderRes/../../outside/tex.png\n")
    (outside / "tex.png").write_bytes(png_2x2())
    _refused(r"q\.mtl:3: texture ", load_scene, objs)


def test_confine_keeps_the_places_inside_their_roots(tmp_path, monkeypatch):
    monkeypatch.delenv(TRUST_ENV, raising=False)
    root = tmp_path / "r"
    root.mkdir()
    assert confine("a/b.png", root, "texture") == ([root / "a/b.png"], None)
    assert confine("a\\b.png", root, "texture") == ([root / "a/b.png"], None)       # Windows separators
    assert confine(str(root / "a.png"), root, "texture") == ([root / "a.png"], None)     # absolute, inside
    for bad in ("../x", "/etc/passwd", "C:/x", "C:\\x", "a/../../x", str(tmp_path / "a.png")):
        places, why = confine(bad, root, "texture")
        assert places == [] and why and repr(bad) in why, bad
    monkeypatch.setenv(TRUST_ENV, "0")
    assert confine("../x", root, "texture")[0] == []
    monkeypatch.setenv(TRUST_ENV, "1")
    assert confine("../x", root, "texture") == ([root / "../x"], None)
    assert confine("/etc/passwd", root, "texture") == ([Path("/etc/passwd")], None)


def test_the_cli_refuses_in_one_line_and_reads_with_trust_paths(tree, capsys):
    from warp_spt.cli.main import main

    scene, outside = tree
    (outside / "tex.png").write_bytes(png_2x2())
    objs = _mtl_scene(scene, f"newmtl m\nKd 1 1 1\nmap_Kd ../outside/tex.png\n")
    out = scene / "o.npy"
    args = ["-obj", objs[0], "-res", "4", "4", "-sr", "1", "--quiet", "-out", str(out), "--frame"]
    assert main(args) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "q.mtl:3" in err[0] and "--trust-paths" in err[0], err
    assert not out.exists()
    assert main(args + ["--trust-paths"]) == 0 and np.load(out).shape[:2] == (4, 4)
    assert TRUST_ENV not in os.environ
