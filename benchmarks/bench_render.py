"""Render speed: camera samples/s, rays/s and seconds on the demo scenes, 1 thread and all threads,
kernel compile time (cold and cached) and what each kernel specialisation saves.

    python benchmarks/bench_render.py            # 512x512, 16 spp, depth 6 and 8 (a few minutes)
    python benchmarks/bench_render.py --quick    # 128x128, 4 spp: a smoke run
    python benchmarks/bench_render.py --speed-only   # the speed and thread-scaling table alone

Figures are from one run; compare ratios within a run, not absolute times across machines.

Thread scaling on a shared machine: wall-clock speed-up measures the other jobs as much as the
renderer, so the table also gives the process's CPU seconds (all threads) and the CPU-time scaling
``threads x CPU(1 thread) / CPU(n threads)``: the speed-up the renderer would reach on idle cores if
its tiles split evenly (64 tiles of 4096 pixels at 512^2), i.e. what parallel overhead costs. The
load average at each run is printed beside it.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING   # no banner or module-load lines (Warp 1.19 dropped config.quiet)

import warp_spt.rendering.tiles as R
from warp_spt.upload.device_scene import DeviceScene, Features  # noqa: E402
from warp_spt.demo import demo_files  # noqa: E402
from warp_spt.integrators import get_kernel  # noqa: E402
from warp_spt.io.loader import load_scene  # noqa: E402
from warp_spt.scene.sky import Sky  # noqa: E402

SEED_DEMO = REPO.parent / "shared" / "seed" / "demo"


def scenes() -> dict[str, DeviceScene]:
    out = {}
    objs, mtls = demo_files()
    out["builtin demo"] = DeviceScene(load_scene(objs, mtls))
    if (SEED_DEMO / "cornell_export.obj").is_file():
        seed = load_scene([str(SEED_DEMO / "cornell_export.obj"), str(SEED_DEMO / "baller.obj")],
                          [str(SEED_DEMO / "testMiku.mtl")])
        out["seed demo (no character)"] = DeviceScene(seed)
    return out


def timed_render(scene: DeviceScene, size: int, spp: int, depth: int, threads: int,
                 features: Features | None = None) -> tuple[float, int, float]:
    """(wall seconds, closest-hit rays, CPU seconds of the whole process)."""
    t, c = time.perf_counter(), time.process_time()
    res = R.render_scene(scene, settings=R.RenderSettings(width=size, height=size, spp=spp, max_depth=depth,
                                                          sky=Sky.gradient(), threads=threads, features=features))
    return time.perf_counter() - t, res.stats.rays, time.process_time() - c


def speed_table(all_scenes: dict[str, DeviceScene], size: int, spp: int) -> None:
    ncpu = os.cpu_count() or 1
    print(f"\n## Speed: {size}x{size}, {spp} spp (GradientSky), threads 1 and {ncpu}")
    print("| scene | tris | depth | threads | wall s | CPU s | camera samples/CPU-s | rays/CPU-s | wall speed-up "
          "| CPU-time scaling | load avg |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for name, sc in all_scenes.items():
        get_kernel(sc.features)      # compile outside the timing
        timed_render(sc, 16, 1, 2, 1)
        for depth in (6, 8):
            base = None
            for threads in (1, ncpu):
                load = os.getloadavg()[0]
                secs, rays, cpu = timed_render(sc, size, spp, depth, threads)
                base = base or (secs, cpu)
                print(f"| {name} | {sc.scene.num_triangles} | {depth} | {threads} | {secs:.2f} | {cpu:.2f} | "
                      f"{size * size * spp / cpu:,.0f} | {rays / cpu:,.0f} | {base[0] / secs:.2f}x | "
                      f"{threads * base[1] / cpu:.2f}x | {load:.1f} |")


def specialisation_table(name: str, sc: DeviceScene, size: int, spp: int) -> None:
    """Time the scene's own kernel against kernels with one unused feature switched back on."""
    own = sc.features
    print(f"\n## What specialisation saves ({name}, {size}x{size}, {spp} spp, depth 8, all threads)")
    print(f"scene features: {own}")
    print("| kernel | CPU seconds | relative to specialised |")
    print("|---|---|---|")
    variants = {"specialised": own, "general (every feature)": Features.general()}
    for field in ("meshes", "spheres", "textures", "checker", "refraction", "emitters", "smooth", "diffuse",
                  "specular"):
        if not getattr(own, field):
            variants[f"+ {field} code"] = replace(own, **{field: True})
    base = None
    for label, feats in variants.items():
        get_kernel(feats)
        timed_render(sc, 16, 1, 2, None, feats)
        best = min(timed_render(sc, size, spp, 8, None, feats)[2] for _ in range(2))   # CPU s
        base = base or best
        print(f"| {label} | {best:.3f} | {best / base:.3f} |")


