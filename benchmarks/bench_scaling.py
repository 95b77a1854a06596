"""Large meshes (issue 33): whole-process time and peak memory against triangle count, warp_spt and Mitsuba 3.

    python benchmarks/bench_scaling.py                          # 100k, 1M, 3M triangles (binary PLY)
    python benchmarks/bench_scaling.py --sizes 100k,1M,3M,10M --format obj --plot docs/scaling.png
    python benchmarks/bench_scaling.py --before ../old-checkout      # also another checkout's warp_spt

Each size is a heightfield generated here (a grid of smooth hills, two triangles per cell, written
once as binary PLY or OBJ into a temporary folder), lit by a one-sided area light above it (a quad
in its own OBJ) and a constant sky, seen at an angle by a pinhole camera: 256x256, 16 spp, depth 6.
The heightfield is a grey diffuse surface (warp_spt: the clay default, albedo 0.6; Mitsuba: a
two-sided diffuse of 0.6).

Every render is a fresh Python process, as a user's command runs: imports, parsing the files,
building the acceleration structures, the render, the image as a numpy array. Printed per size and
renderer: wall seconds (of the whole child process, measured by this script), its CPU seconds (all
threads: steadier than wall time on a shared machine) and the child's peak resident memory (``ru_maxrss``, its own report at exit), then the ratios warp_spt / Mitsuba. A first
round at the smallest size fills both renderers' kernel caches (and a Python bytecode cache in the
temporary folder, as an installed package has one) and is not counted. warp_spt renders
with its defaults (``nee`` + ``sobol``), Mitsuba with ``path`` and its default ``independent``
sampler, both on ``--threads`` threads.

``--phases`` only prints where one warp_spt render's CPU seconds go, step by step, with the peak
memory after each. ``--parse`` only times reading each size's file, binary PLY and OBJ (MB/s), and says whether the
OBJ went through the vectorised scanner. ``--plot FILE`` draws time and memory against triangles for both renderers (matplotlib, optional).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SIZE, SPP, DEPTH = 256, 16, 6
EXTENT = 10.0                   # the heightfield spans [0, EXTENT]^2 in x and y, Z up
SKY = (0.3, 0.35, 0.4)
LIGHT = (8.0, 8.0, 8.0)
CAMERA = dict(position=(5.0, -5.0, 4.0), target=(5.0, 5.0, 0.0), fov=60.0)   # below the light: its back emits in warp_spt only


def parse_size(text: str) -> int:
    t = text.strip().lower()
    scale = {"k": 1_000, "m": 1_000_000}.get(t[-1:], 1)
    return int(float(t[:-1] if scale > 1 else t) * scale)


def heightfield(triangles: int) -> tuple[np.ndarray, np.ndarray]:
    """(points (N, 3) float32, faces (K, 3) int32) of a g x g grid of hills with about ``triangles`` triangles."""
    g = max(2, int(round(np.sqrt(triangles / 2.0))) + 1)
    u = np.linspace(0.0, EXTENT, g)
    x, y = np.meshgrid(u, u, indexing="xy")
    z = 0.6 * np.sin(1.3 * x) * np.cos(0.9 * y) + 0.3 * np.sin(3.1 * x + 2.3 * y) + 0.15 * np.cos(7.0 * y - 5.0 * x)
    points = np.stack([x, y, z], axis=-1).reshape(-1, 3).astype(np.float32)
    i = np.arange(g - 1)
    a = (i[:, None] * g + i[None, :]).reshape(-1)          # lower-left corner of every cell
    faces = np.empty((len(a), 2, 3), dtype=np.int32)
    faces[:, 0] = np.stack([a, a + 1, a + g + 1], axis=1)
    faces[:, 1] = np.stack([a, a + g + 1, a + g], axis=1)
    return points, faces.reshape(-1, 3)


def write_ply(path: Path, points: np.ndarray, faces: np.ndarray) -> None:
    header = (f"ply\nformat binary_little_endian 1.0\nelement vertex {len(points)}\n"
              "property float x\nproperty float y\nproperty float z\n"
              f"element face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n").encode()
    rows = np.empty(len(faces), dtype=[("n", "u1"), ("v", "<i4", (3,))])
    rows["n"] = 3
    rows["v"] = faces
    with open(path, "wb") as f:
        f.write(header)
        f.write(points.astype("<f4").tobytes())
        f.write(rows.tobytes())


def write_obj(path: Path, points: np.ndarray, faces: np.ndarray) -> None:
    with open(path, "w") as f:
        np.savetxt(f, points, fmt="v %.6g %.6g %.6g")
        np.savetxt(f, faces + 1, fmt="f %d %d %d")


def write_scene(folder: Path, triangles: int, fmt: str) -> tuple[Path, int]:
    """The heightfield file and the light's OBJ/MTL (warp_spt) in ``folder``; returns (file, triangles)."""
    points, faces = heightfield(triangles)
    mesh = folder / f"height.{fmt}"
    (write_ply if fmt == "ply" else write_obj)(mesh, points, faces)
    # the light: a 3x3 quad 5 above the middle, facing down (Mitsuba's emitters are one-sided)
    c, h, s = EXTENT / 2, 5.0, 1.5
    quad = f"v {c - s} {c - s} {h}\nv {c - s} {c + s} {h}\nv {c + s} {c + s} {h}\nv {c + s} {c - s} {h}\n"
    (folder / "light.obj").write_text(f"mtllib light.mtl\n{quad}usemtl light\nf 1 2 3\nf 1 3 4\n")
    (folder / "light_mi.obj").write_text(f"{quad}f 1 2 3\nf 1 3 4\n")     # Mitsuba's: the same quad
    (folder / "light.mtl").write_text(f"newmtl light\nKd 0 0 0\nKe {LIGHT[0]} {LIGHT[1]} {LIGHT[2]}\nRoughness 1\n")
    return mesh, len(faces)


