"""Environment lighting: equal-error efficiency of importance sampling against uniform sampling of
the map (and pbrt-v4's MIS compensation), nee + sobol, on a scene of a matte ground, a matte sphere
and a rough metal sphere under the synthetic sun + sky map of scripts/make_test_envmap.py.

Efficiency = 1 / (relative error^2 x seconds) against a reference of many samples (importance
sampled); equal-error efficiency ratios are printed against uniform. Figures only, never asserted.

    python benchmarks/bench_envmap.py [--res 64] [--spp 16] [--ref-spp 1024] [--runs 3]
    python benchmarks/bench_envmap.py --vs-mitsuba [--spp 64] [--runs 3]

``--vs-mitsuba``: the scene of the Mitsuba comparison (tests/support/mitsuba_envmap_scene.py: a grey, a rough
gold and a rough glass sphere under the synthetic map, 48 x 24, camera rays not seeing the map),
ours (nee + sobol, no roulette) against Mitsuba 3 (``path``, its default roulette,
``independent`` sampler, its envmap importance sampling, ``scalar_rgb``) at equal spp, each error against the stored reference
(tests/data/mitsuba_envmap_refs.npz, Mitsuba at 8 x 4096 spp), efficiency 1 / (error^2 x seconds).
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

OBJ = """v -6 -6 0
v 6 -6 0
v 6 6 0
v -6 6 0
usemtl ground
f 1 2 3
f 1 3 4
usemtl matte
b -1.1 0 1 1
usemtl metal
b 1.1 0 1 1
"""
MTL = """newmtl ground
Kd 0.6 0.6 0.6
newmtl matte
Kd 0.8 0.3 0.2
newmtl metal
Kd 0.9 0.9 0.9
Pm 1
Pr 0.25
"""


def synthetic():
    spec = importlib.util.spec_from_file_location("make_test_envmap", ROOT / "scripts" / "make_test_envmap.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.synthetic_envmap


def vs_mitsuba(spp: int, runs: int) -> None:
    import mitsuba as mi

    import warp_spt as ws
    from tests.support import mitsuba_envmap_scene as ES
    from warp_spt.upload.device_scene import DeviceScene
    from tests.data.make_mitsuba_envmap_refs import synthetic
    from warp_spt.rendering.result import relative_error

    mi.set_variant("scalar_rgb")
    with np.load(ROOT / "tests" / "data" / "mitsuba_envmap_refs.npz") as z:
        ref = z["mean"].astype(np.float64)
    c = ES.CAMERA
    with tempfile.TemporaryDirectory() as tmp:
        objs, mtls = ES.write_files(Path(tmp))
        host = ws.load_scene(objs, mtls, warn=lambda message: None)
        host.materials.multiscatter[:] = False
        host.sky = ws.Sky.environment(synthetic(), up=(0.0, 1.0, 0.0), background=(0.0, 0.0, 0.0))
        host = DeviceScene(host)        # uploaded once, as Mitsuba's scene is loaded once
        cam = ws.Camera.look_at(c["position"], c["target"], up=c["up"], fov=c["fov"])
        scene = {"type": "scene", "integrator": {"type": "path", "max_depth": -1, "hide_emitters": True},
                 "sensor": {"type": "perspective", "fov": c["fov"], "fov_axis": "x",
                            "to_world": mi.ScalarTransform4f().look_at(origin=c["position"], target=c["target"],
                                                                       up=c["up"]),
                            "film": {"type": "hdrfilm", "width": ES.WIDTH, "height": ES.HEIGHT,
                                     "pixel_format": "rgb", "rfilter": {"type": "box"}},
                            "sampler": {"type": "independent"}},
                 "sky": {"type": "envmap", "bitmap": mi.Bitmap(synthetic(pole_rows=True))}}
        for (name, _, _, bsdf), f in zip(ES.SPHERES, objs):
            scene[name] = {"type": "obj", "filename": f, "face_normals": True, "bsdf": bsdf}
        ms = mi.load_dict(scene)
    dev = ws.render_scene(host, cam, ws.RenderSettings(width=8, height=4, spp=1, max_depth=ES.MAX_DEPTH))  # compile
    mi.render(ms, spp=1)
    rows, rmse_rows = {}, {}
    for who in ("warp_spt", "mitsuba"):
        errs, rmses, times = [], [], []
        for k in range(runs):
            t = time.perf_counter()
            if who == "mitsuba":
                img = np.asarray(mi.render(ms, spp=spp, seed=50 + k), dtype=np.float64)
            else:
                # each renderer's defaults: ours without Russian roulette (with it from 5 hits, as
                # Mitsuba's default, the per-pixel error measured 0.46 against 0.31, no faster)
                img = ws.render_scene(host, cam, ws.RenderSettings(width=ES.WIDTH, height=ES.HEIGHT, spp=spp,
                                                                   max_depth=ES.MAX_DEPTH, seed=50 + k)).image
            times.append(time.perf_counter() - t)
            errs.append(relative_error(img - ref, ref))
            rmses.append(float(np.sqrt(np.mean((img - ref) ** 2)) / ref.mean()))
        err, sec = float(np.sqrt(np.mean(np.square(errs)))), float(np.median(times))
        rmse = float(np.sqrt(np.mean(np.square(rmses))))
        rows[who], rmse_rows[who] = 1.0 / (err * err * sec), 1.0 / (rmse * rmse * sec)
        print(f"{who:9s} {spp} spp: relative error {err:.4f} (per pixel), RMSE / mean {rmse:.4f}, {sec:.2f} s")
    del dev
    print(f"equal-error efficiency warp_spt / mitsuba: {rows['warp_spt'] / rows['mitsuba']:.2f}x by the per-pixel "
          f"relative error, {rmse_rows['warp_spt'] / rmse_rows['mitsuba']:.2f}x by RMSE "
          "(the reference is Mitsuba's own, 8 x 4096 spp)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--vs-mitsuba", action="store_true")
    ap.add_argument("--res", type=int, default=64)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--ref-spp", type=int, default=1024)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--threads", type=int, default=None)
    a = ap.parse_args(argv)
    if a.vs_mitsuba:
        vs_mitsuba(a.spp, a.runs)
        return 0

    import warp_spt as ws
    from warp_spt.rendering.result import relative_error
    from warp_spt.scene.environment import EnvironmentMap

    img = synthetic()(256)
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "s.obj").write_text(OBJ)
        (Path(tmp) / "s.mtl").write_text(MTL)
        scene = ws.load_scene([str(Path(tmp) / "s.obj")], [str(Path(tmp) / "s.mtl")])
    cam = ws.Camera(position=(0.0, -7.0, 3.0), direction=(0.0, 1.0, -0.3), fov=45.0, up=(0.0, 0.0, 1.0))
    base = ws.RenderSettings(width=a.res, height=a.res, spp=a.spp, max_depth=4, threads=a.threads)

    def run(sampling: str, spp: int, seed: int):
        sky = ws.Sky.environment(EnvironmentMap(img, "synthetic", sampling), up=(0.0, 0.0, 1.0))
        s = replace(scene, sky=sky)
        ws.render_scene(s, cam, replace(base, spp=1, width=8, height=8))       # compile and upload first
        t = time.perf_counter()
        r = ws.render_scene(s, cam, replace(base, spp=spp, seed=seed))
        return r.image, time.perf_counter() - t

    ref, tref = run("importance", a.ref_spp, 12345)
    print(f"reference: {a.res}x{a.res}, {a.ref_spp} spp importance sampled, {tref:.1f} s")
    eff = {}
    for sampling in ("uniform", "importance", "compensated"):
        errs, times = [], []
        for k in range(a.runs):
            im, t = run(sampling, a.spp, k)
            errs.append(relative_error(im - ref, ref))
            times.append(t)
        err, t = float(np.sqrt(np.mean(np.square(errs)))), float(np.median(times))
        eff[sampling] = 1.0 / (err * err * t)
        print(f"{sampling:12s} {a.spp} spp: relative error {err:.4f}, {t:.2f} s, efficiency {eff[sampling]:.3g}")
    for sampling in ("importance", "compensated"):
        print(f"equal-error efficiency {sampling} / uniform: {eff[sampling] / eff['uniform']:.2f}x")
    print(f"compensated / importance: {eff['compensated'] / eff['importance']:.2f}x")
    return 0


if __name__ == "__main__":
    sys.exit(main())