def compile_times() -> None:
    """Cold compile in a fresh process with an empty kernel cache, then a cached load in another."""
    print("\n## Kernel compile (builtin demo's kernel), fresh processes")
    code = ("import time,warp as wp; wp.config.log_level=wp.LOG_WARNING; wp.init(); t=time.perf_counter();"
            "from warp_spt.demo import demo_files; from warp_spt.io.loader import load_scene;"
            "from warp_spt.upload.device_scene import DeviceScene; from warp_spt.integrators import get_kernel;"
            "o,m=demo_files(); s=DeviceScene(load_scene(o,m)); t=time.perf_counter();"
            "get_kernel(s.features); print(time.perf_counter()-t)")
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, WARP_CACHE_PATH=cache, PYTHONPATH=str(REPO))
        for label in ("cold (empty cache)", "cached"):
            out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
            secs = out.stdout.strip().splitlines()[-1] if out.stdout.strip() else f"failed: {out.stderr[-300:]}"
            print(f"- {label}: {float(secs):.2f} s" if secs[0].isdigit() else f"- {label}: {secs}")


_START_CHILD = """
import time
t0, c0 = time.perf_counter(), time.process_time()
import warp as wp
wp.config.log_level = wp.LOG_WARNING   # no banner or module-load lines (Warp 1.19 dropped config.quiet)
from warp_spt import Camera, RenderSettings, Sky, load_scene, render_scene
from warp_spt.rendering.setup import bind
t1, c1 = time.perf_counter(), time.process_time()
scene = load_scene([{obj!r}], [{mtl!r}])
t2, c2 = time.perf_counter(), time.process_time()
rs = RenderSettings(width=64, height=64, spp=1, max_depth=6, sky=Sky.black(), threads=1)
cam = Camera(position=(16.0, -38.0, 16.0), direction=(0.0, 1.0, 0.0), fov=40.0, aperture=0.0, focus=30.0)
bind(scene, cam, rs)
t3, c3 = time.perf_counter(), time.process_time()
render_scene(scene, cam, rs)
t4, c4 = time.perf_counter(), time.process_time()
import sys, warp_spt
print(warp_spt.__file__, file=sys.stderr)
print(t1 - t0, t2 - t1, t3 - t2, t4 - t3, c1 - c0, c2 - c1, c3 - c2, c4 - c3)
"""


_PARTS_CHILD = """
import time
c0 = time.process_time()
import warp as wp
c1 = time.process_time()
wp.config.log_level = wp.LOG_WARNING
from warp_spt.runtime.warp_init import init_warp
init_warp()
c2 = time.process_time()
from warp_spt import Camera, RenderSettings, Sky, load_scene, render_scene
import warp_spt.upload.device_scene as ds
import warp_spt.rendering.setup as setup
from warp._src import context
c3 = time.process_time()
spent = {{"upload (DeviceScene)": 0.0, "get_kernel (built and hashed, or found by own key)": 0.0,
         "module loaded": 0.0}}
def timed(owner, name, key):
    orig = getattr(owner, name)
    def wrapper(*a, **k):
        c = time.process_time()
        try:
            return orig(*a, **k)
        finally:
            spent[key] += time.process_time() - c
    setattr(owner, name, wrapper)
timed(ds.DeviceScene, "__init__", "upload (DeviceScene)")
timed(setup, "get_kernel", "get_kernel (built and hashed, or found by own key)")
timed(context.Module, "load", "module loaded")
scene = load_scene([{obj!r}], [{mtl!r}])
c4 = time.process_time()
rs = RenderSettings(width=64, height=64, spp=1, max_depth=6, sky=Sky.black(), threads=1)
cam = Camera(position=(16.0, -38.0, 16.0), direction=(0.0, 1.0, 0.0), fov=40.0, aperture=0.0, focus=30.0)
setup.bind(scene, cam, rs)
c5 = time.process_time()
parts = {{"import warp": c1 - c0, "wp.init": c2 - c1, "warp_spt imports": c3 - c2, "load_scene": c4 - c3,
         "bind": c5 - c4, **spent}}
print(repr(parts))
"""


