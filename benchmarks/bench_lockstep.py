"""Issue 45, section 1: W paths per thread in lockstep (``benchmarks/lockstep_prototype.py``) against
today's fast kernel (``nee``, one path per thread), on bench_vs_mitsuba's Cornell box and indirect room.

One run, the variants interleaved: each repeat launches every kernel once over the whole image
(one thread, ``wp.launch`` on the CPU, timed by the launching thread's CPU time), so both see the
same load; medians and [min-max] of ``--repeat``, and the load average before and after. Then
each film's RMSE against a reference rendered by today's kernel at ``--ref-spp`` with another seed,
and whether the lockstep film is bit-identical to today's (same random numbers per (pixel, sample,
dimension), same sums in the same order). ``--asm`` counts the packed float instructions (ps on
zmm / ymm / xmm and scalar ss) in each kernel's object file, as bench_packets.py does.

    PYTHONPATH=. python benchmarks/bench_lockstep.py                     # 128x128, 16 spp, W = 8
    PYTHONPATH=. python benchmarks/bench_lockstep.py --lanes 8 16 --asm   # docs/performance.md's table

Cold compiles are long: W=8 at inline threshold 20000 took 48 s, W=16 321 s (2-core machine, load 7).
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent))

import warp as wp  # noqa: E402

wp.config.quiet = True

DEPTH = {"cornell": 6, "indirect": 8}        # issue 45's table: Cornell at depth 6, the room at 8


def scenes(folder: Path, names: list) -> list:
    """(name, DeviceScene, Camera, Sky) of bench_vs_mitsuba's scenes."""
    import bench_vs_mitsuba as mb
    from warp_spt.scene.sky import Sky
    out = []
    for name in names:
        desc = mb.SCENES[name]
        sub = folder / name
        sub.mkdir()
        out.append((name, mb.warp_scene(desc, sub), mb.warp_camera(desc), Sky.constant(*desc["sky"])))
    return out


def object_file(kernel) -> Path | None:
    """The cached ``.o`` Warp loaded ``kernel`` from."""
    (exec_,) = kernel.module.execs.values()
    digest = exec_.module_hash.hex() if isinstance(exec_.module_hash, bytes) else str(exec_.module_hash)
    folder = Path(wp.config.kernel_cache_dir) / f"wp_{kernel.module.name}_{digest[:7]}"
    return next(folder.glob("*.o"), None)


