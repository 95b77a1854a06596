"""The kernel index (runtime/kernel_index.py): a compiled kernel found by a key of our own.

The key must change whenever the kernel's code could (else a stale object would load): a changed
``wp.func`` source, another specialisation, a code-relevant ``wp.config`` value. A kernel loaded by
its own key must render the same bits as one built and looked up by Warp's hash, and a record whose
files are gone must fall back to Warp's look-up.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import pytest
import warp as wp

from warp_spt.device.structs import Features
from warp_spt.runtime import kernel_index

REPO = Path(__file__).resolve().parents[2]


def test_a_changed_wp_func_source_changes_the_key(tmp_path):
    # two copies (the digest is read once per process and folder, as the imported code is fixed)
    same, changed = tmp_path / "same" / "warp_spt", tmp_path / "changed" / "warp_spt"
    for copy in (same, changed):
        shutil.copytree(kernel_index.PACKAGE, copy, ignore=shutil.ignore_patterns("__pycache__"))
    spec = ("nee", "sobol", Features())
    assert kernel_index.own_key("fast", spec, str(same)) == kernel_index.own_key("fast", spec)
    target = changed / "device" / "sampling.py"
    text = target.read_text()
    at = text.index("@wp.func\n")
    body = text.index("\n", text.index("def ", at)) + 1       # the first line after the def
    target.write_text(text[:body] + "    unused_line = 0.0\n" + text[body:])
    assert kernel_index.own_key("fast", spec, str(changed)) != kernel_index.own_key("fast", spec)


def test_the_key_names_the_specialisation_and_code_relevant_config(monkeypatch):
    base = kernel_index.own_key("fast", ("nee", "sobol", Features()))
    others = [kernel_index.own_key("fast", ("seed", "sobol", Features())),
              kernel_index.own_key("fast", ("nee", "independent", Features())),
              kernel_index.own_key("fast", ("nee", "sobol", replace(Features(), spheres=not Features().spheres))),
              kernel_index.own_key("aov", ("nee", "sobol", Features()))]
    assert len({base, *others}) == 5
    monkeypatch.setattr(wp.config, "mode", "debug" if wp.config.mode != "debug" else "release")
    assert kernel_index.own_key("fast", ("nee", "sobol", Features())) != base
    monkeypatch.undo()
    monkeypatch.setattr(wp.config, "log_level", wp.config.log_level + 1)      # changes no code
    assert kernel_index.own_key("fast", ("nee", "sobol", Features())) == base


_CHILD = """
import hashlib, json, sys
from warp_spt import RenderSettings, load_scene, render_scene
from warp_spt.demo import demo_files
from warp_spt.runtime import kernel_cache, kernel_index
objs, mtls = demo_files()
res = render_scene(load_scene(objs, mtls), settings=RenderSettings(width=24, height=16, spp=2, max_depth=4, threads=1))
print(json.dumps({"image": hashlib.sha256(res.image.tobytes()).hexdigest(),
                  "steps built": len(kernel_cache.entries("step")),
                  "by own key": [k is not None for (kind, _), k in kernel_cache._built.items()
                                 if kind == "fast, by own key"],
                  "keys": [kernel_index.own_key("fast", spec) for kind, spec in kernel_cache._built
                           if kind == "fast, by own key"]}))
"""


def _render(env_extra: dict) -> dict:
    env = dict(os.environ, PYTHONPATH=str(REPO), **env_extra)
    out = subprocess.run([sys.executable, "-c", _CHILD], env=env, capture_output=True, text=True, cwd=REPO,
                         timeout=900)
    assert out.returncode == 0, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


def _records() -> list[Path]:
    from warp_spt.runtime.warp_init import init_warp
    init_warp()
    return sorted(Path(wp.config.kernel_cache_dir, kernel_index.INDEX_FOLDER).glob("*.json"))


def test_a_kernel_loaded_by_its_own_key_renders_the_same_bits():
    warp_own = _render({"WARP_SPT_KERNEL_INDEX": "0"})        # built, found by Warp's hash
    assert warp_own["steps built"] > 0 and warp_own["by own key"] == []
    _render({})                                              # writes the record where missing
    indexed = _render({})
    assert indexed["by own key"] == [True] and indexed["steps built"] == 0   # no Warp function built
    assert indexed["image"] == warp_own["image"]


def test_a_record_whose_object_is_gone_falls_back_to_warps_look_up(tmp_path):
    _render({})
    records = _records()
    assert records
    # the same record under a cache folder where its object file is missing: load declines it
    rec = json.loads(records[0].read_text())
    fake_cache = tmp_path / "cache"
    (fake_cache / kernel_index.INDEX_FOLDER).mkdir(parents=True)
    (fake_cache / kernel_index.INDEX_FOLDER / records[0].name).write_text(json.dumps(rec))
    from warp_spt.integrators.common import make_kernel
    saved = wp.config.kernel_cache_dir
    try:
        wp.config.kernel_cache_dir = str(fake_cache)
        assert kernel_index.load(records[0].stem, make_kernel(None, None, decorate=False)) is None
    finally:
        wp.config.kernel_cache_dir = saved


def test_no_own_key_for_code_from_outside_the_package(monkeypatch):
    from warp_spt.integrators import INTEGRATORS, _own_code, get_integrator
    from warp_spt.samplers import SAMPLERS

    assert _own_code("nee", "sobol", Features())
    nee = get_integrator("nee")
    outside = replace(nee, name="outside", make_step=lambda *a, **k: nee.make_step(*a, **k))
    monkeypatch.setitem(INTEGRATORS, "outside", outside)
    assert not _own_code("outside", "sobol", Features())          # a step built by a user's module
    assert not _own_code("guided", "sobol", Features())           # a kernel of its own
    assert not _own_code("nee", "sobol", replace(Features(), procedural=(("user_tex", "0" * 16),)))
    monkeypatch.setitem(SAMPLERS, "outside", lambda: SAMPLERS["sobol"]())
    assert not _own_code("nee", "outside", Features())


def test_no_key_without_sources_to_read(tmp_path):
    assert kernel_index.own_key("fast", ("nee", "sobol", Features()), str(tmp_path / "missing")) is None


def test_a_record_that_does_not_load_is_replaced():
    first = _render({})
    assert len(first["keys"]) == 1
    path = Path(_records()[0]).parent / (first["keys"][0] + ".json")
    path.write_text("{")                 # a record that cannot be read: Warp's look-up, then a new record
    again = _render({})
    assert again["by own key"] == [False] and again["steps built"] > 0
    assert json.loads(path.read_text())["kernel"]
    last = _render({})
    assert last["by own key"] == [True] and last["steps built"] == 0 and last["image"] == first["image"]


def test_a_kernel_built_for_cuda_is_neither_recorded_nor_looked_up(tmp_path):
    """The CUDA compile test builds kernels for "cuda" on machines without a GPU, where Warp raises
    for the name: the index stays out of it (it raised there, and every CUDA compile errored)."""
    import warp as wp

    from warp_spt.runtime.warp_init import init_warp

    init_warp()
    if wp.is_cuda_available():
        pytest.skip("this machine has a CUDA device: the name resolves")
    key = "0" * 64
    assert kernel_index.remember(key, object(), "cuda") is None
    assert kernel_index.load(key, lambda: None, "cuda") is None