def start_parts(repeat: int) -> None:
    """Where a cached start's CPU time goes, in one process: ``import warp``, ``wp.init``, warp_spt's
    imports, ``load_scene`` and ``bind`` (and, inside bind, the upload, building and hashing the
    step and kernel, loading the compiled module), CPU seconds, ``repeat`` fresh processes on a
    filled temporary kernel cache (the Cornell box of --start-only), min and median of each part.
    The parts of bind may overlap: the wide BVH's build module loads inside the upload."""
    import ast
    import statistics
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_vs_mitsuba as mb
    desc = mb.SCENES["cornell"]
    with tempfile.TemporaryDirectory() as folder, tempfile.TemporaryDirectory() as cache:
        obj, mtl = Path(folder) / "scene.obj", Path(folder) / "scene.mtl"
        obj.write_text(mb.obj_text(desc["shapes"]))
        mtl.write_text(mb.mtl_text(desc["materials"]))
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        env.update(PYTHONPATH=os.environ.get("PYTHONPATH", str(REPO)),
                   PYTHONPYCACHEPREFIX=str(Path(folder) / "pycache"), WARP_CACHE_PATH=cache)
        code = _PARTS_CHILD.format(obj=str(obj), mtl=str(mtl))
        subprocess.run([sys.executable, "-c", code], env=env, check=True, cwd=folder, capture_output=True)
        runs = []
        for _ in range(repeat):
            out = subprocess.run([sys.executable, "-c", code], env=env, cwd=folder, capture_output=True, text=True)
            if out.returncode != 0:
                raise RuntimeError(out.stderr[-2000:])
            runs.append(ast.literal_eval(out.stdout.strip().splitlines()[-1]))
    print(f"\n## A cached start's CPU seconds by part (Cornell box, {repeat} fresh processes, "
          f"load average {os.getloadavg()[0]:.1f})")
    print("| part | min | median |")
    print("|---|---|---|")
    for key in runs[0]:
        vals = [r[key] for r in runs]
        inner = key not in ("import warp", "wp.init", "warp_spt imports", "load_scene", "bind")
        print(f"| {'  of bind: ' if inner else ''}{key} | {min(vals):.3f} | {statistics.median(vals):.3f} |")


