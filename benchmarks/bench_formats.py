"""Load times of the PLY and glTF readers on a large generated model, against trimesh (if installed).

A height-field grid of about ``--triangles`` triangles is written as a binary PLY (float32 positions,
triangle faces) and as a .glb (float32 positions, uint32 indices) into a temporary folder; each file
is read ``--repeat`` times by our reader and by ``trimesh.load(..., process=False)`` and the best
wall time is printed. ``--first-pixel`` also times ``warp-spt -obj MODEL -res 8 8 -sr 1`` (a child
process: parsing, validation, BVH builds, kernel from the cache, one tiny image).

``--instances N`` measures instancing instead (MeshData.transforms, through upload/instances.py): N
instances of a ``--mesh-triangles`` mesh (a lumpy sphere) on a grid, uploaded once and instanced,
against the same scene flattened into world-space meshes (``--flat-instances`` of them, as far as
memory allows): device bytes of the geometry, upload time, closest-hit rays per second on the same
rays (a pinhole view of the grid, ``--size`` squared; best of 3 launches; the renderer's own
traversal) and the wall time of a path-traced render (``--render-size`` squared, 1 spp, nee, after a
warm-up render). ``--image PNG`` saves the instanced view shaded by |cos| of the world normal.

``--rigid T`` measures rigid animation instead: a .glb of one T-triangle grid whose node is
translated and rotated by a channel, loaded and uploaded per frame as ``--frames`` renders do
(``ObjSequence`` and a ``DeviceScene`` with the mesh cache), best of ``--repeat`` per frame. Run it
with PYTHONPATH at another checkout to time that one's code (the script uses the public API only).

    python benchmarks/bench_formats.py                      # 1M triangles
    python benchmarks/bench_formats.py --triangles 100000 --first-pixel
    python benchmarks/bench_formats.py --instances 1000 --mesh-triangles 100000 --flat-instances 10
    python benchmarks/bench_formats.py --rigid 51000
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

from tests.support.format_files import GltfBuilder, binary_ply_mesh  # noqa: E402


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
    ap.add_argument("--instances", type=int, default=0)
    ap.add_argument("--mesh-triangles", type=int, default=100_000)
    ap.add_argument("--flat-instances", type=int, default=10)
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--render-size", type=int, default=64)
    ap.add_argument("--image")
    ap.add_argument("--rigid", type=int, default=0)
    args = ap.parse_args()
    if args.instances:
        return bench_instances(args)
    if args.rigid:
        return bench_rigid(args)
    from warp_spt.gltf import load_gltf
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


def bench_instances(args) -> None:
    import warp as wp

    from tests.accel.test_instances import _cast_flat, _cast_inst, bumpy_sphere, flattened
    from warp_spt.upload.instances import geometry_bytes, upload_instances
    from warp_spt.rendering.settings import RenderSettings
    from warp_spt.rendering.tiles import render_scene
    from warp_spt.scene.camera import Camera

    n = max(4, int(np.sqrt(args.mesh_triangles / 4)))
    mesh = bumpy_sphere(n)
    side = int(np.ceil(np.sqrt(args.instances)))
    xf = np.tile(np.eye(4), (args.instances, 1, 1))
    k = np.arange(args.instances)
    xf[:, 0, 3], xf[:, 2, 3] = 3.0 * (k % side), 3.0 * (k // side)
    rng = np.random.default_rng(0)
    xf[:, 1, 3] = rng.uniform(0, 1, args.instances)
    # a pinhole above and in front of the grid, looking at its centre
    centre = np.array([1.5 * (side - 1), 0.0, 1.5 * (side - 1)])
    eye = centre + np.array([0.0, 0.9, -1.2]) * max(1.5 * side, 4.0)
    fwd = (centre - eye) / np.linalg.norm(centre - eye)
    right = np.cross(fwd, [0, 1, 0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    s = np.linspace(-0.5, 0.5, args.size)
    px, py = np.meshgrid(s, -s)
    d = fwd + px[..., None] * right + py[..., None] * up
    d = (d / np.linalg.norm(d, axis=-1, keepdims=True)).reshape(-1, 3).astype(np.float32)
    o = np.broadcast_to(eye, d.shape).astype(np.float32)
    rays = (wp.array(o, dtype=wp.vec3), wp.array(d, dtype=wp.vec3))
    print(f"{args.instances} instances of a {len(mesh.indices):,}-triangle mesh ({args.instances * len(mesh.indices):,} "
          f"triangles), {len(d):,} rays; wall seconds")

    def trace(kernel, inputs):
        outs = [wp.zeros(len(d), dtype=float), wp.zeros(len(d), dtype=int), wp.zeros(len(d), dtype=int),
                wp.zeros(len(d), dtype=wp.vec3)]
        wp.launch(kernel, dim=len(d), inputs=[*inputs, *rays, *outs])       # compile, warm
        wp.synchronize()
        best = float("inf")
        for _ in range(3):
            t = time.perf_counter()
            wp.launch(kernel, dim=len(d), inputs=[*inputs, *rays, *outs])
            wp.synchronize()
            best = min(best, time.perf_counter() - t)
        return best, outs

    camera = Camera.look_at(eye, centre, up="y", fov=2 * np.degrees(np.arctan(0.5 * np.sqrt(2))))
    rs = RenderSettings(width=args.render_size, height=args.render_size, spp=1, max_depth=3, integrator="nee")

    def render_time(dev):
        render_scene(dev, camera, rs)                      # compile, warm
        t = time.perf_counter()
        render_scene(dev, camera, rs)
        return time.perf_counter() - t

    t = time.perf_counter()
    inst = upload_instances([mesh], np.zeros(args.instances, np.int32), xf)
    up_inst = time.perf_counter() - t
    secs, outs = trace(_cast_inst, [inst.device.geometry])
    hits = int((outs[1].numpy() >= 0).sum())
    print(f"instanced: {inst.device_bytes() / 2**20:8.1f} MiB geometry, upload {up_inst:.2f} s, "
          f"{len(d) / secs / 1e6:.2f} M rays/s ({hits:,} hits), render {args.render_size}^2 x 1 spp "
          f"{render_time(inst.device):.2f} s")
    if args.image:
        from PIL import Image

        shade = np.abs(np.einsum("ij,ij->i", outs[3].numpy(), d)) * (outs[1].numpy() >= 0)
        Image.fromarray((255 * shade.reshape(args.size, args.size)).astype(np.uint8)).save(args.image)
        print(f"wrote {args.image}")
    m = min(args.flat_instances, args.instances)
    if m:
        sub = upload_instances([mesh], np.zeros(m, np.int32), xf[:m])
        t = time.perf_counter()
        flat = flattened([mesh], np.zeros(m, np.int32), xf[:m])
        up_flat = time.perf_counter() - t
        flat_bytes = geometry_bytes(flat)
        s_flat, _ = trace(_cast_flat, [flat.geometry])
        s_sub, _ = trace(_cast_inst, [sub.device.geometry])
        print(f"first {m} instances: flattened {flat_bytes / 2**20:.1f} MiB, upload {up_flat:.2f} s, "
              f"{len(d) / s_flat / 1e6:.2f} M rays/s, render {render_time(flat):.2f} s; "
              f"instanced {sub.device_bytes() / 2**20:.1f} MiB, {len(d) / s_sub / 1e6:.2f} M rays/s, "
              f"render {render_time(sub.device):.2f} s (same rays, same view)")
        print(f"flattened, all {args.instances}: about {flat_bytes / m * args.instances / 2**30:.1f} GiB "
              "(scaled from the first ones)")


def bench_rigid(args) -> None:
    from warp_spt.animation import ObjSequence
    from warp_spt.upload.device_scene import DeviceScene

    pos, faces = grid(args.rigid)
    g = GltfBuilder()
    p = g.accessor(pos, "VEC3", 5126)
    i = g.accessor(faces.reshape(-1).astype(np.uint32), "SCALAR", 5125)
    g.doc["meshes"].append({"primitives": [{"attributes": {"POSITION": p}, "indices": i}]})
    g.node(mesh=0)
    times = g.accessor(np.array([0.0, 1.0], np.float32), "SCALAR", 5126)
    moves = g.accessor(np.array([[0, 0, 0], [2, 0, 1]], np.float32), "VEC3", 5126)
    s = np.sqrt(0.5)
    turns = g.accessor(np.array([[0, 0, 0, 1], [0, s, 0, s]], np.float32), "VEC4", 5126)
    g.doc["animations"] = [{"samplers": [{"input": times, "output": moves}, {"input": times, "output": turns}],
                            "channels": [{"sampler": 0, "target": {"node": 0, "path": "translation"}},
                                         {"sampler": 1, "target": {"node": 0, "path": "rotation"}}]}]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "moving.glb"
        path.write_bytes(g.glb())
        print(f"a {len(faces):,}-triangle mesh moved rigidly by a node channel; per frame: load (posed) + upload, "
              f"best of {args.repeat}, wall seconds")
        for _ in range(2):
            seq = ObjSequence([str(path)], fps=8)
            meshes: dict = {}
            DeviceScene(seq.scene(0), meshes=meshes)                  # frame 0: the first build
            loads, uploads = [], []
            for k in range(1, 1 + args.repeat):
                t = time.perf_counter()
                scene = seq.scene(k)
                loads.append(time.perf_counter() - t)
                t = time.perf_counter()
                DeviceScene(scene, meshes=meshes)
                uploads.append(time.perf_counter() - t)
        print(f"per frame: load {min(loads):.3f} s, upload {min(uploads):.3f} s (frames 1..{args.repeat}, uploads: "
              + ", ".join(f"{x:.3f}" for x in uploads) + ")")


if __name__ == "__main__":
    main()
