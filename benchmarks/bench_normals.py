"""What smooth normals by angle cost at load (issue 31): scene/normals.smooth_normals on UV spheres.

    python benchmarks/bench_normals.py [--triangles 20000 200000 1000000] [--repeat 3]

Prints, per size, the best of ``--repeat`` runs of ``smooth_normals`` (30 degrees) and, for scale,
of reading the same sphere's OBJ text with ``warp_spt.load_obj`` (the parse the smoothing follows).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from warp_spt.io.obj import load_obj  # noqa: E402
from warp_spt.scene.normals import smooth_normals  # noqa: E402


def sphere(triangles: int) -> tuple[np.ndarray, np.ndarray]:
    """A welded UV sphere of about ``triangles`` triangles."""
    n_v = max(4, int(round(np.sqrt(triangles / 4))))
    n_u = 2 * n_v
    th = np.linspace(0, np.pi, n_v + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, n_u, endpoint=False)
    t, p = np.meshgrid(th, ph, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    pts = np.concatenate([[[0, 0, 1]], ring, [[0, 0, -1]]])
    j = np.arange(n_u)
    at = lambda i, jj: 1 + i * n_u + (jj % n_u)
    faces = [np.stack([np.zeros(n_u, int), at(0, j), at(0, j + 1)], 1),
             np.stack([np.full(n_u, len(pts) - 1), at(n_v - 2, j + 1), at(n_v - 2, j)], 1)]
    for i in range(n_v - 2):
        a, b, c, d = at(i, j), at(i, j + 1), at(i + 1, j), at(i + 1, j + 1)
        faces += [np.stack([a, c, b], 1), np.stack([b, c, d], 1)]
    return pts, np.concatenate(faces)


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--triangles", type=int, nargs="+", default=[20_000, 200_000, 1_000_000])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    print("| triangles | smooth_normals (s) | load_obj of the same OBJ (s) |")
    print("|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for n in args.triangles:
            p, f = sphere(n)
            obj = Path(tmp) / "s.obj"
            obj.write_text("".join(f"v {x:.7f} {y:.7f} {z:.7f}\n" for x, y, z in p)
                           + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f))
            t_smooth = best(lambda: smooth_normals(p, f, 30.0), args.repeat)
            t_load = best(lambda: load_obj(str(obj)), args.repeat)
            print(f"| {len(f):,} | {t_smooth:.2f} | {t_load:.2f} |")


if __name__ == "__main__":
    main()
