"""Issue 33, the plan's first step measured: do a vertex's Sobol' requests fill the vector lanes when
computed as one batch?

The renderer's Sobol' sampler (``samplers/sobol.py``) answers one 2-D request at a time
(``sobol_2d_keyed``: about 15 integer hashes). A path vertex makes several requests whose inputs
(pixel key, sample index, dimension) are all known at once; computed as the lanes of one batch, the
same integer operations run on 8 (or 16) requests side by side, which clang may map onto AVX2 /
AVX-512 integer instructions. This script times, per Warp thread (one pixel), ``--samples``
samples of ``--requests`` 2-D requests each:

    scalar      ``sobol_2d_keyed`` called once per request, as the integrators do
    lanes N     one batch of N requests: the same functions (mix32, shuffled_index, owen_scramble,
                reverse_bits, sobol_dim1), their results written lane by lane into local vectors
    lanes N mem the same, the batch's inputs and outputs in a per-thread scratch row (memory-backed
                lanes: the form clang vectorised in bench_packets.py)

Every variant must give the same bits as the scalar one (checked on every value). Times: the
launching thread's CPU time of one single-threaded launch, variants interleaved, median of
``--repeat``. ``--asm`` counts the packed integer instructions (vpmulld, vpxor, vpsrlvd...) on
zmm / ymm / xmm registers in each kernel's object file.

    python benchmarks/bench_sampler_lanes.py                      # 128x128 pixels, 16 samples, 8 requests
    python benchmarks/bench_sampler_lanes.py --requests 16 --asm
"""

import argparse
import os
import re
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))

import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING

from warp_spt.samplers.sobol import POINTS, _X_SALT, _Y_SALT, owen_scramble, shuffled_index  # noqa: E402
from warp_spt.samplers.sobol_points import _DIM_MUL, mix32, pixel_key, reverse_bits, sobol_dim1, to_unit  # noqa: E402

sobol_2d_keyed = POINTS.two_keyed

OPTIONS = {"cpu_compiler_flags": "-march=native -mllvm=-inline-threshold=2000 -mllvm=-slp-recursion-max-depth=4"}


def kernels(requests: int, lanes: int, options: dict) -> dict:
    """The three kernels for ``requests`` 2-D requests per sample, batched ``lanes`` at a time."""
    if requests % lanes:
        raise SystemExit(f"--requests must be a multiple of {lanes}")
    batches = requests // lanes
    vf = wp.types.vector(length=lanes, dtype=wp.float32)
    vu = wp.types.vector(length=lanes, dtype=wp.uint32)

    @wp.kernel(enable_backward=False, module="unique", module_options=options)
    def scalar(seed: wp.uint32, samples: int, offs: wp.array(dtype=int), out: wp.array(dtype=wp.float32)):
        pix = wp.tid()
        pkey = pixel_key(seed, pix)
        acc = float(0.0)
        for s in range(samples):
            d0 = offs[s]
            for r in range(wp.static(requests)):
                v = sobol_2d_keyed(pkey, s, d0 + 2 * r)
                acc += v[0] + v[1]
        out[pix] = acc

    @wp.kernel(enable_backward=False, module="unique", module_options=options)
    def scalar_inlined(seed: wp.uint32, samples: int, offs: wp.array(dtype=int), out: wp.array(dtype=wp.float32)):
        pix = wp.tid()
        pkey = pixel_key(seed, pix)
        acc = float(0.0)
        for s in range(samples):
            d0 = offs[s]
            for r in range(offs.shape[0] * 0 + wp.static(requests)):     # a loop clang sees as dynamic
                key = mix32(pkey ^ (wp.uint32(d0 + 2 * r) * _DIM_MUL))
                i = shuffled_index(key, s)
                acc += to_unit(owen_scramble(reverse_bits(i), mix32(key ^ _X_SALT))) + \
                    to_unit(owen_scramble(sobol_dim1(i), mix32(key ^ _Y_SALT)))
        out[pix] = acc

    @wp.func
    def batch(pkey: wp.uint32, index: int, first_dim: int):
        """Requests first_dim, first_dim + 2, ... (lanes of them) of sample ``index``: (xs, ys)."""
        xs = vf()
        ys = vf()
        for j in range(wp.static(lanes)):
            key = mix32(pkey ^ (wp.uint32(first_dim + 2 * j) * _DIM_MUL))
            i = shuffled_index(key, index)
            xs[j] = to_unit(owen_scramble(reverse_bits(i), mix32(key ^ _X_SALT)))
            ys[j] = to_unit(owen_scramble(sobol_dim1(i), mix32(key ^ _Y_SALT)))
        return xs, ys

    @wp.kernel(enable_backward=False, module="unique", module_options=options)
    def lanes_local(seed: wp.uint32, samples: int, offs: wp.array(dtype=int), out: wp.array(dtype=wp.float32)):
        pix = wp.tid()
        pkey = pixel_key(seed, pix)
        acc = float(0.0)
        for s in range(samples):
            d0 = offs[s]
            for b in range(wp.static(batches)):
                xs, ys = batch(pkey, s, d0 + 2 * lanes * b)
                for j in range(wp.static(lanes)):
                    acc += xs[j] + ys[j]
        out[pix] = acc

    @wp.func
    def mix32_lanes(x: vu) -> vu:
        out = vu()
        for j in range(wp.static(lanes)):
            out[j] = mix32(x[j])
        return out

    @wp.kernel(enable_backward=False, module="unique", module_options=options)
    def lanes_mem(seed: wp.uint32, samples: int, offs: wp.array(dtype=int), scratch: wp.array2d(dtype=vu),
                  out: wp.array(dtype=wp.float32)):
        pix = wp.tid()
        pkey = pixel_key(seed, pix)
        acc = float(0.0)
        for s in range(samples):
            d0 = offs[s]
            for b in range(wp.static(batches)):
                # the batch's keys in memory, then each stage over the whole row
                keys = vu()
                for j in range(wp.static(lanes)):
                    keys[j] = pkey ^ (wp.uint32(d0 + 2 * lanes * b + 2 * j) * _DIM_MUL)
                scratch[pix, 0] = mix32_lanes(keys)
                row = scratch[pix, 0]
                idx = vu()
                for j in range(wp.static(lanes)):
                    idx[j] = shuffled_index(row[j], s)
                scratch[pix, 1] = idx
                sx = vu()
                sy = vu()
                for j in range(wp.static(lanes)):
                    sx[j] = row[j] ^ _X_SALT
                    sy[j] = row[j] ^ _Y_SALT
                scratch[pix, 2] = mix32_lanes(sx)
                scratch[pix, 3] = mix32_lanes(sy)
                ii = scratch[pix, 1]
                kx = scratch[pix, 2]
                ky = scratch[pix, 3]
                for j in range(wp.static(lanes)):
                    acc += to_unit(owen_scramble(reverse_bits(ii[j]), kx[j])) + \
                        to_unit(owen_scramble(sobol_dim1(ii[j]), ky[j]))
        out[pix] = acc

    return {"scalar": scalar, "scalar, inlined": scalar_inlined, f"lanes {lanes}": lanes_local,
            f"lanes {lanes} mem": lanes_mem}


