"""Issue 24: host build time and tree statistics of warp_spt.accel.wide_bvh.build_wide.

Meshes: random triangle soups (small triangles, uniform centres in a cube) of 10k..1M triangles,
the built-in demo's triangles (51,242), and the demo subdivided 1:4 once and twice (205k, 820k:
real geometry at the size of big user models). Prints build seconds (CPU time of this process,
median of --repeat), wide nodes, depth, stack_bound (the traversal's stack must hold this many
entries; today's kernels have 64), mean filled slots per node, and an SAH cost estimate of the
tree (interior box areas + leaf areas x triangles, relative to the root box: lower is better; the
traversal benchmark is benchmarks/bench_wide_bvh.py, rows "build_wide").

    python benchmarks/bench_wide_build.py
    python benchmarks/bench_wide_build.py --sizes 10000,100000 --repeat 5 --no-demo
"""

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from warp_spt.accel.wide_bvh import WideBvh, build_wide


def soup(k: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    c = rng.uniform(0.0, 100.0, size=(k, 1, 3))
    size = 100.0 / k ** (1 / 3)                      # triangles about as big as their spacing
    p = (c + rng.normal(scale=0.5 * size, size=(k, 3, 3))).astype(np.float32)
    return p.reshape(-1, 3), np.arange(3 * k).reshape(k, 3)


def demo() -> tuple[np.ndarray, np.ndarray]:
    from warp_spt.demo import demo_files
    from warp_spt.io.loader import load_scene
    objs, mtls = demo_files()
    scene = load_scene(objs, mtls, warn=lambda m: None)
    pts, idx, base = [], [], 0
    for m in scene.meshes:
        pts.append(np.asarray(m.positions, dtype=np.float32))
        idx.append(np.asarray(m.indices, dtype=np.int64).reshape(-1, 3) + base)
        base += len(m.positions)
    return np.concatenate(pts), np.concatenate(idx)


def subdivide(points: np.ndarray, tris: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Every triangle into 4 at its edge midpoints (vertices not shared: fine for a BVH)."""
    a, b, c = (points[tris[:, i]].astype(np.float32) for i in range(3))
    ab, bc, ca = (a + b) / 2, (b + c) / 2, (c + a) / 2
    quads = [(a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca)]
    p = np.stack([np.stack(q, axis=1) for q in quads], axis=1).reshape(-1, 3)
    return p, np.arange(len(p)).reshape(-1, 3)


def sah_cost(bvh: WideBvh) -> float:
    lo, hi = bvh.box[:, 0:3].astype(np.float64), bvh.box[:, 3:6].astype(np.float64)
    filled = np.isfinite(lo).all(axis=1)
    d = np.where(filled[:, None, :], hi - lo, 0.0)
    area = d[:, 0] * d[:, 1] + d[:, 1] * d[:, 2] + d[:, 2] * d[:, 0]
    rd = np.where(filled[0], hi[0], -np.inf).max(axis=1) - np.where(filled[0], lo[0], np.inf).min(axis=1)
    root = rd[0] * rd[1] + rd[1] * rd[2] + rd[2] * rd[0]
    inner, leaf = filled & (bvh.child >= 0), filled & (bvh.child < 0)
    count = (-bvh.child.astype(np.int64) - 1) & 7
    return float((root + area[inner].sum() + (area[leaf] * count[leaf]).sum()) / root)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="10000,30000,100000,300000,1000000")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-demo", action="store_true")
    ap.add_argument("--builders", default="warp,numpy", help="build_wide's builders to compare (warp, numpy)")
    args = ap.parse_args()
    meshes = [(f"random soup {int(k):,}", *soup(int(k))) for k in args.sizes.split(",")]
    if not args.no_demo:
        p, t = demo()
        meshes.append(("built-in demo", p, t))
        p, t = subdivide(p, t)
        meshes.append(("demo subdivided x4", p, t))
        meshes.append(("demo subdivided x16", *subdivide(p, t)))
    builders = args.builders.split(",")
    if "warp" in builders:           # the build kernel's compile (or cache load) is not a build's time
        build_wide(*soup(100), builder="warp")
    print("| mesh | builder | triangles | build CPU s | us per triangle | wide nodes | depth | stack_bound | "
          "slots filled | SAH cost |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for name, p, t in meshes:
        for builder in builders:
            times = []
            for _ in range(args.repeat):
                t0 = time.process_time()
                bvh = build_wide(p, t, builder=builder)
                times.append(time.process_time() - t0)
            filled = float(np.isfinite(bvh.box[:, 0]).sum(axis=1).mean())
            sec = float(np.median(times))
            print(f"| {name} | {builder} | {len(t):,} | {sec:.3f} | {sec / len(t) * 1e6:.2f} | {bvh.num_nodes:,} | "
                  f"{bvh.depth} | {bvh.stack_bound} | {filled:.2f} | {sah_cost(bvh):.2f} |", flush=True)


if __name__ == "__main__":
    main()
