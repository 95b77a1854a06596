"""What the CLI's view checks cost (issue 10): probe, camera-inside test, recentring, view_checks.

For a closed, welded blob of about 10k, 100k and 1M triangles (tests/support/models.py), times each check
the CLI runs before a render that has no ``-cam`` (the probe's kernel is compiled once beforehand)
and, for scale, the scene upload (``DeviceScene``: BVH build) that every render pays anyway. The
camera-inside test is timed with the camera inside the blob (its worst case: the winding-number
query runs, on a mesh built for it).

    python benchmarks/bench_view_checks.py [--sizes 10000 100000 1000000] [--repeat 3]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

from bench_parse import best_time as best  # noqa: E402  (this folder is on sys.path when run as a script)

from tests.support.models import _sphere_grid  # noqa: E402
from warp_spt.cli import view_checks  # noqa: E402
from warp_spt.upload.device_scene import DeviceScene  # noqa: E402
from warp_spt.io.mtl import builtin_clay  # noqa: E402
from warp_spt.scene.camera import Camera  # noqa: E402
from warp_spt.scene.model import MaterialTable, MeshData, Scene  # noqa: E402
from warp_spt.scene.recentre import recentre  # noqa: E402


def blob_scene(triangles: int) -> Scene:
    n_v = max(4, int(round((triangles / 4) ** 0.5)))
    pts, faces = _sphere_grid(2 * n_v, n_v + 1)
    mesh = MeshData("blob", (pts * 10.0).astype(np.float32), faces.astype(np.int32),
                    np.zeros((len(faces), 3, 2), np.float32), None, np.zeros(len(faces), np.int32))
    m = builtin_clay()
    table = MaterialTable([m.name], np.float32([m.diffuse]), np.float32([m.reflect]), np.float32([m.refract]),
                          np.float32([m.emission]), np.full((1, 4), -1, np.int32), np.float32([m.roughness]),
                          np.float32([m.fuzz]), np.float32([m.ior]), np.array([False]))
    return Scene([mesh], np.zeros((0, 4), np.float32), np.zeros(0, np.int32), table, [])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    view_checks.probe(blob_scene(1000), Camera())          # compile the probe kernel once
    print(f"{'triangles':>10} {'upload s':>9} {'probe s':>8} {'inside s':>9} {'recentre s':>10} "
          f"{'frame s':>8} {'checks / upload':>16}")
    for size in args.sizes:
        scene = blob_scene(size)
        outside = Camera.frame(scene)
        t_up = best(lambda: DeviceScene(scene), args.repeat)
        t_probe = best(lambda: view_checks.probe(scene, outside), args.repeat)
        t_in = best(lambda: view_checks.enclosing_object(scene, (0.0, 0.0, 0.0)), args.repeat)
        t_rc = best(lambda: recentre(scene, outside), args.repeat)
        t_fr = best(lambda: Camera.frame(scene), args.repeat)
        checks = t_probe + t_in + t_rc + t_fr
        print(f"{scene.num_triangles:>10,} {t_up:>9.3f} {t_probe:>8.3f} {t_in:>9.3f} {t_rc:>10.4f} "
              f"{t_fr:>8.4f} {checks / t_up:>16.2f}")


if __name__ == "__main__":
    main()
