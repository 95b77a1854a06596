"""Backward against forward: time and peak memory of gradient renders, and texel-gradient contention.

    PYTHONPATH=. python benchmarks/bench_gradients.py [--size 128] [--spp 4] [--depth 6]
        [--integrator nee] [--sampler sobol] [--skip modes tape growth texels geometry interop]

Scene: the demo Cornell box (cornell.obj, demo.mtl); by default the renderer's default integrator
and sampler (nee + sobol). Modes:

* ``forward``: the fast renderer (enable_backward=False), all cores;
* ``render_gradients prb``: path replay per tile (warp_spt.diff.prb; 1 and all threads); given an adjoint
  image, it takes the image from its own first pass and runs no separate forward render;
* ``render_gradients tape``: the fast renderer's image, then Warp's adjoint of the unrolled step per tile;
* ``tape``: ``render_differentiable`` + ``wp.Tape.backward`` (one thread, the first approach).

Accounting of "backward / forward": *forward* is the fast kernel's render of the same image
(``render_scene``, same settings, 1 thread), *backward* everything ``render_gradients`` does beyond
returning that image, i.e. its wall-clock time minus that forward. The two run alternately, one pair
after the other, so that a changing load on the shared machine moves both; the median of the pairs is
printed. Then path replay at 4x the spp, 2x and 4x the depth (beyond the tape's 8), the same way,
with what the backward pass allocates.

Peak memory is the rise of the process's peak resident set (VmHWM, reset through
/proc/self/clear_refs after compiling and warming up) during one call. Compile times are printed too
(each cold compile is measured once, so run it twice to see the cached figures).
Texel contention: backward time with the gradient of a 2x2, 16x16 or 256x256 texture on a quad
filling the view, against no texel gradient (CPU kernels are serial per thread and each tile has its
own buffer: no atomic contention is expected, and this measures it).
Geometry (``geometry``): the Cornell box's pose (``cornell.obj.translation`` and ``.rotation``, every
triangle moving) and the camera's position at the same spp: the forward render, the interior term
(``boundary=False``) by the tape and by path replay (``diff.replay_pathwise``), the whole gradient with the boundary term, and the primary boundary
term's parts (the host's curves and samples, the kernel tracing its pairs of rays, the chain rule) and
the secondary term; what setting a
pose costs (a world-space mesh's BVH is rebuilt; an instance's only the top-level BVH).
Interop (``interop``): an iteration through ``render_arrays`` on a ``wp.Tape`` against the same calls
made directly, and the bytes it copies.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import warp as wp

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))    # run from a checkout, like the others

import warp_spt  # noqa: E402
from warp_spt.demo import demo_dir  # noqa: E402
from warp_spt.diff.gradients import (  # noqa: E402
    enable_material_gradients,
    render_differentiable,
    render_gradients,
)
from warp_spt.diff.params import parameters  # noqa: E402
from warp_spt.integrators import DEFAULT_INTEGRATOR  # noqa: E402
from warp_spt.rendering.settings import RenderSettings  # noqa: E402
from warp_spt.rendering.tiles import render_scene  # noqa: E402
from warp_spt.samplers import DEFAULT_SAMPLER  # noqa: E402


def _rss_kb(field: str) -> int:
    for line in Path("/proc/self/status").read_text().splitlines():
        if line.startswith(field + ":"):
            return int(line.split()[1])
    return 0


def peak_rise_mb(fn) -> tuple[float, float]:
    """(seconds, MB of peak RSS above the RSS before the call)."""
    try:
        Path("/proc/self/clear_refs").write_text("5")      # reset VmHWM to the current RSS
    except OSError:
        pass
    before = _rss_kb("VmRSS")
    t0 = time.perf_counter()
    fn()
    seconds = time.perf_counter() - t0
    return seconds, (_rss_kb("VmHWM") - before) / 1024.0


def cornell(size: int, spp: int, depth: int, integrator: str = DEFAULT_INTEGRATOR, sampler: str = DEFAULT_SAMPLER):
    d = demo_dir()
    scene = warp_spt.load_scene([str(d / "cornell.obj")], [str(d / "demo.mtl")])
    params = parameters(scene, warp_spt.Camera(), warp_spt.Sky.black())
    rs = RenderSettings(width=size, height=size, spp=spp, max_depth=depth, tile_pixels=1024, integrator=integrator,
                        sampler=sampler)
    return params, rs


NAMES = ["red.diffuse", "green.diffuse", "white.diffuse", "light.emission", "Floor.roughness"]


def bench_modes(size: int, spp: int, depth: int, integrator: str, sampler: str, with_tape: bool = True) -> None:
    params, rs = cornell(size, spp, depth, integrator, sampler)
    adj = np.ones((size, size, 3))
    dev = params.scene

    def forward():
        render_scene(dev, params.camera, replace(rs, sky=params.sky))

    def grads(mode, threads=None):
        return lambda: render_gradients(params, replace(rs, threads=threads), adjoint=adj, wrt=NAMES, mode=mode)

    def tape():
        enable_material_gradients(dev)
        r = render_differentiable(dev, params.camera, width=size, height=size, spp=spp, max_depth=depth,
                                  sky=params.sky, integrator=integrator, sampler=sampler)
        r.tape.backward(grads={r.image: wp.array(adj.reshape(-1, 3).astype(np.float32), dtype=wp.vec3)})

    rows = [("forward (fast kernel, all threads)", forward),
            ("render_gradients prb, all threads", grads("prb")),
            ("render_gradients prb, 1 thread", grads("prb", 1)),
            ("render_gradients tape, all threads", grads("tape")),
            ("tape: render_differentiable + backward", tape)]
    if not with_tape:       # the tape's kernels are the slowest to compile cold
        rows = rows[:3]
    for name, fn in rows[:2] + rows[3:]:
        t0 = time.perf_counter()
        fn()                                       # compile (or load from Warp's cache) and warm up
        print(f"  first call of {name}: {time.perf_counter() - t0:.1f} s (includes compiling)")
    print(f"\nCornell box {size}x{size}, spp {spp}, depth {depth}; {integrator} + {sampler}; best of 3, "
          f"the modes interleaved")
    runs: dict[str, list] = {name: [] for name, _ in rows}
    for _ in range(3):
        for name, fn in rows:
            runs[name].append(peak_rise_mb(fn))
    f = min(r[0] for r in runs[rows[0][0]])
    for name, _ in rows:
        s, mb = min(r[0] for r in runs[name]), max(r[1] for r in runs[name])
        print(f"  {name:42s} {s * 1e3:8.0f} ms  {s / f:5.2f}x forward   peak +{mb:6.1f} MB")
    print("  backward / forward, 1 thread (render_gradients minus the fast kernel's render of the same image, "
          "run alternately); median [range] of 5 pairs:")
    for mode in ("prb", "tape") if with_tape else ("prb",):
        ratios, fwd_s, bwd_s, r = backward_split(params, replace(rs, threads=1), adj, mode, 5)
        print(f"  {mode:4s}: backward {ratios[2]:.2f}x forward [{ratios[0]:.2f}-{ratios[-1]:.2f}]; forward "
              f"{min(fwd_s) * 1e3:.0f} ms, backward {min(bwd_s) * 1e3:.0f} ms (best); backward allocates "
              f"{r.backward_bytes / 1024:.0f} KiB ({r.tiles} tiles)")


def backward_split(params, rs: RenderSettings, adj: np.ndarray, mode: str, pairs: int):
    """(sorted backward/forward ratios, forward seconds, backward seconds, last GradientResult) of
    ``pairs`` alternated (fast render, render_gradients) pairs; backward = render_gradients - forward."""
    ratios, fwd_s, bwd_s = [], [], []
    for _ in range(pairs):
        t0 = time.perf_counter()
        render_scene(params.scene, params.camera, replace(rs, sky=params.sky))
        f = time.perf_counter() - t0
        t0 = time.perf_counter()
        r = render_gradients(params, rs, adjoint=adj, wrt=NAMES, mode=mode)
        b = time.perf_counter() - t0 - f
        ratios.append(b / f)
        fwd_s.append(f)
        bwd_s.append(b)
    return sorted(ratios), fwd_s, bwd_s, r


def bench_growth(size: int, spp: int, depth: int, integrator: str, sampler: str) -> None:
    """Path replay's backward against its forward as spp and depth grow (the tape stops at depth 8)."""
    params, rs = cornell(size, spp, depth, integrator, sampler)
    adj = np.ones((size, size, 3))
    print(f"\nPath replay as spp and depth grow ({size}x{size}, 1 thread; backward/forward as above, "
          f"median of 3 pairs)")
    for s, d in ((spp, depth), (4 * spp, depth), (spp, 2 * depth), (spp, 4 * depth)):
        rr = replace(rs, spp=s, max_depth=d, threads=1)
        ratios, fwd_s, bwd_s, r = backward_split(params, rr, adj, "prb", 3)
        mb = peak_rise_mb(lambda: render_gradients(params, rr, adjoint=adj, wrt=NAMES, mode="prb"))[1]
        print(f"  spp {s:4d} depth {d:3d}: forward {sorted(fwd_s)[1] * 1e3:7.0f} ms, backward "
              f"{sorted(bwd_s)[1] * 1e3:7.0f} ms ({ratios[1]:.2f}x), backward allocates "
              f"{r.backward_bytes / 1024:.0f} KiB, peak +{mb:.1f} MB")


