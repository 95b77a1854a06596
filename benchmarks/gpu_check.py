"""GPU check: the GPU tests, then the main renders on ``cuda`` and on ``cpu`` side by side, one table.

    python benchmarks/gpu_check.py             # 512x512, 16 spp (about 5 minutes on 16 cores + an H100, cold caches)
    python benchmarks/gpu_check.py --quick     # 128x128, 4 spp, the tests too: a smoke run
    python benchmarks/gpu_check.py --no-tests  # the tables alone
    python benchmarks/gpu_check.py --device cpu --quick --no-tests   # a rehearsal without a GPU

Where Warp finds no CUDA device it prints why and exits with status 0 (nothing to check). Nothing is
fetched from the network; Warp's kernel cache may start empty: every kernel the run needs is first
compiled and loaded from a thread pool (one thread per core: CUDA's NVRTC and the CPU's Clang
compiles run outside Warp's code-generation lock), so the timings below never include a compile.

Steps, each printed with its time:

1. The machine: GPU (name, architecture, memory; ``nvidia-smi``'s driver), CPU model and cores,
   Python, Warp and numpy versions, the kernel cache's folder.
2. The kernel cache warmed (the tests' and the table's kernels, CUDA and CPU).
3. ``tests/gpu/test_device_render.py`` with ``WARP_SPT_TEST_DEVICE=cuda`` (every integrator x sampler on the GPU,
   ``guided``/``ears`` deterministic there, GPU and CPU images statistically equal, the
   progressive and albedo/normal passes, ``--device cuda`` on the command line): pytest's summary
   and, on failure, its last lines; the exit status is pytest's.
4. The table: ``bench_vs_mitsuba``'s Cornell box and the built-in demo (its default camera, the
   gradient sky), ``nee`` + ``sobol``, depth 6, rendered on the CPU (all cores, our wide BVH), on
   CUDA with Warp's BVH (the default there) and on CUDA with our wide BVH
   (``wide_bvh_max_triangles``): render seconds (launches only, after a warm-up render; the best
   of ``--repeat``), camera samples/s, closest-hit rays/s, the speed-up over the CPU, and the GPU
   image's mean against the CPU's: the relative difference of the two images' means and its t
   statistic, the standard error estimated from the spread of the per-block differences
   (16x16-pixel blocks; the two renders use different seeds, so they are independent estimates
   of the same image and the differences' spread is their noise). |t| above 4 is flagged.
5. Against Mitsuba on the same GPU: ``bench_vs_mitsuba``'s Cornell box and indirectly lit room at
   256x256 and the table's spp, ours (``nee`` + ``sobol``) beside Mitsuba 3's ``cuda_ad_rgb`` ``path``
   with each of its samplers (the best kept), against a Mitsuba reference of 8192 spp: wall seconds
   of a whole render to host memory (after a warm-up render, so neither side's compile counts),
   RMSE, and the equal-error efficiency ratio 1 / (MSE x seconds). Where Mitsuba cannot run (not
   installed, no such variant, its backend does not start) it prints why and goes on. A GPU
   machine without network access gets Mitsuba, drjit and Warp as wheels: ``benchmarks/gpu_carry.py``
   prepares them here and prints the commands. ``--device cpu`` compares with ``llvm_ad_rgb``.
"""

from __future__ import annotations

import argparse
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from unittest import mock

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

import numpy as np  # noqa: E402

TEST_FILES = ("tests/gpu/test_device_render.py", "tests/gpu/test_device_kinds.py")
BLOCK = 16            # pixels per side of the blocks whose differences estimate the noise
FLAG_T = 4.0


def say(text: str = "") -> None:
    print(text, flush=True)


def machine() -> None:
    import warp as wp

    say("## Machine")
    cpu = platform.processor() or "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    say(f"CPU: {cpu}, {os.cpu_count()} logical cores; Python {platform.python_version()}, Warp {wp.__version__}, "
        f"numpy {np.__version__}; kernel cache {wp.config.kernel_cache_dir}")
    for d in wp.get_cuda_devices():
        say(f"GPU {d.alias}: {d.name}, sm_{d.arch}, {d.total_memory / 2**30:.1f} GiB")
    if shutil.which("nvidia-smi"):
        out = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version,memory.total", "--format=csv,noheader"],
                             capture_output=True, text=True)
        say(f"nvidia-smi: {out.stdout.strip() or out.stderr.strip()}")