def report_asm(ks: dict) -> None:
    cache = wp.config.kernel_cache_dir
    packed = re.compile(r"\svp(mulld|xor|xord|srlvd|sllvd|srld|slld|and|andd|or|ord|ternlogd|add|addd)\s")
    print("\n| kernel | instructions | packed integer ops on zmm | on ymm | on xmm |")
    print("|---|---|---|---|---|")
    for label, k in ks.items():
        objs = sorted(Path(cache).glob(f"wp_{k.module.name}_*/*.o"), key=os.path.getmtime)[-1:]
        if not objs:
            continue
        try:
            text = subprocess.run(["objdump", "-d", "--no-show-raw-insn", str(objs[0])], check=False,
                                  capture_output=True, text=True).stdout.splitlines()
        except FileNotFoundError:
            print("objdump not found: no disassembly")
            return
        ops = [ln for ln in text if packed.search(ln)]
        print(f"| {label} | {len(text)} | {sum('zmm' in ln for ln in ops)} | "
              f"{sum('ymm' in ln and 'zmm' not in ln for ln in ops)} | "
              f"{sum('xmm' in ln and 'ymm' not in ln and 'zmm' not in ln for ln in ops)} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--size", type=int, default=128, help="pixels per side (one thread each)")
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--requests", type=int, default=8, help="2-D requests per sample")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--flags", default=OPTIONS["cpu_compiler_flags"], help="clang flags (default: the path kernel's)")
    ap.add_argument("--asm", action="store_true")
    args = ap.parse_args()
    wp.init()
    from bench_packets import cpu_name
    n = args.size * args.size
    ks = {}
    for lanes in sorted({min(8, args.requests), min(16, args.requests)}):
        if args.requests % lanes == 0:
            ks.update(kernels(args.requests, lanes, {"cpu_compiler_flags": args.flags}))
    for k in ks.values():
        wp.load_module(k.module, device="cpu")
    outs = {label: wp.zeros(n, dtype=wp.float32) for label in ks}
    scratch = {label: wp.zeros((n, 4), dtype=wp.types.vector(length=int(label.split()[1]), dtype=wp.uint32))
               for label in ks if label.endswith("mem")}
    seed = wp.uint32(7)
    # a zero dimension offset per sample, read from memory: it keeps clang from hoisting the (pixel,
    # dimension) hashes out of the sample loop, which a path kernel's vertex cannot do either
    offs = wp.zeros(args.samples, dtype=int)

    def run(label):
        k = ks[label]
        if label in scratch:
            wp.launch(k, dim=n, inputs=[seed, args.samples, offs, scratch[label], outs[label]])
        else:
            wp.launch(k, dim=n, inputs=[seed, args.samples, offs, outs[label]])

    for label in ks:
        run(label)
    ref = outs["scalar"].numpy()
    same = {label: np.array_equal(outs[label].numpy().view(np.uint32), ref.view(np.uint32)) for label in ks}
    times = {label: [] for label in ks}
    for _ in range(args.repeat):
        for label in ks:
            t = time.thread_time()
            run(label)
            times[label].append(time.thread_time() - t)
    requests = n * args.samples * args.requests
    print(f"CPU: {cpu_name()}; {args.size}x{args.size} threads, {args.samples} samples x {args.requests} 2-D "
          f"requests each; one thread, median of {args.repeat}; flags: {args.flags}")
    print("| variant | CPU s | M requests/s | over scalar | bits |")
    print("|---|---|---|---|---|")
    base = statistics.median(times["scalar"])
    for label, ts in times.items():
        med = statistics.median(ts)
        print(f"| {label} | {med:.4f} | {requests / med / 1e6:.1f} | {base / med:.2f} | "
              f"{'identical' if same[label] else 'DIFFER'} |")
    if args.asm:
        report_asm(ks)


if __name__ == "__main__":
    main()
