"""Host cost per instance of a glTF whose nodes all place one mesh (issue 42: 200,000 nodes took
over 400 s before the first sample of a 24x24 render, about 0.5 ms of host work each).

The budget: at most 100 us of host work per instance from the file to the first sample on a
2-core machine, of which everything after reading the file (the command line's view checks:
probe, up-axis and base cues, the insideness check; the upload and the top-level BVH) at most
50 us (45 measured under load): those are array operations and one probe launch per mesh, not a
Python loop or a kernel launch per placement. The glTF reader's node walk (JSON checked node by node, the world matrices
composed level by level in whole arrays) is the rest: about 34 us per node at 200,000.

Run: python benchmarks/bench_instances.py [N ...]    (default 2000 20000 200000)
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

from tests.support.format_files import gltf_instanced_grid  # noqa: E402


def measure(n: int, folder: Path) -> dict[str, float]:
    from warp_spt.io.loader import load_scene
    from warp_spt.rendering.first_view import first_view
    from warp_spt.rendering.settings import RenderSettings
    from warp_spt.rendering.tiles import render_scene
    from warp_spt.upload.device_scene import DeviceScene

    path = folder / f"grid_{n}.gltf"
    path.write_bytes(gltf_instanced_grid(n).gltf()[0])
    t0 = time.perf_counter()
    scene = load_scene([str(path)])
    t1 = time.perf_counter()
    fv = first_view(scene, width=24, height=24)
    t2 = time.perf_counter()
    dev = DeviceScene(fv.scene)
    t3 = time.perf_counter()
    render_scene(dev, fv.camera, RenderSettings(width=24, height=24, spp=1, sky=fv.sky))
    t4 = time.perf_counter()
    return {"read": t1 - t0, "view": t2 - t1, "upload": t3 - t2, "render": t4 - t3}


def main(sizes: list[int]) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        measure(8, Path(tmp))                          # kernels compiled and loaded outside the figures
        print(f"{'instances':>10} {'read':>9} {'view':>9} {'upload':>9} {'render':>9}   us per instance")
        for n in sizes:
            m = measure(n, Path(tmp))
            per = {k: 1e6 * v / n for k, v in m.items()}
            print(f"{n:>10,} " + " ".join(f"{v:8.2f}s" for v in m.values())
                  + "   " + ", ".join(f"{k} {v:.1f}" for k, v in per.items())
                  + f"; after reading {per['view'] + per['upload'] + per['render']:.1f}")


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [2000, 20000, 200000])
