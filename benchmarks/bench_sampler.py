"""Independent (PCG) sampling against the Owen-scrambled Sobol' sampler on analytic integrands.

    python benchmarks/bench_sampler.py            # 2048 estimates per N, N = 1 .. 4096 (~1 minute)
    python benchmarks/bench_sampler.py --quick    # 512 estimates, N up to 1024

Each "pixel" is one independent estimate of the integral from N samples (index 0..N-1 of its own
sequence, as a renderer's pixel would draw them); the RMSE over pixels against the analytic value is
the estimator's error. Sobol' draws dimension pairs (0,1), (2,3), ... with the sampler's ``POINTS.two``; the
independent sampler draws each dimension with wp.randf from stream_state(seed, pixel, sample), as the renderer
does today. Slopes are least-squares fits of log RMSE against log N over N >= 4 (independent
sampling: -0.5; scrambled nets: -1.5 for smooth 2D integrands, about -0.75 for a 2D discontinuity),
at powers of two; a second table shows the gain at N = 3 * 2**k, between powers of two.
The timing kernel only draws the numbers and sums them (single-threaded CPU launch; minimum of 3).

    python benchmarks/bench_sampler.py --render   # whole renders: a vertex's Sobol' requests one by one
                                                  # against one batch (Sampler.make_batch), same bits

``--render``: nee + sobol's fast kernel built twice, the vertex drawing its requests one at a time
(the sampler without ``make_batch``) and as one batch (the product), and nee + sobol-affine (its own
numbers, so its film is not sobol's: its mean is printed), on bench_vs_mitsuba's Cornell
box (diffuse, black sky) and the tests' Cornell box (glossy and glass balls, gradient sky), roulette
from 3 hits. Each run is one single-threaded launch over every pixel, timed by the launching
thread's CPU time, the two builds alternated ``--repeat`` times (the machine may be loaded: the
median is printed with the spread); the films must be bit-identical.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING   # no banner or module-load lines (Warp 1.19 dropped config.quiet)

from warp_spt.device.sampling import stream_state  # noqa: E402
from warp_spt.samplers import sobol, sobol_affine  # noqa: E402

vec8 = wp.types.vector(length=8, dtype=float)
HALF_PI = math.pi / 2

# name, dimensions, exact integral over the unit cube
INTEGRANDS = [
    ("smooth 2D: e^x sin(pi y)", 2, (math.e - 1.0) * 2.0 / math.pi),
    ("2D disk indicator r=0.4", 2, math.pi * 0.16),
    ("4D product of (pi/2) sin(pi u)", 4, 1.0),
    ("8D product of (pi/2) sin(pi u)", 8, 1.0),
    ("4D cross-pair steps (worst case)", 4, 1.0),
]


@wp.func
def integrand(kind: int, u: vec8) -> float:
    if kind == 0:
        return wp.exp(u[0]) * wp.sin(3.14159265358979 * u[1])
    if kind == 1:
        dx = u[0] - 0.5
        dy = u[1] - 0.5
        return wp.where(dx * dx + dy * dy < 0.16, 1.0, 0.0)
    if kind == 4:
        return 1.0 + wp.sign(u[0] - 0.5) * wp.sign(u[2] - 0.5)
    f = float(1.0)
    for k in range(wp.where(kind == 2, 4, 8)):
        f = f * (1.5707963267948966 * wp.sin(3.14159265358979 * u[k]))
    return f


def make_draw(sampler: str):
    """The wp.func that fills the first ``dims`` entries of a vec8 for (seed, pixel, sample)."""
    if sampler in ("sobol", "sobol-affine"):
        two_d = (sobol if sampler == "sobol" else sobol_affine).POINTS.two

        @wp.func
        def draw(seed: wp.uint32, pixel: int, j: int, dims: int) -> vec8:
            u = vec8()
            for k in range(dims // 2):
                v = two_d(seed, pixel, j, 2 * k)
                u[2 * k] = v[0]
                u[2 * k + 1] = v[1]
            return u
    else:
        @wp.func
        def draw(seed: wp.uint32, pixel: int, j: int, dims: int) -> vec8:
            u = vec8()
            state = stream_state(seed, pixel, j)
            for k in range(dims):
                u[k] = wp.randf(state)
            return u
    return draw


def make_kernels(sampler: str):
    draw = make_draw(sampler)

    @wp.kernel(enable_backward=False, module="unique")
    def estimate(seed: wp.uint32, kind: int, dims: int, checkpoints: wp.array(dtype=int),
                 sums: wp.array2d(dtype=wp.float64)):
        """sums[p, c] = sum of the first checkpoints[c] samples' integrand values of pixel p."""
        p = wp.tid()
        acc = wp.float64(0.0)
        c = int(0)
        for j in range(checkpoints[checkpoints.shape[0] - 1]):
            acc += wp.float64(integrand(kind, draw(seed, p, j, dims)))
            if j + 1 == checkpoints[c]:
                sums[p, c] = acc
                c += 1

    @wp.kernel(enable_backward=False, module="unique")
    def draw_only(seed: wp.uint32, dims: int, n: int, out: wp.array(dtype=float)):
        p = wp.tid()
        s = float(0.0)
        for j in range(n):
            u = draw(seed, p, j, dims)
            for k in range(dims):
                s += u[k]
        out[p] = s

    return estimate, draw_only


