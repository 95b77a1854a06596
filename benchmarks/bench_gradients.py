"""Backward against forward: time and peak memory of gradient renders, and texel-gradient contention.

    PYTHONPATH=. python benchmarks/bench_gradients.py [--size 128] [--spp 4] [--depth 6]

Scene: the demo Cornell box (cornell.obj, demo.mtl), seed integrator, independent sampler. Modes:

* ``forward``: the fast renderer (enable_backward=False), all cores;
* ``render_gradients``: its forward image, then the adjoint kernel per tile (1 and all threads);
* ``tape``: ``render_differentiable`` + ``wp.Tape.backward`` (one thread, the previous approach).

Peak memory is the rise of the process's peak resident set (VmHWM, reset through
/proc/self/clear_refs after compiling and warming up) during one call. Compile times are printed too
(each cold compile is measured once, so run it twice to see the cached figures).
Texel contention: backward time with the gradient of a 2x2, 16x16 or 256x256 texture on a quad
filling the view, against no texel gradient (CPU kernels are serial per thread and each tile has its
own buffer: no atomic contention is expected, and this measures it).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import warp as wp

import warp_spt
from warp_spt.demo import demo_dir
from warp_spt.gradients import enable_material_gradients, render_differentiable, render_gradients
from warp_spt.params import parameters
from warp_spt.renderer import RenderSettings, render_scene


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


def cornell(size: int, spp: int, depth: int):
    d = demo_dir()
    scene = warp_spt.load_scene([str(d / "cornell.obj")], [str(d / "demo.mtl")])
    params = parameters(scene, warp_spt.Camera(), warp_spt.Sky.black())
    rs = RenderSettings(width=size, height=size, spp=spp, max_depth=depth, tile_pixels=1024, integrator="seed")
    return params, rs


def bench_modes(size: int, spp: int, depth: int) -> None:
    params, rs = cornell(size, spp, depth)
    adj = np.ones((size, size, 3))
    names = ["red.diffuse", "green.diffuse", "white.diffuse", "light.emission", "Floor.roughness"]
    dev = params.scene

    def forward():
        render_scene(dev, params.camera, rs.__class__(**{**rs.__dict__, "sky": params.sky}))

    def grads(threads):
        return lambda: render_gradients(params, RenderSettings(**{**rs.__dict__, "threads": threads}), adjoint=adj,
                                        wrt=names)

    def tape():
        enable_material_gradients(dev)
        r = render_differentiable(dev, params.camera, width=size, height=size, spp=spp, max_depth=depth,
                                  sky=params.sky)
        r.tape.backward(grads={r.image: wp.array(adj.reshape(-1, 3).astype(np.float32), dtype=wp.vec3)})

    for name, fn in [("forward", forward), ("gradients", grads(None)), ("tape", tape)]:
        t0 = time.perf_counter()
        fn()                                       # compile (or load from Warp's cache) and warm up
        print(f"  first call of {name}: {time.perf_counter() - t0:.1f} s (includes compiling)")
    print(f"\nCornell box {size}x{size}, spp {spp}, depth {depth}; seed integrator; times best of 3")
    rows = {}
    for name, fn in [("forward (fast kernel, all threads)", forward),
                     ("render_gradients, 1 thread", grads(1)),
                     ("render_gradients, all threads", grads(None)),
                     ("tape: render_differentiable + backward", tape)]:
        runs = [peak_rise_mb(fn) for _ in range(3)]
        rows[name] = (min(r[0] for r in runs), max(r[1] for r in runs))
    f = rows["forward (fast kernel, all threads)"][0]
    for name, (s, mb) in rows.items():
        print(f"  {name:42s} {s * 1e3:8.0f} ms  {s / f:5.2f}x forward   peak +{mb:6.1f} MB")
    r = render_gradients(params, rs, adjoint=adj, wrt=names)
    print(f"  render_gradients split: forward {r.forward_seconds * 1e3:.0f} ms + backward "
          f"{r.backward_seconds * 1e3:.0f} ms = backward {r.backward_seconds / r.forward_seconds:.2f}x its forward;"
          f" backward allocates {r.backward_bytes / 1024:.0f} KiB ({r.tiles} tiles, {r.threads} threads)")
    for s in (spp, 4 * spp):
        rr = RenderSettings(**{**rs.__dict__, "spp": s})
        secs, mb = peak_rise_mb(lambda: render_gradients(params, rr, adjoint=adj, wrt=names))
        print(f"  spp {s:4d}: render_gradients {secs * 1e3:7.0f} ms, peak +{mb:.1f} MB")


def bench_texels(size: int, spp: int) -> None:
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))
    import inverse_rendering as ir

    print(f"\nTexel gradients, quad {size}x{size}, spp {spp}, depth 2, nearest; backward time best of 3")
    for n in (2, 16, 256):
        with tempfile.TemporaryDirectory() as tmp:
            scene, camera = ir.textured_quad(Path(tmp), n)
        params = parameters(scene, camera, warp_spt.Sky.constant(1, 1, 1))
        rs = RenderSettings(width=size, height=size, spp=spp, max_depth=2, tile_pixels=1024, integrator="seed")
        adj = np.ones((size, size, 3))
        out = {}
        for label, wrt in (("no texels", ["quad.diffuse"]), ("texels", ["quad.diffuse_map"])):
            render_gradients(params, rs, adjoint=adj, wrt=wrt)
            out[label] = min(render_gradients(params, rs, adjoint=adj, wrt=wrt).backward_seconds for _ in range(3))
        print(f"  {n:3d}x{n:<3d} texture: backward {out['texels'] * 1e3:6.0f} ms with texel gradients, "
              f"{out['no texels'] * 1e3:6.0f} ms without ({out['texels'] / out['no texels']:.2f}x)")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=4)
    ap.add_argument("--depth", type=int, default=6)
    a = ap.parse_args()
    bench_modes(a.size, a.spp, a.depth)
    bench_texels(a.size, a.spp)


if __name__ == "__main__":
    main()