# ---------------------------------------------------------------------------------------------
# Scenes and settings


def bench_scenes(folder: Path) -> dict:
    """name -> (host Scene, Camera, Sky) of the table's scenes."""
    import bench_vs_mitsuba as mb

    from warp_spt.demo import demo_files
    from warp_spt.io.loader import load_scene
    from warp_spt.scene.camera import Camera
    from warp_spt.scene.sky import Sky

    desc = mb.SCENES["cornell"]
    (folder / "cornell.obj").write_text(mb.obj_text(desc["shapes"]))
    (folder / "cornell.mtl").write_text(mb.mtl_text(desc["materials"]))
    quiet = dict(warn=lambda message: None)
    return {
        "cornell": (load_scene([str(folder / "cornell.obj")], [str(folder / "cornell.mtl")], **quiet),
                    mb.warp_camera(desc), Sky.constant(*desc["sky"])),
        "builtin demo": (load_scene(*demo_files(), **quiet), Camera(), Sky.gradient()),
    }


def configs(gpu: str) -> tuple:
    """(label, device, wide_bvh_max_triangles) of the table's rows: the CPU, then the GPU with its
    default (Warp's BVH) and with our wide BVH."""
    from warp_spt.upload.device_scene import WIDE_BVH_MAX_TRIANGLES

    return (("cpu", "cpu", None), (gpu, gpu, None), (f"{gpu}, wide BVH", gpu, WIDE_BVH_MAX_TRIANGLES))


def device_scene(host, device: str, wide, stand_in: bool = False):
    """``host`` on ``device``; ``stand_in``: on the CPU with the features the GPU would give it (Warp's
    BVH unless ``wide`` says otherwise), so that its kernels can be compiled to PTX without a GPU."""
    from warp_spt.upload.device_scene import DeviceScene

    if stand_in and device != "cpu":
        return DeviceScene(host, device="cpu", wide_bvh_max_triangles=0 if wide is None else wide)
    return DeviceScene(host, device=device, wide_bvh_max_triangles=wide)


# ---------------------------------------------------------------------------------------------
# Warming the kernel cache in parallel


def unloaded_kernel(dev, rs, mode: str = "fast"):
    """The kernel ``bind(dev, camera, rs, mode=mode)`` would pick, built but not loaded."""
    from warp_spt.rendering.setup import device_kernel
    from warp_spt.runtime import kernel_cache

    with mock.patch.object(kernel_cache, "load", lambda kernel, device="cpu": kernel):
        return device_kernel(dev, rs, mode)


def warm(jobs: list) -> None:
    """Compile and load the modules of ``jobs`` [(kernel, device)] from a thread pool (a load that
    fails there is retried on this thread, where the renderers load theirs). ``wp.load_module``, not
    an ahead-of-time compile: a CPU launch's block size is 1, an AOT compile's 256, so an AOT object
    is another cache entry than the one a render loads."""
    import warp as wp

    todo = list({(id(k.module), dev): (k, dev) for k, dev in jobs}.values())

    def load_one(job):
        k, dev = job
        t = time.perf_counter()
        try:
            wp.load_module(k.module, device=dev)
            return time.perf_counter() - t, None
        except Exception as err:     # retried below, on this thread
            return time.perf_counter() - t, err

    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=max(1, os.cpu_count() or 1)) as pool:
        done = list(pool.map(load_one, todo))
    t1 = time.perf_counter()
    failed = [job for job, (_, err) in zip(todo, done) if err is not None]
    for (k, dev), (_, err) in zip(todo, done):
        if err is not None:
            say(f"  loading {k.key} on {dev} in a thread failed ({type(err).__name__}: {err}); again on this thread")
            wp.load_module(k.module, device=dev)
    each = [sec for sec, _ in done]
    say(f"{len(todo)} modules compiled or loaded in {t1 - t0:.1f} s (longest {max(each, default=0):.1f} s, sum "
        f"{sum(each):.1f} s)" + (f"; {len(failed)} retried in {time.perf_counter() - t1:.1f} s" if failed else ""))