def bench_texels(size: int, spp: int) -> None:
    from warp_spt.diff.inverse_demo import textured_quad

    print(f"\nTexel gradients, quad {size}x{size}, spp {spp}, depth 2, nearest; backward time best of 3")
    for n in (2, 16, 256):
        with tempfile.TemporaryDirectory() as tmp:
            scene, camera = textured_quad(Path(tmp), n)
        params = parameters(scene, camera, warp_spt.Sky.constant(1, 1, 1))
        rs = RenderSettings(width=size, height=size, spp=spp, max_depth=2, tile_pixels=1024, integrator="seed")
        adj = np.ones((size, size, 3))
        out = {}
        for label, wrt in (("no texels", ["quad.diffuse"]), ("texels", ["quad.diffuse_map"])):
            render_gradients(params, rs, adjoint=adj, wrt=wrt)
            out[label] = min(render_gradients(params, rs, adjoint=adj, wrt=wrt).backward_seconds for _ in range(3))
        print(f"  {n:3d}x{n:<3d} texture: backward {out['texels'] * 1e3:6.0f} ms with texel gradients, "
              f"{out['no texels'] * 1e3:6.0f} ms without ({out['texels'] / out['no texels']:.2f}x)")


def bench_geometry(size: int, spp: int, depth: int, integrator: str, sampler: str) -> None:
    """The geometry gradients' terms against the forward render (module docstring)."""
    from warp_spt.diff import boundary as B
    from warp_spt.diff import secondary as S
    from warp_spt.rendering.setup import bind

    params, rs = cornell(size, spp, depth, integrator, sampler)
    rs = replace(rs, max_depth=min(depth, 8))          # the tape's interior term: at most 8 bounces
    adj = np.ones((size, size, 3))
    names = ["cornell.obj.translation", "cornell.obj.rotation", "camera.position"]

    def forward():
        render_scene(params.scene, params.camera, replace(rs, sky=params.sky))

    def interior():
        return render_gradients(params, rs, adjoint=adj, wrt=names, boundary=False, mode="tape")

    def interior_replay():
        return render_gradients(params, rs, adjoint=adj, wrt=names, boundary=False, mode="prb")

    def whole():
        return render_gradients(params, rs, adjoint=adj, wrt=names)

    for fn in (forward, interior, interior_replay, whole):
        fn()                                           # compile (or load) and warm up
    rows = [("forward (fast kernel, all threads)", forward), ("interior term (tape, boundary=False)", interior),
            ("interior term (path replay, boundary=False)", interior_replay),
            (f"interior + boundary terms ({whole().mode})", whole)]
    runs = {name: [] for name, _ in rows}
    for _ in range(3):
        for name, fn in rows:
            runs[name].append(peak_rise_mb(fn))
    f = min(r[0] for r in runs[rows[0][0]])
    print(f"\nGeometry: Cornell box {size}x{size}, spp {spp} (boundary spp {spp}), depth {rs.max_depth}; "
          f"{integrator} + {sampler}; wrt {', '.join(names)}; best of 3, interleaved")
    for name, _ in rows:
        sec, mb = min(r[0] for r in runs[name]), max(r[1] for r in runs[name])
        print(f"  {name:42s} {sec * 1e3:8.0f} ms  {sec / f:5.2f}x forward   peak +{mb:6.1f} MB")
    r = whole()
    print(f"  backward allocates {r.backward_bytes / 1024:.0f} KiB ({r.tiles} tiles)")
    b = bind(params.scene, params.camera, replace(rs, sky=params.sky), mode="tape")
    proj = B.Projection.of(b.camera, size, size)
    parts = {}
    for _ in range(3):
        t0 = time.perf_counter()
        curves = B.candidate_curves(b.dev.scene, b.dev.geometry.has_corner_normals != 0, proj, size, size,
                                    b.dev.geometry.extent, {})
        smp = B.draw(curves, b.dev.scene, proj, spp * size * size, np.random.default_rng(0))
        t1 = time.perf_counter()
        B._trace_pairs(b, proj, smp.px, smp.normal, 1)
        t2 = time.perf_counter()
        infos = [params.info(n) for n in names]
        B.primary_term(b, adj, infos, spp, 1)
        t3 = time.perf_counter()
        S.secondary_term(b, adj, infos, spp, 1)
        t4 = time.perf_counter()
        for k, v in (("curves and samples (host)", t1 - t0), ("paths of the sample pairs (kernel)", t2 - t1),
                     ("the whole primary term", t3 - t2), ("the secondary term (all of it)", t4 - t3)):
            parts[k] = min(parts.get(k, v), v)
    print(f"  the primary term: {len(curves)} curves, {spp * size * size} samples, {2 * spp * size * size} rays; "
          f"the secondary term: {spp * size * size} paths, each a camera-ray hit and (depth >= 3) a deeper "
          f"vertex, each receiver 2 rays and 2 paths")
    for k, v in parts.items():
        print(f"    {k:40s} {v * 1e3:8.0f} ms  {v / f:5.2f}x forward")
    for label, value in (("a world-space mesh's pose (its BVH rebuilt)", (0.01, 0.0, 0.0)),):
        t0 = time.perf_counter()
        for k in range(5):
            params["cornell.obj.translation"] = np.asarray(value) * (k + 1)
        print(f"  setting {label}: {(time.perf_counter() - t0) / 5 * 1e3:.1f} ms "
              f"({len(params.scene.scene.meshes[0].indices)} triangles)")
    params["cornell.obj.translation"] = (0.0, 0.0, 0.0)