def rmse_table(kernels, pixels: int, n_max: int, seed: int):
    """RMSE per integrand and sampler at N = every power of two and every 3 * 2**k up to n_max."""
    ns = np.array(sorted({2**k for k in range(int(math.log2(n_max)) + 1)}
                         | {3 * 2**k for k in range(int(math.log2(n_max))) if 3 * 2**k <= n_max}))
    checkpoints = wp.array(ns.astype(np.int32), dtype=int)
    result, spread = {}, {}
    for kind, (name, dims, exact) in enumerate(INTEGRANDS):
        result[name], spread[name] = {}, {}
        for sampler, (estimate, _) in kernels.items():
            sums = wp.zeros((pixels, ns.size), dtype=wp.float64)
            wp.launch(estimate, pixels, inputs=[wp.uint32(seed), kind, dims, checkpoints, sums])
            sq = (sums.numpy() / ns - exact) ** 2
            result[name][sampler] = np.sqrt(sq.mean(axis=0))
            # the RMSE's relative standard error at N = n_max, from the spread of the squared errors
            spread[name][sampler] = 0.5 * sq[:, -1].std() / math.sqrt(pixels) / sq[:, -1].mean()
    return ns, result, spread


def time_draws(draw_only, dims: int, pixels: int, n: int) -> float:
    out = wp.zeros(pixels, dtype=float)
    best = float("inf")
    for _ in range(3):
        t = time.perf_counter()
        wp.launch(draw_only, pixels, inputs=[wp.uint32(1), dims, n, out])
        wp.synchronize()
        best = min(best, time.perf_counter() - t)
    return best / (pixels * n) * 1e9