def start_times(repeat: int) -> None:
    """Cold and cached start of a render of bench_vs_mitsuba's Cornell box (64x64, 1 spp: the
    launch itself is short) in fresh processes: an empty kernel cache (a temporary WARP_CACHE_PATH,
    so the shared cache is left alone), then the cache that run filled, then a new scene's start:
    that cache without its compiled modules (Warp's other folders kept, such as the shared
    precompiled header), and a new scene's start after another scene was rendered: a new cache
    filled by a render of bench_vs_mitsuba's caustics scene (other materials and spheres: another
    path kernel), so the modules that do not depend on the scene (the wide BVH's build kernels) are
    cached as on a machine that has rendered before, and only the Cornell box's path kernel is
    compiled. Medians of ``repeat`` (new empty caches each run).

    Python's bytecode is cached for the children (in a temporary PYTHONPYCACHEPREFIX, filled by an
    import before any timing) even where PYTHONDONTWRITEBYTECODE is set, as on our VM: an installed
    package has its bytecode, and compiling warp_spt's sources took 0.1-0.15 s of every start
    measured without it."""
    import statistics
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_vs_mitsuba as mb
    desc = mb.SCENES["cornell"]
    rows: dict[str, list[list[float]]] = {"cold (empty kernel cache)": [], "cached": [],
                                          "new scene (all compiled modules removed)": [],
                                          "new scene (after another scene's render)": []}
    with tempfile.TemporaryDirectory() as folder:
        obj, mtl = Path(folder) / "scene.obj", Path(folder) / "scene.mtl"
        obj.write_text(mb.obj_text(desc["shapes"]))
        mtl.write_text(mb.mtl_text(desc["materials"]))
        code = _START_CHILD.format(obj=str(obj), mtl=str(mtl))
        other = mb.SCENES["caustics"]
        other_obj, other_mtl = Path(folder) / "other.obj", Path(folder) / "other.mtl"
        other_obj.write_text(mb.obj_text(other["shapes"]))
        other_mtl.write_text(mb.mtl_text(other["materials"]))
        other_code = _START_CHILD.format(obj=str(other_obj), mtl=str(other_mtl))
        # PYTHONPATH as given (another checkout's warp_spt: before/after figures), else this one
        base_env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        base_env.update(PYTHONPATH=os.environ.get("PYTHONPATH", str(REPO)),
                        PYTHONPYCACHEPREFIX=str(Path(folder) / "pycache"))
        subprocess.run([sys.executable, "-c", "import warp_spt.rendering.setup, warp_spt.rendering.tiles"],
                       env=base_env, check=True, cwd=folder)
        bare = []
        for _ in range(repeat):
            t = time.perf_counter()
            subprocess.run([sys.executable, "-c", "pass"], check=True)
            bare.append(time.perf_counter() - t)
            with tempfile.TemporaryDirectory() as cache, tempfile.TemporaryDirectory() as other_cache:
                for label in rows:
                    env = dict(base_env, WARP_CACHE_PATH=cache)
                    if label == "new scene (all compiled modules removed)":     # drop the compiled modules, keep the rest
                        for sub in Path(cache).glob("*/wp_*"):
                            if sub.name != "wp_spt_clang_pch":
                                shutil.rmtree(sub)
                    elif label.startswith("new scene (after"):
                        env = dict(base_env, WARP_CACHE_PATH=other_cache)
                        subprocess.run([sys.executable, "-c", other_code], env=env, capture_output=True,
                                       check=True, cwd=folder)
                    t = time.perf_counter()
                    # cwd: python -c puts it first on sys.path, where a checkout would shadow PYTHONPATH
                    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                                         cwd=folder)
                    wall = time.perf_counter() - t
                    if out.returncode != 0:
                        raise RuntimeError(out.stderr[-2000:])
                    nums = [float(x) for x in out.stdout.split()[-8:]]
                    parts, cpu = nums[:4], nums[4:]
                    rows[label].append([wall - sum(parts)] + parts + [wall] + cpu)
    print(f"\n## Start-up (bench_vs_mitsuba's Cornell box, nee + sobol, 64x64, 1 spp), fresh processes, "
          f"median of {repeat}, load average {os.getloadavg()[0]:.1f}")
    interpreter = statistics.median(bare)
    print(f"warp_spt from {out.stderr.strip().splitlines()[-1]}")
    print(f"(wall / CPU seconds of each step; an empty interpreter, python -c pass, starts and exits in "
          f"{interpreter:.2f} s wall; 'until the first launch' is that plus imports, load_scene and bind)")
    print("| start | interpreter + exit | imports | load_scene | bind (compile or load) | first render | "
          "until the first launch | whole process |")
    print("|---|---|---|---|---|---|---|---|")
    for label, runs in rows.items():
        med = [statistics.median(col) for col in zip(*runs)]
        wall, cpu = med[1:5], med[6:10]
        cells = [f"{med[0]:.2f} s"] + [f"{w:.2f} / {c:.2f} s" for w, c in zip(wall, cpu)]
        before_launch = (interpreter + sum(wall[:3]), interpreter + sum(cpu[:3]))
        print(f"| {label} | " + " | ".join(cells) + f" | {before_launch[0]:.2f} / {before_launch[1]:.2f} s | "
              f"{med[5]:.2f} s |")