def bench_interop(size: int, spp: int, depth: int, integrator: str, sampler: str) -> None:
    """One iteration through ``render_arrays`` on a ``wp.Tape`` (positions from a wp.array, the loss
    in a Warp kernel, ``tape.backward``) against the same work called directly (``params[name] = v``,
    ``render_scene``, ``render_gradients(adjoint=...)``): the interop's overhead, and what it copies."""
    import warp as wp

    from warp_spt.diff.interop import render_arrays

    params, rs = cornell(size, spp, depth, integrator, sampler)
    name = "cornell.obj.positions"
    base = params[name].astype(np.float64)
    target = np.zeros((size, size, 3), np.float32)

    @wp.kernel
    def l2(image: wp.array(dtype=float, ndim=3), t: wp.array(dtype=float, ndim=3), loss: wp.array(dtype=float)):
        y, x, c = wp.tid()
        d = image[y, x, c] - t[y, x, c]
        wp.atomic_add(loss, 0, d * d)

    t_wp = wp.array(target, dtype=float)

    def on_tape(k):
        x = wp.array(base + 1e-4 * k, dtype=wp.vec3, requires_grad=True)
        loss = wp.zeros(1, dtype=float, requires_grad=True)
        tape = wp.Tape()
        with tape:
            image = render_arrays(params, {name: x}, replace(rs, seed=k), gradient_seed=1000 + k)
            wp.launch(l2, dim=image.shape, inputs=[image, t_wp], outputs=[loss])
        tape.backward(loss)
        return x.grad.numpy()

    def direct(k):
        params[name] = base + 1e-4 * k
        image = render_scene(params.scene, params.camera, replace(rs, seed=k, sky=params.sky)).image
        adj = 2.0 * (image - target)
        return render_gradients(params, replace(rs, seed=k), adjoint=adj, wrt=[name], gradient_seed=1000 + k,
                                image=False).grads[name]

    on_tape(0), direct(0)                              # compile (or load) and warm up
    runs = {"on_tape": [], "direct": []}
    for k in range(1, 4):
        for key, fn in (("direct", direct), ("on_tape", on_tape)):
            t0 = time.perf_counter()
            fn(k)
            runs[key].append(time.perf_counter() - t0)
    d, t = min(runs["direct"]), min(runs["on_tape"])
    v = len(base)
    print(f"\nInterop: Cornell box {size}x{size}, spp {spp}, depth {depth}; wrt {name} ({v} vertices); best of 3")
    print(f"  direct (params[name] = v, render_scene, render_gradients)   {d * 1e3:8.0f} ms")
    print(f"  render_arrays on a wp.Tape + Warp L2 + tape.backward        {t * 1e3:8.0f} ms  {t / d:5.2f}x")
    print(f"  copied per iteration on the CPU device: the input 0 B (numpy() is a view), the image "
          f"{size * size * 3 * 4} B, the gradient {2 * v * 3 * 4} B (read and written back through the host)")
    params[name] = base


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--depth", type=int, default=6)
    ap.add_argument("--integrator", default=DEFAULT_INTEGRATOR)
    ap.add_argument("--sampler", default=DEFAULT_SAMPLER)
    ap.add_argument("--skip", nargs="*", default=[], choices=["modes", "tape", "growth", "texels", "geometry", "interop"])
    a = ap.parse_args()
    if "modes" not in a.skip:
        bench_modes(a.size, a.spp, a.depth, a.integrator, a.sampler, with_tape="tape" not in a.skip)
    if "growth" not in a.skip:
        bench_growth(a.size, a.spp, a.depth, a.integrator, a.sampler)
    if "texels" not in a.skip:
        bench_texels(a.size, a.spp)
    if "geometry" not in a.skip:
        bench_geometry(a.size, a.spp, a.depth, a.integrator, a.sampler)
    if "interop" not in a.skip:
        bench_interop(a.size, a.spp, a.depth, a.integrator, a.sampler)


if __name__ == "__main__":
    main()