_CHILD = """
import resource, sys, time
from pathlib import Path
folder, mesh, threads = Path({folder!r}), {mesh!r}, {threads}
cam = {camera!r}
if {ours}:
    import warp as wp
    wp.config.log_level = wp.LOG_WARNING
    from warp_spt import Camera, RenderSettings, Sky, load_scene, render_scene
    scene = load_scene([mesh, str(folder / "light.obj")], [str(folder / "light.mtl")], default_material="clay",
                       warn=lambda m: None)
    d = [t - p for t, p in zip(cam["target"], cam["position"])]
    camera = Camera(position=cam["position"], direction=d, fov=cam["fov"], aperture=0.0, focus=10.0)
    rs = RenderSettings(width={size}, height={size}, spp={spp}, max_depth={depth}, sky=Sky.constant(*{sky!r}),
                        threads=threads, seed=1)
    image = render_scene(scene, camera, rs).image
else:
    import mitsuba as mi
    mi.set_variant({variant!r})
    import drjit as dr
    dr.set_thread_count(threads)
    rgb = lambda c: {{"type": "rgb", "value": list(c)}}
    d = {{"type": "scene", "integrator": {{"type": "path", "max_depth": {depth}}},
         "height": {{"type": {fmt!r}, "filename": mesh, "face_normals": True,
                    "bsdf": {{"type": "twosided", "material": {{"type": "diffuse", "reflectance": rgb((0.6, 0.6, 0.6))}}}}}},
         "light": {{"type": "obj", "filename": str(folder / "light_mi.obj"), "face_normals": True,
                   "bsdf": {{"type": "diffuse", "reflectance": rgb((0, 0, 0))}},
                   "emitter": {{"type": "area", "radiance": rgb({light!r})}}}},
         "sky": {{"type": "constant", "radiance": rgb({sky!r})}},
         "sensor": {{"type": "perspective", "fov": cam["fov"], "fov_axis": "x",
                    "to_world": mi.ScalarTransform4f().look_at(origin=list(cam["position"]), target=list(cam["target"]),
                                                               up=[0, 0, 1]),
                    "sampler": {{"type": "independent", "sample_count": {spp}}},
                    "film": {{"type": "hdrfilm", "width": {size}, "height": {size}, "pixel_format": "rgb",
                             "rfilter": {{"type": "box"}}}}}}}}
    import numpy as np
    image = np.array(mi.render(mi.load_dict(d), spp={spp}, seed=1))[..., :3]
r = resource.getrusage(resource.RUSAGE_SELF)
print("RESULT", r.ru_maxrss * 1024, float(image.mean()), r.ru_utime + r.ru_stime)
"""