def cached_against(other: str, repeat: int) -> None:
    """A cached start of --start-only's Cornell box with another checkout's warp_spt (``other``, a
    folder holding ``warp_spt``: the code before a change) and with this one, alternating, each on a
    kernel cache of its own filled first (fresh processes, bytecode cached as in --start-only);
    medians of ``repeat`` CPU seconds: the two figures are taken under the same load."""
    import statistics
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_vs_mitsuba as mb
    desc = mb.SCENES["cornell"]
    trees = {f"other ({other})": str(Path(other).resolve()),
             "this checkout": os.environ.get("PYTHONPATH", str(REPO))}
    with tempfile.TemporaryDirectory() as folder:
        obj, mtl = Path(folder) / "scene.obj", Path(folder) / "scene.mtl"
        obj.write_text(mb.obj_text(desc["shapes"]))
        mtl.write_text(mb.mtl_text(desc["materials"]))
        code = _START_CHILD.format(obj=str(obj), mtl=str(mtl))
        base = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        envs = {}
        for i, (label, path) in enumerate(trees.items()):
            cache = Path(folder) / f"cache{i}"
            envs[label] = dict(base, PYTHONPATH=path, WARP_CACHE_PATH=str(cache),
                               PYTHONPYCACHEPREFIX=str(Path(folder) / f"pycache{i}"))
            subprocess.run([sys.executable, "-c", code], env=envs[label], check=True, cwd=folder, capture_output=True)
        runs: dict[str, list[list[float]]] = {label: [] for label in trees}
        bare = []
        for _ in range(repeat):
            t = time.perf_counter()
            subprocess.run([sys.executable, "-c", "pass"], check=True)
            bare.append(time.perf_counter() - t)
            for label in trees:
                out = subprocess.run([sys.executable, "-c", code], env=envs[label], capture_output=True, text=True,
                                     cwd=folder)
                if out.returncode != 0:
                    raise RuntimeError(out.stderr[-2000:])
                runs[label].append([float(x) for x in out.stdout.split()[-4:]])
    interpreter = statistics.median(bare)
    print(f"\n## A cached start, alternating two checkouts (Cornell box, median of {repeat} CPU s, load average "
          f"{os.getloadavg()[0]:.1f}; python -c pass: {interpreter:.2f} s wall)")
    print("| code | imports | load_scene | bind | first render | until the first launch |")
    print("|---|---|---|---|---|---|")
    for label, rows in runs.items():
        med = [statistics.median(col) for col in zip(*rows)]
        print(f"| {label} | " + " | ".join(f"{x:.3f}" for x in med) +
              f" | {interpreter + sum(med[:3]):.3f} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="128x128, 4 spp")
    ap.add_argument("--speed-only", action="store_true", help="only the speed and scaling table")
    ap.add_argument("--start-only", action="store_true",
                    help="only the cold and cached start-up times (fresh processes, temporary kernel caches)")
    ap.add_argument("--start-parts", action="store_true",
                    help="only where a cached start's CPU time goes, part by part (fresh processes)")
    ap.add_argument("--repeat", type=int, default=3, help="--start-only, --start-parts: runs (default 3)")
    ap.add_argument("--cached-against", metavar="DIR",
                    help="only a cached start, alternating the warp_spt under DIR (e.g. a git archive of the code "
                         "before a change) and this checkout's, --repeat times")
    args = ap.parse_args()
    if args.cached_against:
        cached_against(args.cached_against, args.repeat)
        return
    if args.start_only:
        start_times(args.repeat)
        return
    if args.start_parts:
        start_parts(args.repeat)
        return
    size, spp = (128, 4) if args.quick else (512, 16)
    if not args.speed_only:
        compile_times()
    all_scenes = scenes()
    speed_table(all_scenes, size, spp)
    for name, sc in all_scenes.items() if not args.speed_only else ():
        specialisation_table(name, sc, size // 2, spp)


if __name__ == "__main__":
    main()