def warm_jobs(scenes: dict, size: int, spp: int, tests: bool, folder: Path, gpu: str, stand_in: bool = False,
              media: bool = True) -> list:
    """[(kernel, device)] of every kernel the run needs; ``stand_in``: the GPU's kernels built from
    CPU scenes with the GPU's features (see :func:`device_scene`), for :func:`compile_ptx`."""
    import warp_spt.rendering.aux_buffers  # noqa: F401  (registers the "aov" kind)
    from warp_spt.upload.device_scene import WIDE_BVH_MAX_TRIANGLES
    from warp_spt.integrators import INTEGRATORS
    from warp_spt.rendering.settings import RenderSettings
    from warp_spt.samplers import SAMPLERS
    from warp_spt.scene.sky import Sky

    def rs(device, **kw):
        return RenderSettings(device="cpu" if stand_in else device, **kw)

    jobs = []
    for host, camera, sky in scenes.values():
        for _, device, wide in configs(gpu):
            dev = device_scene(host, device, wide, stand_in)
            jobs.append((unloaded_kernel(dev, rs(device, width=size, height=size, spp=spp, sky=sky)), device))
    if tests:           # the kernels of tests/gpu/test_device_render.py (its Cornell box, every integrator x sampler)
        from tests.support.stability_scenes import cornell_files
        from tests.gpu.test_device_kinds import KIND_SCENES, settings

        from warp_spt.io.loader import load_scene
        host = load_scene(*cornell_files(folder), warn=lambda message: None)
        sky = Sky.constant(0.1, 0.1, 0.1)
        for device in (gpu, "cpu"):
            dev = device_scene(host, device, None, stand_in)
            for i in INTEGRATORS:
                for s in SAMPLERS:
                    if device == "cpu" and s != "sobol":
                        continue
                    jobs.append((unloaded_kernel(dev, rs(device, integrator=i, sampler=s, sky=sky)), device))
            jobs.append((unloaded_kernel(dev, rs(device, sampler="independent"), "aov"), device))
        wide = device_scene(host, gpu, WIDE_BVH_MAX_TRIANGLES, stand_in)
        jobs.append((unloaded_kernel(wide, rs(gpu, sky=sky)), gpu))
        # and of tests/gpu/test_device_kinds.py (this round's kinds: pbr, environment map, punctual lights,
        # the light tree, volpath's media), on both devices
        for k, build in enumerate(KIND_SCENES.values()):
            host, _, kw, _ = build(folder / f"kind{k}")
            if not media and (host.fog is not None or host.interiors):
                continue
            for device in (gpu, "cpu"):
                dev = device_scene(host, device, None, stand_in)
                jobs.append((unloaded_kernel(dev, settings("cpu" if stand_in else device, kw)), device))
    return jobs


def compile_ptx(jobs: list, gpu: str, arch: int) -> int:
    """Compile the GPU's kernels of ``jobs`` to PTX for ``arch`` into Warp's kernel cache, from a thread
    pool, without a GPU (Warp's bundled NVRTC). A GPU machine whose Warp picks that architecture (the
    lowest of its GPUs', PTX when its driver is at least Warp's CUDA toolkit) then loads them from the
    cache (``WARP_CACHE_PATH``) instead of compiling: NVRTC is most of a cold check's time."""
    import warp as wp

    todo = list({id(k.module): k for k, dev in jobs if dev == gpu}.values())
    say(f"compiling {len(todo)} modules to PTX for sm_{arch} into {wp.config.kernel_cache_dir}")

    def one(k):
        t = time.perf_counter()
        wp.compile_aot_module(k.module, arch=arch, use_ptx=True)
        return time.perf_counter() - t

    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=max(1, os.cpu_count() or 1)) as pool:
        each = list(pool.map(one, todo))
    say(f"{len(todo)} modules in {time.perf_counter() - t0:.1f} s (longest {max(each, default=0):.1f} s)")
    return 0


# ---------------------------------------------------------------------------------------------
# The tests