def render_scenes(folder: Path) -> list:
    """(name, DeviceScene, Camera, Sky) of the --render scenes."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_rays import SKY, mitsuba_cornell
    from tests.support.stability_scenes import cornell_camera, cornell_files

    from warp_spt.upload.device_scene import DeviceScene
    from warp_spt.io.loader import load_scene
    room = DeviceScene(load_scene(*cornell_files(folder), warn=lambda message: None))
    return [mitsuba_cornell(folder), ("Cornell box (tests), glossy and glass balls", room, cornell_camera(), SKY)]


def render_table(size: int, spp: int, repeat: int) -> None:
    """Per-request against batched Sobol' requests in nee's fast kernel: CPU us per sample, same film."""
    import dataclasses
    import statistics
    import tempfile

    from warp_spt.emitters import declare_sky, light_table
    from warp_spt.integrators import RenderParams, camera_params, nee
    from warp_spt.integrators.common import make_kernel, make_start_path
    from warp_spt.samplers import get_sampler

    batched = get_sampler("sobol")
    variants = {"one by one": dataclasses.replace(batched, make_batch=None), "one batch": batched,
                "sobol-affine, one batch": get_sampler("sobol-affine")}
    n = size * size
    print(f"\nnee + sobol, {size}x{size}, {spp} spp, depth 6, roulette from 3 hits: CPU us per sample "
          f"(one single-threaded launch, builds alternated, median [min-max] of {repeat})")
    print("| scene | requests | us per sample | over one by one | film |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, dev, cam, sky in render_scenes(Path(tmp)):
            feats = dev.features.with_lights(declare_sky(sky))
            kernels = {}
            for label, sampler in variants.items():
                k = make_kernel(nee.make_path_step(feats, sampler, light_sampling=True), make_start_path(sampler))
                wp.load_module(k.module, device="cpu")
                kernels[label] = k
            rp = RenderParams()
            rp.width, rp.pixel_start, rp.sample_start, rp.sample_count = size, 0, 0, spp
            rp.max_depth, rp.roulette_depth, rp.seed = 6, 3, wp.uint32(1)
            fixed = [dev.geometry, dev.materials, dev.textures(), light_table(dev, sky), camera_params(cam, size, size),
                     rp]
            films = {label: wp.zeros(n, dtype=wp.vec3d) for label in kernels}
            times = {label: [] for label in kernels}
            for _ in range(repeat):
                for label, k in kernels.items():
                    films[label].zero_()
                    t = time.thread_time()
                    wp.launch(k, dim=n, inputs=[*fixed, films[label], wp.zeros((n, 2), dtype=wp.int64), None])
                    times[label].append(time.thread_time() - t)
            ref = films["one by one"].numpy()
            base = statistics.median(times["one by one"])
            for label, ts in times.items():
                med = statistics.median(ts)
                same = "bit-identical" if np.array_equal(films[label].numpy(), ref) else "DIFFERS"
                if label.startswith("sobol-affine"):     # another sampler: its own numbers, the same mean
                    same = f"mean {films[label].numpy().mean() / ref.mean():.4f}x sobol's"
                print(f"| {name} | {label} | {med / (n * spp) * 1e6:.3f} [{min(ts) / (n * spp) * 1e6:.3f}-"
                      f"{max(ts) / (n * spp) * 1e6:.3f}] | {base / med:.3f}x | {same} |")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--render", action="store_true", help="only the whole-render timing (see above)")
    ap.add_argument("--pixels", type=int, default=0, help="estimates per N (default 2048; --quick 512)")
    ap.add_argument("--size", type=int, default=128, help="--render: pixels per side")
    ap.add_argument("--spp", type=int, default=8, help="--render: samples per pixel")
    ap.add_argument("--repeat", type=int, default=7, help="--render: alternated runs of each build")
    args = ap.parse_args()
    if args.render:
        render_table(args.size, args.spp, args.repeat)
        return
    pixels, n_max = (512, 1024) if args.quick else (2048, 4096)
    pixels = args.pixels or pixels
    kernels = {s: make_kernels(s) for s in ("independent", "sobol", "sobol-affine")}
    for estimate, draw_only in kernels.values():       # compile outside the timings
        wp.launch(estimate, 1, inputs=[wp.uint32(0), 0, 2, wp.array([1], dtype=int), wp.zeros((1, 1), dtype=wp.float64)])
        wp.launch(draw_only, 1, inputs=[wp.uint32(0), 2, 1, wp.zeros(1, dtype=float)])

    ns, table, spread = rmse_table(kernels, pixels, n_max, seed=12345)
    print(f"RMSE of {pixels} independent estimates against the exact integral")
    shown = [n for n in ns if n in (1, 4, 16, 64, 256, 1024, 4096)]
    print("| integrand | sampler | " + " | ".join(f"N={n}" for n in shown)
          + " | slope | RMSE ratio at N=max | +- at N=max |")
    print("|---|---|" + "---|" * (len(shown) + 3))
    powers = (ns & (ns - 1)) == 0
    fit = powers & (ns >= 4)
    for name, rows in table.items():
        for sampler, err in rows.items():
            slope = np.polyfit(np.log(ns[fit]), np.log(err[fit]), 1)[0]
            ratio = rows["independent"][-1] / err[-1]
            cells = " | ".join(f"{err[list(ns).index(n)]:.2e}" for n in shown)
            print(f"| {name} | {sampler} | {cells} | {slope:.2f} | {ratio:.1f}x | {100 * spread[name][sampler]:.1f}% |")

    around = [n for n in (32, 48, 64, 96, 128, 192, 256) if n <= n_max]
    print("\nNon-power-of-two N: RMSE(independent) / RMSE(sobol) (a power of two is a whole net)")
    print("| integrand | sampler | " + " | ".join(f"N={n}" for n in around) + " |")
    print("|---|---|" + "---|" * len(around))
    for name, rows in table.items():
        for sampler in ("sobol", "sobol-affine"):
            gain = rows["independent"] / rows[sampler]
            print(f"| {name} | {sampler} | " + " | ".join(f"{gain[list(ns).index(n)]:.1f}" for n in around) + " |")

    n_time = 256 if args.quick else 1024
    print(f"\nns per sample (draws only, {pixels} x {n_time} samples, one thread, min of 3)")
    print("| dims | independent ns | sobol ns | sobol-affine ns | sobol / independent | sobol / sobol-affine |")
    print("|---|---|---|---|---|---|")
    for dims in (2, 4, 8):
        t_ind = time_draws(kernels["independent"][1], dims, pixels, n_time)
        t_sob = time_draws(kernels["sobol"][1], dims, pixels, n_time)
        t_aff = time_draws(kernels["sobol-affine"][1], dims, pixels, n_time)
        print(f"| {dims} | {t_ind:.1f} | {t_sob:.1f} | {t_aff:.1f} | {t_sob / t_ind:.1f} | {t_sob / t_aff:.2f} |")


if __name__ == "__main__":
    main()