# --phases: one warp_spt render in a fresh process, its CPU seconds and peak memory step by step (the
# steps are timed by wrapping the functions named here, in this child only: nothing else changes)
_PHASES_CHILD = """
import resource, sys, time
def hwm():
    return int(open("/proc/self/status").read().split("VmHWM:")[1].split()[0]) // 1024
cpu = time.process_time
import warp as wp
wp.config.log_level = wp.LOG_WARNING
from warp_spt import Camera, RenderSettings, Sky, load_scene, render_scene
from warp_spt.runtime.warp_init import init_warp
import warp_spt.upload.device_scene as ds
import warp_spt.rendering.setup as setup
init_warp()
rows = [("Python, numpy, Warp and warp_spt imports, wp.init", cpu(), hwm())]
spent = {{}}
def timed(owner, name, label):
    f = getattr(owner, name)
    def g(*a, **k):
        t = cpu()
        try:
            return f(*a, **k)
        finally:
            spent[label] = spent.get(label, 0.0) + cpu() - t
            spent[label + " peak"] = hwm()
    setattr(owner, name, g)
timed(ds, "build_wide", "wide BVH build")
timed(ds.DeviceScene, "_upload_wide", "wide BVH upload, leaf-ordered corners")
timed(setup, "upload", "DeviceScene")
timed(setup, "light_table", "light table")
t = cpu()
scene = load_scene([{mesh!r}, {light!r}], [{mtl!r}], default_material="clay", warn=lambda m: None)
rows.append(("read the file, build the host Scene (load_scene)", cpu() - t, hwm()))
cam = {camera!r}
d = [a - b for a, b in zip(cam["target"], cam["position"])]
camera = Camera(position=cam["position"], direction=d, fov=cam["fov"], aperture=0.0, focus=10.0)
rs = RenderSettings(width={size}, height={size}, spp={spp}, max_depth={depth}, sky=Sky.constant(*{sky!r}),
                    threads={threads}, seed=1)
t = cpu()
render_scene(scene, camera, rs)
total = cpu() - t
up = spent["DeviceScene"]
rows.append(("DeviceScene (validation, meshes, BVHs, materials)", up, spent["DeviceScene peak"]))
rows.append(("  of it: the wide BVH build", spent["wide BVH build"], spent["wide BVH build peak"]))
rows.append(("  of it: the wide BVH upload", spent["wide BVH upload, leaf-ordered corners"],
             spent["wide BVH upload, leaf-ordered corners peak"]))
rows.append(("light table", spent["light table"], spent["light table peak"]))
rows.append(("kernel from the cache, the render, the image", total - up - spent["light table"], hwm()))
r = resource.getrusage(resource.RUSAGE_SELF)
rows.append(("whole process", r.ru_utime + r.ru_stime, r.ru_maxrss // 1024))
print("PHASES", repr(rows))
"""


def phases(sizes: list[int], threads: int, fmt: str = "ply") -> None:
    """Where one warp_spt render's CPU seconds go, and the peak memory after each step (fresh
    processes, after an uncounted round that fills the caches), the heightfield written as ``fmt``."""
    import ast
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env["PYTHONPYCACHEPREFIX"] = str(folder / "pycache")
        for i, k in enumerate(sizes):
            mesh, tris = write_scene(folder, k, fmt)
            code = _PHASES_CHILD.format(mesh=str(mesh), light=str(folder / "light.obj"), mtl=str(folder / "light.mtl"),
                                        camera=CAMERA, size=SIZE, spp=SPP, depth=DEPTH, sky=SKY, threads=threads)
            for _ in range(2 if i == 0 else 1):
                out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=folder, env=env)
                if out.returncode != 0:
                    raise RuntimeError(out.stderr[-3000:])
            rows = ast.literal_eval(next(x for x in out.stdout.splitlines() if x.startswith("PHASES"))[7:])
            print(f"\n{tris:,} triangles, {fmt} (load average {os.getloadavg()[0]:.1f})\n")
            print("| step | CPU s | peak RSS so far, MB |")
            print("|---|---|---|")
            for name, sec, peak in rows:
                print(f"| {name} | {sec:.2f} | {peak} |")
            mesh.unlink()


