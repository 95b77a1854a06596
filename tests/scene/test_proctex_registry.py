"""The procedural textures' two halves: the Warp-free declarations (scene/proctex_registry.py) that the
MTL reader parses against, and the Warp functions registered beside them (device/proctex.py)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import warp as wp

import warp_spt
from warp_spt.device import proctex
from warp_spt.io.mtl import parse_mtl_bytes
from warp_spt.scene import proctex_registry
from warp_spt.scene.errors import SceneError

REPO = Path(__file__).resolve().parents[2]

# Runs in a fresh interpreter: nothing in it may import Warp. It prints what it parsed, the error an
# unregistered (user) texture gets, and whether Warp was imported.
WARP_FREE = r'''
import json, sys
from warp_spt.io.mtl import load_mtl
from warp_spt.scene.errors import SceneError

mats = load_mtl(sys.argv[1])
ref = mats["m"].base_color_map
try:
    load_mtl(sys.argv[2])
    err = None
except SceneError as e:
    err = {"path": e.path, "line": e.line, "message": e.message}
print(json.dumps({"name": ref.name, "params": ref.params, "line": ref.line, "error": err,
                  "warp": "warp" in sys.modules}))
'''


def test_the_mtl_reader_parses_procedural_maps_without_warp(tmp_path):
    good, bad = tmp_path / "good.mtl", tmp_path / "bad.mtl"
    good.write_text("newmtl m\nKd 0.5 0.5 0.5\nmap_Kd proc:noise scale=2\n")
    bad.write_text("newmtl u\nKd 0.5 0.5 0.5\n\nmap_Kd proc:my_stripes width=0.2\n")
    env = dict(os.environ, PYTHONPATH=str(REPO) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    run = subprocess.run([sys.executable, "-c", WARP_FREE, str(good), str(bad)], capture_output=True, text=True,
                         cwd=REPO, env=env, timeout=120)
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout.strip().splitlines()[-1])
    assert out["warp"] is False
    # noise's layout: scale, color1 (black), color2 (white), padded to 16 floats
    assert out["name"] == "noise" and out["line"] == 3
    assert out["params"] == [2.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0] + [0.0] * 9
    # a user texture is registered by importing its module (which needs Warp); unregistered, the
    # MTL line is refused with file and line, and the message lists the built-ins it could use
    err = out["error"]
    assert err["path"] == str(bad) and err["line"] == 4
    assert "unknown procedural texture 'my_stripes'" in err["message"]
    assert all(name in err["message"] for name in ("checker", "grid", "marble", "noise", "wood"))


@warp_spt.texture("t_visible", level=proctex.ProcParam(0.5, 0.0, 2.0), tint=(0.1, 0.2, 0.3))
def t_visible(uv: wp.vec2, p: wp.vec3, n: wp.vec3, prm: warp_spt.ProcParams) -> wp.vec3:
    return wp.vec3(prm[0] * prm[1], prm[2], prm[3])


def t_two_args(uv: wp.vec2, p: wp.vec3) -> wp.vec3:
    return wp.vec3(0.0)


def test_a_texture_registered_through_the_decorator_is_visible_to_the_parser():
    assert "t_visible" in proctex_registry.registered()
    mat = parse_mtl_bytes(b"newmtl m\nmap_Kd proc:t_visible level=1.5 tint=0.5,0.25,1\n", "v.mtl")["m"]
    assert mat.base_color_map.name == "t_visible"
    assert mat.base_color_map.params[:4] == (1.5, 0.5, 0.25, 1.0)
    with pytest.raises(SceneError, match=r"level of proc:t_visible must lie in \[0, 2\]") as err:
        parse_mtl_bytes(b"newmtl m\nmap_Kd proc:t_visible level=3\n", "v.mtl")
    assert err.value.line == 2
    # the Warp half sits beside the declaration under the same name, and reads as it
    entry = proctex._FUNCTIONS["t_visible"]
    assert entry.texture is proctex_registry.get_texture("t_visible") is proctex.get_texture("t_visible")
    assert entry.layout() == {"level": (0, 1), "tint": (1, 3)} and entry.user_func is t_visible


def test_a_refused_registration_registers_neither_half():
    with pytest.raises(ValueError, match="expected"):
        proctex.register_texture("t_refused", t_two_args, level=1.0)
    with pytest.raises(ValueError, match="RGB triple"):
        proctex.register_texture("t_refused", t_two_args, tint=(1.0, 2.0))
    assert "t_refused" not in proctex_registry.registered() and "t_refused" not in proctex._FUNCTIONS


def test_each_builtin_has_one_declaration_and_its_warp_function():
    for name, declaration in proctex_registry.BUILTINS.items():
        assert proctex._FUNCTIONS[name].texture is declaration
    assert set(proctex_registry.BUILTINS) == {"checker", "noise", "marble", "wood", "grid"}