def run_tests(timeout: float, gpu: str, media: bool = True) -> int:
    env = dict(os.environ, WARP_SPT_TEST_DEVICE=gpu, PYTHONPATH=os.pathsep.join(
        [str(REPO)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p]))
    t = time.perf_counter()
    try:
        out = subprocess.run([sys.executable, "-m", "pytest", *TEST_FILES, "-q", "-rs", "-p", "no:cacheprovider",
                              *([] if media else ["-k", "not media"])],
                             cwd=REPO, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as err:
        say(f"{' '.join(TEST_FILES)}: TIMED OUT after {timeout:.0f} s")
        say((err.stdout or b"").decode("utf-8", "replace")[-3000:] if isinstance(err.stdout, bytes) else
            (err.stdout or "")[-3000:])
        return 124
    lines = (out.stdout + out.stderr).strip().splitlines()
    say(f"{' '.join(TEST_FILES)} (WARP_SPT_TEST_DEVICE={gpu}), {time.perf_counter() - t:.1f} s, exit status {out.returncode}:")
    say("\n".join(lines[-60:] if out.returncode else lines[-8:]))
    return out.returncode


# ---------------------------------------------------------------------------------------------
# The table


def block_t(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """(relative difference of the means of images a and b, its t statistic from the spread of the
    per-block mean differences)."""
    h, w = (a.shape[0] // BLOCK) * BLOCK, (a.shape[1] // BLOCK) * BLOCK
    da = a[:h, :w].reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK, 3).mean(axis=(1, 3))
    db = b[:h, :w].reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK, 3).mean(axis=(1, 3))
    d = (da - db).mean(axis=2).ravel()
    mean = float(b.mean())
    se = float(d.std(ddof=1) / np.sqrt(d.size))
    return float(d.mean()) / mean, (float(d.mean()) / se if se > 0 else (0.0 if d.mean() == 0 else np.inf))


def table(scenes: dict, size: int, spp: int, repeat: int, gpu: str) -> None:
    from warp_spt.rendering.settings import RenderSettings
    from warp_spt.rendering.tiles import render_scene

    say(f"## {gpu} beside cpu: {size}x{size}, {spp} spp, nee + sobol, depth 6 (render seconds: launches only, "
        f"best of {repeat})")
    say("| scene | device | triangles | render s | M samples/s | M rays/s | speed-up over cpu | "
        "mean vs cpu | t | agree |")
    say("|---|---|---|---|---|---|---|---|---|---|")
    for name, (host, camera, sky) in scenes.items():
        cpu_image, cpu_seconds = None, None
        for label, device, wide in configs(gpu):
            dev = device_scene(host, device, wide)
            seed = 0 if cpu_image is None else 1      # independent estimates of the same image

            def rs(n: int, seed=seed, device=device) -> RenderSettings:
                return RenderSettings(width=size, height=size, spp=n, sky=sky, seed=seed, device=device)

            render_scene(dev, camera, rs(1))          # warm-up: load, first launch
            best = None
            for _ in range(repeat):
                res = render_scene(dev, camera, rs(spp))
                if best is None or res.stats.render_seconds < best.stats.render_seconds:
                    best = res
            sec = best.stats.render_seconds
            image = best.image.astype(np.float64)
            if cpu_image is None:
                cpu_image, cpu_seconds = image, sec
                cells = ["1.00x", "", "", ""]
            else:
                rel, t = block_t(image, cpu_image)
                cells = [f"{cpu_seconds / sec:.1f}x", f"{rel:+.3%}", f"{t:+.2f}",
                         "yes" if abs(t) <= FLAG_T else "NO"]
            say(f"| {name} | {label} | {host.num_triangles:,} | {sec:.3f} | {size * size * spp / sec / 1e6:.2f} | "
                f"{best.stats.rays / sec / 1e6:.1f} | " + " | ".join(cells) + " |")
            if best.stats.dropped_samples:
                say(f"  ({best.stats.dropped_samples} non-finite samples dropped)")


# ---------------------------------------------------------------------------------------------
# Against Mitsuba on the same device


MITSUBA_SCENES = ("cornell", "indirect")


def mitsuba_on(variant: str):
    """(Mitsuba set to ``variant``, None) or (None, why not). A one-sample probe render runs in a
    subprocess first: drjit aborts the process where its backend cannot start (no CUDA driver or
    OptiX for ``cuda_ad_rgb``, too old a libLLVM for ``llvm_ad_rgb``)."""
    try:
        import mitsuba as mi
    except ImportError as err:
        return None, (f"Mitsuba is not installed here ({err}); benchmarks/gpu_carry.py prepares its wheels "
                      f"for a machine without network access")
    if variant not in mi.variants():
        return None, f"Mitsuba {mi.__version__} has no variant {variant} (it has {', '.join(mi.variants())})"
    probe = (f"import mitsuba as mi; mi.set_variant({variant!r}); "
             f"mi.render(mi.load_dict(mi.cornell_box()), spp=1)")
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True)
    if out.returncode != 0:
        lines = out.stderr.strip().splitlines() or [f"exit status {out.returncode}"]
        first = next((ln for ln in lines if "error" in ln.lower()), lines[-1])     # LLVM's is its first line
        return None, f"Mitsuba {mi.__version__}'s {variant} cannot render here: {first.strip()[:200]}"
    mi.set_variant(variant)
    mi.set_log_level(mi.LogLevel.Error)       # its samplers' rounding notes would interleave with the table
    return mi, None


