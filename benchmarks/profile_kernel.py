"""Where the path kernel's CPU time goes, by perf samples mapped onto the kernel's cached object.

    python benchmarks/profile_kernel.py                       # bench_vs_mitsuba's Cornell box, nee + sobol
    python benchmarks/profile_kernel.py --scene indirect --bins

``perf record -e cpu-clock`` cannot name JIT code. Warp hands out the kernel's entry point (its
``cpu_forward`` function) and the kernel cache keeps the object file it loaded, so the entry point
minus that function's offset in the object (``nm -S``) is where the object's code was loaded; every
sample is then placed in a function of the object, or in a shared library that perf names itself
(libm, Warp's runtime). ``--bins`` also splits the large kernel function into 512-byte bins, each
labelled by the float constants its instructions load (``objdump -dr``): 1e-20 is ``mesh_ray``,
5e-7 ``offset_eps``, 6.22 the triangle light's solid-angle threshold, and so on.

The process renders the scene ``--renders`` times on one thread (128x128, 8 spp, depth 6) under
``perf record``; it needs ``perf`` and ``objdump`` (Linux). Figures: docs/performance.md, "Cheaper
vertices, same bits".
"""

from __future__ import annotations

import argparse
import collections
import ctypes
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent


def child(scene: str, renders: int, size: int, spp: int) -> None:
    """Render under perf; print the object file and the entry point's address."""
    sys.path.insert(0, str(HERE))
    import warp as wp
    wp.config.quiet = True
    import bench_vs_mitsuba as mb
    import warp_spt.rendering.tiles as R
    from warp_spt.rendering.setup import bind
    from warp_spt.scene.sky import Sky
    wp.init()
    desc = mb.SCENES[scene]
    folder = Path(tempfile.mkdtemp())
    dev, cam = mb.warp_scene(desc, folder), mb.warp_camera(desc)
    settings = R.RenderSettings(width=size, height=size, spp=spp, max_depth=6, sky=Sky.constant(*desc["sky"]),
                                seed=1, threads=1, integrator="nee", sampler="sobol")
    R.render_scene(dev, cam, settings)
    kernel = bind(dev, cam, settings).kernel
    (exec_,) = kernel.module.execs.values()
    forward = exec_.get_kernel_hooks(kernel).forward
    address = forward if isinstance(forward, int) else ctypes.cast(forward, ctypes.c_void_p).value
    digest = exec_.module_hash.hex() if isinstance(exec_.module_hash, bytes) else str(exec_.module_hash)
    folder = Path(wp.config.kernel_cache_dir) / f"wp_{kernel.module.name}_{digest[:7]}"
    print(f"OBJECT {next(folder.glob('*.o'))}")
    print(f"FORWARD {address:#x}", flush=True)
    for _ in range(renders):
        R.render_scene(dev, cam, settings)


def symbols(obj: str) -> list[tuple[int, int, str]]:
    out = []
    for line in subprocess.check_output(["nm", "-S", obj], text=True).splitlines():
        p = line.split()
        if len(p) == 4:
            out.append((int(p[0], 16), int(p[1], 16), p[3]))
    return out


