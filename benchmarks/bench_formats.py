"""Load times of the PLY and glTF readers on a large generated model, against trimesh (if installed).

A height-field grid of about ``--triangles`` triangles is written as a binary PLY (float32 positions,
triangle faces) and as a .glb (float32 positions, uint32 indices) into a temporary folder; each file
is read ``--repeat`` times by our reader and by ``trimesh.load(..., process=False)`` and the best
wall time is printed. ``--first-pixel`` also times ``warp-spt -obj MODEL -res 8 8 -sr 1`` (a child
process: parsing, validation, BVH builds, kernel from the cache, one tiny image).

    python benchmarks/bench_formats.py                      # 1M triangles
    python benchmarks/bench_formats.py --triangles 100000 --first-pixel
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.format_files import GltfBuilder, binary_ply_mesh  # noqa: E402


def grid(triangles: int) -> tuple[np.ndarray, np.ndarray]:
    n = max(2, int(np.sqrt(triangles / 2)) + 1)
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    z = 0.05 * np.sin(12 * x) * np.cos(9 * y)
    pos = np.stack([x, z, y], -1).reshape(-1, 3).astype(np.float32)
    k = np.arange(n * n).reshape(n, n)[:-1, :-1].reshape(-1)
    faces = np.concatenate([np.stack([k, k + 1, k + n + 1], 1), np.stack([k, k + n + 1, k + n], 1)]).astype(np.int32)
    return pos, faces


def glb_mesh(pos: np.ndarray, faces: np.ndarray) -> bytes:
    g = GltfBuilder()
    p = g.accessor(pos, "VEC3", 5126)
    i = g.accessor(faces.reshape(-1).astype(np.uint32), "SCALAR", 5125)
    g.doc["meshes"].append({"primitives": [{"attributes": {"POSITION": p}, "indices": i}]})
    g.node(mesh=0)
    return g.glb()


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--triangles", type=int, default=1_000_000)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--first-pixel", action="store_true")
    args = ap.parse_args()
    from warp_spt.io.gltf import load_gltf
    from warp_spt.io.ply import load_ply

    try:
        import trimesh
    except ImportError:
        trimesh = None
    pos, faces = grid(args.triangles)
    with tempfile.TemporaryDirectory() as tmp:
        files = {"ply": Path(tmp) / "grid.ply", "glb": Path(tmp) / "grid.glb"}
        files["ply"].write_bytes(binary_ply_mesh(pos, faces))
        files["glb"].write_bytes(glb_mesh(pos, faces))
        print(f"{len(faces):,} triangles, {len(pos):,} vertices; best of {args.repeat} wall seconds")
        print(f"{'file':<6}{'MiB':>8}{'warp_spt':>12}{'trimesh':>12}")
        for kind, path in files.items():
            ours = best(lambda: (load_ply if kind == "ply" else load_gltf)(path), args.repeat)
            d = (load_ply if kind == "ply" else load_gltf)(path)
            assert len(d.faces) == len(faces)
            theirs = best(lambda: trimesh.load(path, process=False), args.repeat) if trimesh else float("nan")
            print(f"{kind:<6}{path.stat().st_size / 2**20:>8.1f}{ours:>12.3f}{theirs:>12.3f}")
        if args.first_pixel:
            env = dict(os.environ, PYTHONPATH=str(ROOT))
            for kind, path in files.items():
                t = time.perf_counter()
                subprocess.run([sys.executable, "-m", "warp_spt", "-obj", str(path), "-res", "8", "8", "-sr", "1",
                                "--quiet", "-out", str(Path(tmp) / "o.png")], check=True, env=env)
                print(f"first pixel ({kind}, whole process, kernel cached): {time.perf_counter() - t:.2f} s")


if __name__ == "__main__":
    main()
