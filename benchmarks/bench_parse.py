"""Scene-file parsing speed: MB/s and triangles/s of load_obj and load_scene.

Generates height-field grid meshes of about 10k, 100k and 1M triangles in a temporary folder,
written by ``write_obj`` the way exporters write them (``v``, ``vt``, ``vn``, ``f v/vt/vn``),
and times the reader on each (best of ``--repeat`` runs). The target: the 1M-triangle file loads
in under 3 s on a 2-core machine.

    python benchmarks/bench_parse.py [--sizes 10000 100000 1000000] [--repeat 3] [--form v/vt/vn]
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # run from a checkout without installing

from warp_spt.io.loader import load_scene
from warp_spt.io.obj import load_obj, write_obj


def grid_mesh(triangles: int, form: str) -> dict:
    """Arrays of an n x n quad grid (2 triangles per quad) with about ``triangles`` triangles."""
    n = max(1, int(round((triangles / 2) ** 0.5)))
    i, j = np.meshgrid(np.arange(n + 1), np.arange(n + 1), indexing="ij")
    x, y = i.ravel() / n, j.ravel() / n
    z = 0.1 * np.sin(7 * x) * np.cos(5 * y)
    pos = np.stack([x, y, z], axis=1).astype(np.float32)
    k = (i[:-1, :-1] * (n + 1) + j[:-1, :-1]).ravel()
    quads = np.stack([k, k + n + 1, k + n + 2, k + 1], axis=1)
    faces = np.concatenate([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]]]).astype(np.int64)
    arrays = {"positions": pos, "faces": faces}
    if "vt" in form:
        arrays.update(texcoords=pos[:, :2], face_texcoords=faces)
    if "vn" in form:
        nrm = np.stack([np.zeros_like(x), np.zeros_like(x), np.ones_like(x)], axis=1).astype(np.float32)
        arrays.update(normals=nrm, face_normals=faces)
    return arrays


def best_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[10_000, 100_000, 1_000_000])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--form", choices=["v", "v/vt", "v//vn", "v/vt/vn"], default="v/vt/vn")
    args = ap.parse_args()
    print(f"face form {args.form}, best of {args.repeat}, {os.cpu_count()} CPUs")
    print(f"{'triangles':>10} {'MB':>7} | {'load_obj s':>10} {'MB/s':>7} {'Mtri/s':>7} | {'load_scene s':>12} {'MB/s':>7}")
    with tempfile.TemporaryDirectory() as tmp:
        for size in args.sizes:
            path = Path(tmp) / f"grid_{size}.obj"
            write_obj(path, **grid_mesh(size, args.form))
            mb = path.stat().st_size / 1e6
            tris = len(load_obj(path).faces)
            t_obj = best_time(lambda: load_obj(path), args.repeat)
            t_scene = best_time(lambda: load_scene([path], warn=lambda m: None), args.repeat)
            print(f"{tris:>10,} {mb:>7.1f} | {t_obj:>10.3f} {mb / t_obj:>7.1f} {tris / t_obj / 1e6:>7.2f} | "
                  f"{t_scene:>12.3f} {mb / t_scene:>7.1f}")
            path.unlink()


if __name__ == "__main__":
    main()