def asm_counts(kernel) -> str:
    """Packed single-precision instructions per register width in the kernel's object file."""
    obj = object_file(kernel)
    if obj is None:
        return "no object file"
    text = subprocess.run(["objdump", "-d", "--no-show-raw-insn", str(obj)], capture_output=True, text=True).stdout
    counts = {"zmm": 0, "ymm": 0, "xmm": 0, "ss": 0}
    total = 0
    for line in text.splitlines():
        m = re.match(r"\s+[0-9a-f]+:\s+(\S+)\s*(.*)", line)
        if not m:
            continue
        total += 1
        op, args = m.groups()
        if re.search(r"ps$", op) or op.startswith("vpcmp") or op.startswith("vblendm"):
            for reg in ("zmm", "ymm", "xmm"):
                if reg in args:
                    counts[reg] += 1
                    break
        elif op.endswith("ss"):
            counts["ss"] += 1
    return f"{total} instructions; packed float: {counts['zmm']} zmm, {counts['ymm']} ymm, {counts['xmm']} xmm; scalar ss {counts['ss']}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--lanes", type=int, nargs="+", default=[8])
    ap.add_argument("--scenes", nargs="+", default=["cornell", "indirect"], choices=list(DEPTH))
    ap.add_argument("--sampler", default="sobol-affine")
    ap.add_argument("--ref-spp", type=int, default=512)
    ap.add_argument("--asm", action="store_true")
    ap.add_argument("--unstaged", action="store_true", help="also the control: lanes stepped whole, one by one")
    ap.add_argument("--no-loops", dest="loops", action="store_false",
                    help="leave out the control whose lane loops are not unrolled")
    ap.add_argument("--inline", type=int, nargs="+", default=[2000, 20000],
                    help="LLVM inline thresholds of the lockstep kernels (the fast kernel's is 2000)")
    args = ap.parse_args()

    from lockstep_prototype import make_lockstep_kernel
    from warp_spt.emitters import declare_sky, light_table
    from warp_spt.integrators import RenderParams, camera_params, nee
    from warp_spt.integrators.common import make_kernel, make_start_path
    from warp_spt.samplers import get_sampler

    wp.init()
    sampler = get_sampler(args.sampler)
    size, spp, n = args.size, args.spp, args.size * args.size
    cpu = next((ln.split(":", 1)[1].strip() for ln in open("/proc/cpuinfo") if ln.startswith("model name")), "?")
    print(f"# {cpu}, {os.cpu_count()} CPUs; nee + {args.sampler}, {size}x{size}, {spp} spp, roulette off; one "
          f"single-threaded launch per render, kernels interleaved, median [min-max] of {args.repeat}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, dev, cam, sky in scenes(Path(tmp), args.scenes):
            feats = dev.features.with_lights(declare_sky(sky))
            kernels, compile_s = {}, {}

            def build(label: str, make) -> None:
                """Compile (or load from Warp's cache: then the seconds are the load's) and keep."""
                t0 = time.perf_counter()
                kernels[label] = make()
                wp.load_module(kernels[label].module, device="cpu")
                compile_s[label] = time.perf_counter() - t0

            build("today (1 path / thread)", lambda: make_kernel(
                nee.make_path_step(feats, sampler, light_sampling=True), make_start_path(sampler)))
            last = args.inline[-1]
            for w in args.lanes:
                for th in args.inline:
                    build(f"lockstep W={w}, inline {th}", lambda: make_lockstep_kernel(feats, sampler, w,
                                                                                        inline_threshold=th))
                if args.loops:
                    build(f"lockstep W={w}, lane loops (control)", lambda: make_lockstep_kernel(
                        feats, sampler, w, unroll=False, inline_threshold=last))
                if args.unstaged:
                    build(f"lanes W={w}, unstaged (control)", lambda: make_lockstep_kernel(
                        feats, sampler, w, staged=False, inline_threshold=last))

            def params(count: int, seed: int):
                rp = RenderParams()
                rp.width, rp.pixel_start, rp.sample_start, rp.sample_count = size, 0, 0, count
                rp.max_depth, rp.roulette_depth, rp.seed = DEPTH[name], 0, wp.uint32(seed)
                return [dev.geometry, dev.materials, dev.textures(), light_table(dev, sky),
                        camera_params(cam, size, size), rp]

            def render(kernel, count: int, seed: int):
                film = wp.zeros(n, dtype=wp.vec3d)
                t = time.thread_time()
                wp.launch(kernel, dim=n, inputs=[*params(count, seed), film, wp.zeros((n, 2), dtype=wp.int64), None])
                return film.numpy() / count, time.thread_time() - t

            ref, ref_s = render(kernels["today (1 path / thread)"], args.ref_spp, 1234)
            load0 = os.getloadavg()[0]
            times = {label: [] for label in kernels}
            films = {}
            for _ in range(args.repeat):
                for label, k in kernels.items():
                    films[label], s = render(k, spp, 1)
                    times[label].append(s)
            load1 = os.getloadavg()[0]
            base = statistics.median(times["today (1 path / thread)"])
            today = films["today (1 path / thread)"]
            print(f"\n## {name} (depth {DEPTH[name]}), load average {load0:.1f} -> {load1:.1f}; reference "
                  f"{args.ref_spp} spp, seed 1234 ({ref_s:.1f} s)")
            print("| kernel | compile s | CPU s per render | M samples/s | over today | RMSE vs reference | film |")
            print("|---|---|---|---|---|---|---|")
            for label, ts in times.items():
                med = statistics.median(ts)
                rmse = float(np.sqrt(np.mean((films[label] - ref) ** 2)))
                same = "bit-identical" if np.array_equal(films[label], today) else \
                    f"differs (max {np.abs(films[label] - today).max():.2e})"
                print(f"| {label} | {compile_s[label]:.1f} | {med:.3f} [{min(ts):.3f}-{max(ts):.3f}] | "
                      f"{n * spp / med / 1e6:.3f} | {base / med:.3f}x | {rmse:.5f} | {same} |")
            if args.asm:
                for label, k in kernels.items():
                    print(f"- {label}: {asm_counts(k)}")


if __name__ == "__main__":
    main()