def constants(obj: str) -> list[float]:
    """The object's .rodata.cst4 section as float32 values."""
    raw = b""
    for line in subprocess.check_output(["objdump", "-s", "-j", ".rodata.cst4", obj], text=True).splitlines():
        m = re.match(r"\s*[0-9a-f]{4,} ((?:[0-9a-f]{8} ?){1,4})", line)
        if m:
            raw += bytes.fromhex(m.group(1).replace(" ", ""))
    return [struct.unpack("<f", raw[i:i + 4])[0] for i in range(0, len(raw) - 3, 4)]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="cornell", help="a scene of bench_vs_mitsuba.py (default cornell)")
    ap.add_argument("--renders", type=int, default=20)
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--bins", action="store_true", help="also the kernel function's 512-byte bins")
    ap.add_argument("--child", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        child(args.scene, args.renders, args.size, args.spp)
        return 0
    for tool in ("perf", "objdump", "nm"):
        if shutil.which(tool) is None:
            print(f"profile_kernel: needs {tool} on PATH")
            return 1
    with tempfile.TemporaryDirectory() as tmp:
        data = f"{tmp}/perf.data"
        run = subprocess.run(["perf", "record", "-q", "-e", "cpu-clock", "-F", "5000", "-o", data, sys.executable,
                              __file__, "--child", "--scene", args.scene, "--renders", str(args.renders),
                              "--size", str(args.size), "--spp", str(args.spp)],
                             capture_output=True, text=True)
        if run.returncode != 0:
            print(f"profile_kernel: perf record failed: {run.stderr.strip().splitlines()[-1:]}")
            return 1
        obj = re.search(r"OBJECT (\S+)", run.stdout).group(1)
        forward = int(re.search(r"FORWARD (0x[0-9a-f]+)", run.stdout).group(1), 16)
        ips = subprocess.check_output(["perf", "script", "-i", data, "-F", "ip,sym,dso"], text=True,
                                      stderr=subprocess.DEVNULL)
    syms = symbols(obj)
    (entry,) = [a for a, _, n in syms if n.endswith("_cpu_forward")]
    base = forward - entry
    kernel = max((s for s in syms if "kernel_forward" in s[2]), key=lambda s: s[1])
    shares, bins = collections.Counter(), collections.Counter()
    for line in ips.splitlines():
        parts = line.split(None, 1)
        if len(parts) < 2:
            continue
        off = int(parts[0], 16) - base
        owner = next((n for a, s, n in syms if a <= off < a + s), None)
        if owner is not None:
            shares["kernel object: " + ("the kernel function" if owner == kernel[2] else owner)] += 1
            if owner == kernel[2]:
                bins[(off - kernel[0]) // 512] += 1
        elif "libm" in parts[1]:
            shares["libm: " + parts[1].split()[0]] += 1
        elif "warp" in parts[1] and "site-packages" in parts[1]:
            shares["Warp's runtime libraries"] += 1
    total = sum(shares.values())
    print(f"# {args.scene}, nee + sobol, {args.size}x{args.size}, {args.spp} spp, {args.renders} renders on one "
          f"thread, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}; {total} samples in the kernel's "
          "code and the libraries it calls")
    print("| where | share |\n|---|---|")
    for name, n in shares.most_common():
        if n / total >= 0.001:
            print(f"| {name} | {100 * n / total:.1f}% |")
    if args.bins:
        values = constants(obj)
        labels = collections.defaultdict(list)
        for line in subprocess.check_output(["objdump", "-dr", "--no-show-raw-insn", obj], text=True).splitlines():
            m = re.match(r"\s*([0-9a-f]+): R_X86_64_\w+\s+(\S+)", line)
            if not m or not kernel[0] <= int(m.group(1), 16) < kernel[0] + kernel[1]:
                continue
            target = m.group(2)
            c = re.match(r"\.rodata\.cst4(?:\+0x([0-9a-f]+))?$", target)
            if c:
                k = int(c.group(1) or "0", 16) // 4
                target = f"{values[k]:.7g}" if k < len(values) else target
            elif target.startswith((".rodata", "_GLOBAL_OFFSET_TABLE_", ".ltext", ".lbss")):
                continue
            labels[(int(m.group(1), 16) - kernel[0]) // 512].append(target)
        print("\n| bin (offset in the kernel function) | share of the kernel function | constants and calls there |")
        print("|---|---|---|")
        in_kernel = sum(bins.values())
        for b in sorted(set(bins) | set(labels)):
            print(f"| {b * 512:#06x} | {100 * bins[b] / in_kernel:.1f}% | {' '.join(dict.fromkeys(labels[b]))} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