def run_child(ours: bool, folder: Path, mesh: Path, fmt: str, threads: int, variant: str, pythonpath: str | None = None
              ) -> tuple[float, int, float, float]:
    """(wall seconds, peak RSS bytes, image mean, CPU seconds of all threads) of one render in a fresh process
    (``pythonpath``: where that process imports warp_spt from)."""
    # bytecode cached as an installed package has it, even where PYTHONDONTWRITEBYTECODE is set (this VM):
    # compiling warp_spt's sources is not part of a user's start (the uncounted first round fills it)
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    env["PYTHONPYCACHEPREFIX"] = str(folder / "pycache")
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    code = _CHILD.format(folder=str(folder), mesh=str(mesh), threads=threads, camera=CAMERA, ours=ours, size=SIZE,
                         spp=SPP, depth=DEPTH, sky=SKY, variant=variant, extent=EXTENT, fmt=fmt, light=LIGHT)
    t = time.perf_counter()
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=folder, env=env)
    wall = time.perf_counter() - t
    line = [x for x in out.stdout.splitlines() if x.startswith("RESULT")]
    if out.returncode != 0 or not line:
        raise RuntimeError(f"{'warp_spt' if ours else 'Mitsuba'} failed (exit {out.returncode}): {out.stderr[-3000:]}")
    _, rss, mean, cpu = line[-1].split()
    return wall, int(rss), float(mean), float(cpu)


def cpu_name() -> str:
    """The CPU's model name and its widest vector extension (the ratio depends on it, issue 33)."""
    try:
        info = Path("/proc/cpuinfo").read_text()
    except OSError:
        return platform.processor() or platform.machine()
    name = next((line.split(":", 1)[1].strip() for line in info.splitlines() if line.startswith("model name")), "?")
    flags = next((line.split(":", 1)[1].split() for line in info.splitlines() if line.startswith("flags")), [])
    vec = "AVX-512" if "avx512f" in flags else "AVX2" if "avx2" in flags else "no AVX2"
    return f"{name} ({vec})"


def pick_variant() -> str:
    """llvm_ad_rgb when a one-sample render works in a subprocess (an old libLLVM aborts it), else scalar_rgb."""
    probe = "import mitsuba as mi; mi.set_variant('llvm_ad_rgb'); mi.render(mi.load_dict(mi.cornell_box()), spp=1)"
    ok = subprocess.run([sys.executable, "-c", probe], capture_output=True).returncode == 0
    return "llvm_ad_rgb" if ok else "scalar_rgb"


