"""Many instances of one mesh (issue 42, item 4): the host work after reading a file, the command
line's view checks and the upload, is array operations over the placements and one probe launch
per mesh, so it does not grow by Python calls per instance (200,000 nodes placing one cube took
over 400 s before the first sample, about 0.5 ms each; ``benchmarks/bench_instances.py`` measures
the budget). Counted in Python function calls, not seconds: the same on any machine."""

from __future__ import annotations

import sys
from collections import Counter

import numpy as np

from warp_spt.io.loader import load_scene
from warp_spt.rendering.first_view import enclosing_object, first_view, probe
from warp_spt.scene.camera import Camera
from warp_spt.upload.device_scene import DeviceScene

from tests.support.format_files import gltf_instanced_grid


def _calls_after_reading(scene) -> int:
    calls = Counter()

    def count(frame, event, arg):
        if event == "call":
            calls[frame.f_code] += 1

    sys.setprofile(count)
    try:
        DeviceScene(first_view(scene, width=24, height=24).scene)
    finally:
        sys.setprofile(None)
    return sum(calls.values())


def test_the_view_checks_and_upload_of_many_instances_make_no_python_calls_per_instance(tmp_path):
    """...while the probe and the insideness check still see every placement."""
    scenes = {}
    for n in (20, 2000):
        path = tmp_path / f"grid_{n}.gltf"
        path.write_bytes(gltf_instanced_grid(n).gltf()[0])
        scenes[n] = load_scene([str(path)])
        DeviceScene(first_view(scenes[n], width=24, height=24).scene)     # kernels loaded before counting
    few, many = _calls_after_reading(scenes[20]), _calls_after_reading(scenes[2000])
    # before: about 255 calls per instance (a probe launch, a matrix inverse and world copies each)
    assert many - few < 0.5 * (2000 - 20), (few, many)
    # and the probe and the insideness check still see every placement
    path = tmp_path / "grid.gltf"
    path.write_bytes(gltf_instanced_grid(9).gltf()[0])        # cubes of side 0.5 at x, z in {0, 2, 4}
    scene = load_scene([str(path)])
    for x, z in ((0.0, 0.0), (4.0, 4.0), (2.0, 4.0)):
        down = Camera(position=(x, 3.0, z), direction=(0.0, -1.0, 0.0), up=(0.0, 0.0, 1.0), fov=1.0)
        t = probe(scene, down, 4, 4).t
        assert np.allclose(t, 2.75, atol=1e-4), (x, z, t)   # the cube's top face at y = 0.25
        assert enclosing_object(scene, (x + 0.1, 0.1, z - 0.1)) is not None
    between = Camera(position=(1.0, 3.0, 1.0), direction=(0.0, -1.0, 0.0), up=(0.0, 0.0, 1.0), fov=1.0)
    assert not np.isfinite(probe(scene, between, 4, 4).t).any()
    assert enclosing_object(scene, (1.0, 0.0, 1.0)) is None