def best_seconds(render, repeat: int):
    """(image, least wall seconds) over ``repeat`` runs of ``render()`` after one warm-up run (kernel
    compiles, Mitsuba's JIT, first launches). The same seed each time, so that a JIT that bakes the
    seed into its kernel compiles it once; the image is the last run's."""
    render()
    best, image = float("inf"), None
    for _ in range(repeat):
        t = time.perf_counter()
        image = render()
        best = min(best, time.perf_counter() - t)
    return image, best


def vs_mitsuba(folder: Path, size: int, spp: int, ref_spp: int, repeat: int, gpu: str, variant: str) -> None:
    """bench_vs_mitsuba's Cornell box and indirectly lit room on ``gpu``, ours (``nee`` + ``sobol``)
    beside Mitsuba's ``path`` (``variant``, every sampler of bench_vs_mitsuba, the best one kept) at the
    same samples per pixel: wall seconds of a whole ``render`` call to an image in host memory (best of
    ``repeat``), RMSE against a Mitsuba reference (``ref_spp``, two independent halves whose spread
    gives its own error, subtracted) and the equal-error efficiency 1 / (MSE x seconds), as a ratio."""
    import bench_vs_mitsuba as mb

    from warp_spt.rendering.settings import RenderSettings
    from warp_spt.rendering.tiles import render_scene

    half = 1
    while half * 4 <= ref_spp // 2:          # Mitsuba's ldsampler takes powers of 4
        half *= 4
    say(f"## {gpu} against Mitsuba {variant}: {size}x{size}, {spp} spp, depth {mb.DEPTH}; wall seconds of a "
        f"whole render to host memory, best of {repeat}; reference: Mitsuba, 2 x {half} spp (ldsampler)")
    mi, why = mitsuba_on(variant)
    if mi is None:
        say(f"not run: {why}")
        return
    mb.mi = mi
    threads = os.cpu_count() or 1        # Mitsuba's LLVM variant only; the GPU ignores it
    say(f"Mitsuba {mi.__version__}, variant {variant}")
    say("| scene | Mitsuba's best sampler | Mitsuba s | Mitsuba RMSE | warp_spt s | warp_spt RMSE | "
        "efficiency warp_spt / Mitsuba |")
    say("|---|---|---|---|---|---|---|")
    for name in MITSUBA_SCENES:
        desc = mb.SCENES[name]
        sub = folder / f"vs_mitsuba_{name}"
        sub.mkdir()
        ref_scene = mb.mitsuba_scene(desc, sub, size, "ldsampler", half)
        ref_a, ref_b = (mb.mitsuba_render(ref_scene, half, seed, threads) for seed in (1, 2))
        ref, ref_mse = 0.5 * (ref_a + ref_b), float(np.mean((ref_a - ref_b) ** 2)) / 4
        theirs = {}
        for sampler in mb.MITSUBA_SAMPLERS:
            n = mb.sampler_spp(sampler, spp)
            scene = mb.mitsuba_scene(desc, sub, size, sampler, n)
            img, sec = best_seconds(lambda scene=scene, n=n: mb.mitsuba_render(scene, n, 7, threads), repeat)
            theirs[sampler] = (mb.efficiency(img, sec, ref, ref_mse), sec, img)
        best = max(theirs, key=lambda k: theirs[k][0])
        dev = mb.warp_scene(desc, sub, device=gpu)
        rs = RenderSettings(**mb.warp_settings(desc, size, spp, "nee", "sobol", 7, threads), device=gpu)
        img, sec = best_seconds(lambda: render_scene(dev, mb.warp_camera(desc), rs).image.astype(np.float64), repeat)
        ours = mb.efficiency(img, sec, ref, ref_mse)

        def rmse(image):
            return max(float(np.mean((image - ref) ** 2)) - ref_mse, 0.0) ** 0.5

        say(f"| {name} | {best} ({mb.sampler_spp(best, spp)} spp) | {theirs[best][1]:.4f} | "
            f"{rmse(theirs[best][2]):.4f} | {sec:.4f} | {rmse(img):.4f} | {ours / theirs[best][0]:.2f} |")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="128x128, 4 spp")
    ap.add_argument("--size", type=int, default=None)
    ap.add_argument("--spp", type=int, default=None)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--no-tests", action="store_true")
    ap.add_argument("--test-timeout", type=float, default=300.0)
    ap.add_argument("--device", default="cuda", help="the GPU (cuda:N); 'cpu' rehearses the script where there "
                    "is no GPU")
    ap.add_argument("--no-media", action="store_true",
                    help="leave out the scenes with participating media: their CUDA kernels take many minutes of "
                         "NVRTC each (compile them ahead with --compile-ptx)")
    ap.add_argument("--compile-ptx", type=int, metavar="ARCH", default=None,
                    help="on any machine (no GPU needed): compile the check's CUDA kernels to PTX for sm_ARCH "
                         "(90 for an H100/H200) into Warp's kernel cache, then stop; carry the cache to the "
                         "GPU machine (WARP_CACHE_PATH) so that its run skips NVRTC")
    ap.add_argument("--no-mitsuba", action="store_true", help="leave out the comparison with Mitsuba")
    ap.add_argument("--mitsuba-variant", default=None,
                    help="Mitsuba's variant for the comparison (default cuda_ad_rgb; llvm_ad_rgb with --device cpu)")
    ap.add_argument("--mitsuba-size", type=int, default=None, help="the comparison's image size (default 256; "
                    "--quick: 64)")
    ap.add_argument("--mitsuba-ref-spp", type=int, default=None,
                    help="samples per pixel of the comparison's Mitsuba reference, two halves of a power of 4 each "
                         "(default 8192; --quick: 512)")
    args = ap.parse_args()
    size = args.size or (128 if args.quick else 512)
    spp = args.spp or (4 if args.quick else 16)

    from warp_spt.runtime.warp_init import check_device, init_warp

    init_warp()
    if args.compile_ptx is not None:
        with tempfile.TemporaryDirectory() as tmp:
            folder = Path(tmp)
            return compile_ptx(warm_jobs(bench_scenes(folder), size, spp, not args.no_tests, folder, args.device,
                                         stand_in=True, media=not args.no_media), args.device, args.compile_ptx)
    try:
        check_device(args.device)
    except ValueError as err:
        say(f"gpu_check: skipped: {err}")
        return 0
    t0 = time.perf_counter()
    machine()
    status = 0
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        scenes = bench_scenes(folder)
        say("\n## Kernel cache")
        warm(warm_jobs(scenes, size, spp, not args.no_tests, folder, args.device, media=not args.no_media))
        if not args.no_tests:
            say("\n## Tests")
            status = run_tests(args.test_timeout, args.device, media=not args.no_media)
        say("")
        table(scenes, size, spp, args.repeat, args.device)
        if not args.no_mitsuba:
            say("")
            variant = args.mitsuba_variant or ("llvm_ad_rgb" if args.device == "cpu" else "cuda_ad_rgb")
            vs_mitsuba(folder, args.mitsuba_size or (64 if args.quick else 256), spp,
                       args.mitsuba_ref_spp or (512 if args.quick else 8192), args.repeat, args.device, variant)
    say(f"\ngpu_check: {time.perf_counter() - t0:.0f} s in all")
    return status


if __name__ == "__main__":
    sys.exit(main())