def parse_speed(sizes: list[int]) -> None:
    """MB/s of reading each size's heightfield as binary PLY and as OBJ (``read_model``, in this
    process, best of 2), and whether the OBJ went through the vectorised scanner (io/obj_bulk.py)."""
    sys.path.insert(0, str(ROOT))
    from warp_spt.io.loader import read_model
    from warp_spt.io.obj_bulk import scan_bulk
    print("| triangles | format | MB | seconds | MB/s | triangles/s | vectorised OBJ scanner |")
    print("|---|---|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for k in sizes:
            for fmt in ("ply", "obj"):
                mesh, tris = write_scene(Path(tmp), k, fmt)
                mb = mesh.stat().st_size / 2**20
                best = min(_timed(lambda: read_model(str(mesh))) for _ in range(2))
                bulk = "" if fmt == "ply" else ("yes" if scan_bulk(mesh.read_bytes(), str(mesh)) is not None else "NO")
                print(f"| {tris:,} | {fmt} | {mb:.0f} | {best:.2f} | {mb / best:.0f} | {tris / best / 1e6:.2f} M | {bulk} |",
                      flush=True)
                mesh.unlink()


def _timed(fn) -> float:
    t = time.perf_counter()
    fn()
    return time.perf_counter() - t


def plot(rows: list[dict], path: str) -> None:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("--plot: matplotlib is not installed (pip install matplotlib); no plot written")
        return
    k = [r["triangles"] for r in rows]
    fig, (a, b) = plt.subplots(1, 2, figsize=(8, 3.2), dpi=80)
    for who, style in (("before", "^:"), ("warp_spt", "o-"), ("Mitsuba", "s--")):
        if who in rows[0]:
            label = "warp_spt before" if who == "before" else who
            a.plot(k, [r[who]["wall"] for r in rows], style, label=label)
            b.plot(k, [r[who]["rss"] / 2**30 for r in rows], style, label=label)
    for ax, label in ((a, "whole process, s"), (b, "peak RSS, GiB")):
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("triangles")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.suptitle(f"Heightfield, {SIZE}x{SIZE}, {SPP} spp, depth {DEPTH}", fontsize=10)
    fig.tight_layout()
    fig.savefig(path)
    print(f"plot written to {path}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="100k,1M,3M", help="triangle counts, e.g. 100k,1M,3M,10M")
    ap.add_argument("--format", choices=("ply", "obj"), default="ply", help="the heightfield's file format")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--repeat", type=int, default=1, help="runs of each renderer per size (median)")
    ap.add_argument("--only", choices=("warp_spt", "Mitsuba"), default=None, help="run one renderer only")
    ap.add_argument("--before", default=None, metavar="DIR",
                    help="also render with the warp_spt of another checkout (its root), as 'before', in turn with the others")
    ap.add_argument("--plot", default=None, metavar="FILE", help="draw the curve into FILE (matplotlib)")
    ap.add_argument("--parse", action="store_true", help="only the reading speed of each size, PLY and OBJ (MB/s)")
    ap.add_argument("--phases", action="store_true",
                    help="only warp_spt's CPU seconds and peak memory step by step (load, upload, BVH, light table, "
                         "render)")
    ap.add_argument("--json", default=None, metavar="FILE", help="also write the figures as JSON")
    args = ap.parse_args()
    sizes = [parse_size(s) for s in args.sizes.split(",")]
    paths = {"warp_spt": None, "Mitsuba": None, "before": args.before}
    if args.parse:
        parse_speed(sizes)
        return 0
    if args.phases:
        phases(sizes, args.threads, args.format)
        return 0
    who = [args.only] if args.only else ["warp_spt", "Mitsuba"]
    variant = ""
    if "Mitsuba" in who:
        try:
            import mitsuba  # noqa: F401
        except ImportError:
            print("Mitsuba is not installed (pip install mitsuba): warp_spt only")
            who = ["warp_spt"]
        else:
            variant = pick_variant()
    if args.before:
        who.insert(0, "before")
    print(f"CPU: {cpu_name()}, {os.cpu_count()} cores; threads {args.threads}; "
          f"Mitsuba variant {variant or '-'}; format {args.format}; load average {os.getloadavg()[0]:.1f}")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        for i, k in enumerate(sizes):
            for f in folder.glob("height.*"):
                f.unlink()
            t = time.perf_counter()
            mesh, tris = write_scene(folder, k, args.format)
            mb = mesh.stat().st_size / 2**20
            print(f"\n{tris:,} triangles: {mesh.name} {mb:.0f} MB written in {time.perf_counter() - t:.1f} s", flush=True)
            if i == 0:              # fills both kernel caches
                for w in who:
                    run_child(w != "Mitsuba", folder, mesh, args.format, args.threads, variant, paths[w])
            row = {"triangles": tris, "file_mb": mb}
            for w in who:
                runs = [run_child(w != "Mitsuba", folder, mesh, args.format, args.threads, variant, paths[w])
                        for _ in range(args.repeat)]
                row[w] = dict(wall=statistics.median(r[0] for r in runs), rss=max(r[1] for r in runs), mean=runs[0][2],
                              cpu=statistics.median(r[3] for r in runs))
                print(f"  {w:8s} {row[w]['wall']:7.2f} s (CPU {row[w]['cpu']:6.2f} s)  peak RSS {row[w]['rss'] / 2**20:7.0f} MB "
                      f"({row[w]['rss'] / tris:5.0f} B/triangle)  image mean {row[w]['mean']:.4f}", flush=True)
            rows.append(row)
    both = "warp_spt" in who and "Mitsuba" in who
    print(f"\nload average at the end {os.getloadavg()[0]:.1f}")
    print(f"\n| triangles | " + " | ".join(f"{w} s (CPU s) | {w} peak MB" for w in who)
          + (" | time ratio (CPU) | memory ratio |" if both else " |"))
    print("|---" * (1 + 2 * len(who) + (2 if both else 0)) + "|")
    for r in rows:
        cells = [f"{r[w]['wall']:.2f} ({r[w]['cpu']:.2f}) | {r[w]['rss'] / 2**20:.0f}" for w in who]
        ratios = ""
        if "warp_spt" in who and "Mitsuba" in who:
            ratios = (f" | **{r['warp_spt']['wall'] / r['Mitsuba']['wall']:.2f}** "
                      f"({r['warp_spt']['cpu'] / r['Mitsuba']['cpu']:.2f}) | "
                      f"**{r['warp_spt']['rss'] / r['Mitsuba']['rss']:.2f}**")
        print(f"| {r['triangles']:,} | " + " | ".join(cells) + ratios + " |")
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=1))
    if args.plot and both:
        plot(rows, args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main())
