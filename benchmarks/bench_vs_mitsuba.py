"""Efficiency against Mitsuba 3: 1 / (MSE x wall seconds) on four scenes, both renderers from one description.

    python benchmarks/bench_vs_mitsuba.py             # 256^2, 16 and 64 spp (about 12 minutes on 2 cores)
    python benchmarks/bench_vs_mitsuba.py --quick     # 96^2, 4 and 16 spp, small references (a smoke run)
    python benchmarks/bench_vs_mitsuba.py --check-reference   # is the reference's error estimate right, is it unbiased?

Mitsuba (``pip install mitsuba``) is a benchmark tool here, not a dependency. Its ``llvm_ad_rgb``
variant is used when a one-sample probe render works in a subprocess (drjit aborts the process when
the system's libLLVM is too old: LLVM 14/15 fail, ``apt-get install libllvm19`` fixes it), else
``scalar_rgb``; the variant is printed.

Each scene is a small structure (``SCENES``) of quads, boxes and spheres with four material kinds
that both renderers express the same way:

=========  ==========================================  ==================================================
kind       warp_spt MTL                                Mitsuba
=========  ==========================================  ==================================================
diffuse    ``Kd c``, ``Roughness 1``                   ``twosided`` ``diffuse`` (ours are two-sided)
light      ``Kd 0``, ``Ke L``, ``Roughness 1``         ``area`` emitter ``L`` on a black ``diffuse``
mirror     ``Kr c``, ``Roughness 0``, ``Fuzz 0``       ``conductor``, ``material: none``, reflectance c
glass      ``Kt 1``, ``Kr 1``, ``Refractable``,        ``dielectric``, ``int_ior`` n
           ``Kn n``, ``Roughness 0``, ``Fuzz 0``
=========  ==========================================  ==================================================

The sky is a constant colour (``Sky.constant`` / a ``constant`` emitter; none when black).

The fourth scene, ``envmap``, is lit by an environment map alone: the scene of
``bench_envmap.py --vs-mitsuba`` and tests/emitters/test_envmap.py (``tests/support/mitsuba_envmap_scene.py``: a grey,
a rough gold and a rough glass sphere under the synthetic sun + sky map, 48 x 24 pixels whatever
the size asked, depth 100, the map hidden from the camera), against its stored reference (Mitsuba
``path``, 8 x 4096 spp, ``tests/data/mitsuba_envmap_refs.npz``; its own error, at 512 times the
samples of a 64 spp estimate, is left out). Its agreement line is per 4 x 4 block, Welch's t of 8
renders of different seeds against the stored reference's 8 runs, with the bound of
tests/emitters/test_envmap.py (Bonferroni over the blocks at dof 7). It is not in
``--whole-process`` or ``--check-reference``.

Differences the descriptions work around, and the ones that remain:

- warp_spt's emitters are two-sided, Mitsuba's emit on the side of the face normal only. Every
  light is therefore one face of a closed box (a lamp housing under the ceiling, the top of a
  pillar) with its normal facing into the room: its back side only lights the inside of the box,
  which nothing sees. (A first version hung light quads 0.02 below the ceiling: the back side's
  light leaking out of that gap lit a thin strip of ceiling beside the light, +20% in the 16x16
  blocks around the light's edge; the block test caught it.)
- warp_spt's glass uses Schlick's approximation of the Fresnel factor, Mitsuba's ``dielectric`` the
  exact one (they differ by up to a few hundredths at grazing angles only).
- Depth: warp_spt's ``max_depth`` counts surface hits, and its NEE happens only at hits that may
  still scatter (hits < max_depth), so its longest path has ``max_depth`` segments whether it
  ends on an emitter it hits, on a light it samples or in the sky. Mitsuba's ``path`` integrator
  counts segments too (``max_depth`` 1: emitters seen directly; 2: direct lighting), so the same
  number, 6, means the same paths in both. Mitsuba keeps its default Russian roulette from depth 5
  (unbiased; warp_spt's default has none).
- Pixel filter: Mitsuba's film uses a ``box`` filter, as warp_spt's (one sample, one pixel).

Every scene is first checked for agreement: warp_spt (NEE + Sobol', ``render_progressive``, which
estimates each pixel's standard error from its batches) against the Mitsuba reference, per 16x16
block and channel, t = difference / (combined standard error); the reference (Mitsuba's
``ldsampler``: at 64 spp its best samplers already beat an independent reference of 1024 spp) is
the mean of two halves rendered with different seeds, and its own error comes from their difference. ``--check-reference``
checks that error estimate against renders with more seeds, and ldsampler against the independent
sampler: ldsampler came out 0.15-0.65% darker (docs/performance.md, Against Mitsuba 3), a bias too
small to move the efficiency ratios by 1%.

Efficiency is 1 / (MSE x wall seconds) in linear radiance over all pixels, the reference's own MSE
(a quarter of its halves' mean squared difference) subtracted from each estimate's. Seconds are
wall seconds of one warm render (kernels compiled by an identical render before; Mitsuba's JIT
caches its kernels, warp_spt's are compiled once per integrator x sampler), the least of two runs.
Mitsuba runs every sampler (its best is the anchor of each ratio; the orthogonal sampler rounds
its count up to a prime square, 64 to 121, so it runs at the largest prime square below: 9 and 49); warp_spt runs its default
(``nee`` + ``sobol``) and the seed's estimator with independent numbers. Threads: warp_spt's
``threads=``, Mitsuba's ``drjit.set_thread_count`` (the LLVM backend's pool, settable per render).
"""

from __future__ import annotations

import argparse
import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

mi = None     # Mitsuba, imported by main(): a child process that renders with warp_spt must not load it

S = 32.0          # room size
DEPTH = 6
MITSUBA_SAMPLERS = ("independent", "stratified", "multijitter", "orthogonal", "ldsampler")
def ours_pairs() -> tuple:
    """warp_spt's (integrator, sampler) rows: its default (first: the ratio the targets read), sobol
    (the default before issue 33), the seed's estimator. A function: the module must not import
    warp_spt when loaded (a --whole-process child imports it from another checkout first)."""
    from warp_spt.samplers import DEFAULT_SAMPLER
    return (("nee", DEFAULT_SAMPLER), ("nee", "sobol"), ("seed", "independent"))
TARGETS = {"cornell": 0.8, "indirect": 2.0, "caustics": 1.0}       # issue 24's; envmap: none set
GEOMEAN_TARGET = 1.2
TARGETS_33 = {"cornell": 1.0, "indirect": 1.5, "caustics": 1.0}    # issue 33's

WHITE, RED, GREEN = (0.73, 0.73, 0.73), (0.65, 0.05, 0.05), (0.12, 0.45, 0.15)


def box(mat: str, lo, hi, light: str = "") -> list:
    """The six faces of an axis-aligned box, each as ("quad", mat, corners) with an outward normal.

    ``light`` "top" or "bottom" makes that face the "light" material: a one-sided emitter for both
    renderers, since the back side of a face of a closed box shines only into the box."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    faces = [[(x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)], [(x0, y0, z0), (x0, y1, z0), (x1, y1, z0), (x1, y0, z0)],
             [(x0, y0, z0), (x1, y0, z0), (x1, y0, z1), (x0, y0, z1)], [(x0, y1, z0), (x0, y1, z1), (x1, y1, z1), (x1, y1, z0)],
             [(x0, y0, z0), (x0, y0, z1), (x0, y1, z1), (x0, y1, z0)], [(x1, y0, z0), (x1, y1, z0), (x1, y1, z1), (x1, y0, z1)]]
    names = [mat] * 6
    if light:
        names[("top", "bottom").index(light)] = "light"
    return [("quad", m, f) for m, f in zip(names, faces)]


def room(front: bool) -> list:
    """A 32-unit room: floor, ceiling, back wall, red left and green right walls, optionally a front wall."""
    q = [("quad", "white", [(0, 0, 0), (S, 0, 0), (S, S, 0), (0, S, 0)]),
         ("quad", "white", [(0, 0, S), (0, S, S), (S, S, S), (S, 0, S)]),
         ("quad", "white", [(0, S, 0), (S, S, 0), (S, S, S), (0, S, S)]),
         ("quad", "red", [(0, 0, 0), (0, S, 0), (0, S, S), (0, 0, S)]),
         ("quad", "green", [(S, 0, 0), (S, 0, S), (S, S, S), (S, S, 0)])]
    if front:
        q.append(("quad", "white", [(0, 0, 0), (0, 0, S), (S, 0, S), (S, 0, 0)]))
    return q


BASE_MATS = {"white": ("diffuse", WHITE), "red": ("diffuse", RED), "green": ("diffuse", GREEN)}

SCENES = {
    # The classic layout (as benchmarks/bench_light.py): the light is the underside of a 0.25-thick housing.
    "cornell": dict(
        camera=dict(position=(S / 2, -38.0, S / 2), direction=(0.0, 1.0, 0.0), fov=40.0), sky=(0.0, 0.0, 0.0),
        materials=dict(BASE_MATS, light=("light", (17.0, 12.0, 4.0))),
        shapes=room(front=False) + box("white", (12, 12, S - 0.25), (20, 20, S), light="bottom")
        + box("white", (6, 16, 0), (14, 24, 16)) + box("white", (18, 6, 0), (26, 14, 8))),
    # A closed room; the light lies on a pillar's top facing the ceiling, above the camera's view:
    # everything the camera sees is lit after two or more bounces.
    "indirect": dict(
        camera=dict(position=(S / 2, 1.0, 11.0), direction=(0.0, 1.0, 0.12), fov=80.0), sky=(0.0, 0.0, 0.0),
        materials=dict(BASE_MATS, light=("light", (40.0, 36.0, 30.0))),
        shapes=room(front=True) + box("white", (12, 21, 0), (20, 27, 19), light="top")
        + box("red", (4, 8, 0), (10, 14, 6))),
    # Cornell room with a small light, a glass ball and a mirror ball, a dim constant sky through the open front.
    "caustics": dict(
        camera=dict(position=(S / 2, -38.0, S / 2), direction=(0.0, 1.0, 0.0), fov=40.0), sky=(0.05, 0.05, 0.05),
        materials=dict(BASE_MATS, light=("light", (60.0, 55.0, 45.0)), glass=("glass", 1.5),
                       mirror=("mirror", (0.95, 0.95, 0.95))),
        shapes=room(front=False) + box("white", (14, 14, S - 0.25), (18, 18, S), light="bottom")
        + [("sphere", "glass", (10.0, 12.0, 7.0), 7.0),
                                    ("sphere", "mirror", (23.0, 20.0, 6.0), 6.0)]),
    # lit by an environment map only (tests/support/mitsuba_envmap_scene.py; see the module docstring)
    "envmap": dict(env=True),
}


# ---------------------------------------------------------------------------------------------
# warp_spt side


def mtl_text(materials: dict) -> str:
    """The MTL text of a scene's materials (see the table in the module docstring)."""
    out = []
    for name, (kind, value) in materials.items():
        out.append(f"newmtl {name}")
        if kind == "diffuse":
            out += [f"Kd {value[0]} {value[1]} {value[2]}", "Roughness 1"]
        elif kind == "light":
            out += ["Kd 0 0 0", f"Ke {value[0]} {value[1]} {value[2]}", "Roughness 1"]
        elif kind == "mirror":
            out += ["Kd 0 0 0", f"Kr {value[0]} {value[1]} {value[2]}", "Roughness 0", "Fuzz 0"]
        elif kind == "glass":
            out += ["Kd 0 0 0", "Kr 1 1 1", "Kt 1 1 1", "Refractable", f"Kn {value}", "Roughness 0", "Fuzz 0"]
    return "\n".join(out) + "\n"


def obj_text(shapes: list) -> str:
    """The OBJ text of a scene's shapes: quads as two triangles, spheres in the seed's ``b`` statement."""
    verts, body = [], []
    for shape in shapes:
        if shape[0] == "quad":
            k = len(verts)
            verts += shape[2]
            body += [f"usemtl {shape[1]}", f"f {k + 1} {k + 2} {k + 3}", f"f {k + 1} {k + 3} {k + 4}"]
        else:
            (x, y, z), r = shape[2], shape[3]
            body += [f"usemtl {shape[1]}", f"b {x} {y} {z} {r}"]
    return "\n".join([f"v {x} {y} {z}" for x, y, z in verts] + body) + "\n"


def warp_scene(desc: dict, folder: Path, device: str = "cpu"):
    """Write the description as OBJ/MTL into ``folder`` and load it with warp_spt onto ``device``."""
    from warp_spt import load_scene
    from warp_spt.upload.device_scene import DeviceScene
    (folder / "scene.obj").write_text(obj_text(desc["shapes"]))
    (folder / "scene.mtl").write_text(mtl_text(desc["materials"]))
    return DeviceScene(load_scene([str(folder / "scene.obj")], [str(folder / "scene.mtl")]), device=device)


def warp_settings(desc: dict, size: int, spp: int, integrator: str, sampler: str, seed: int, threads: int) -> dict:
    """RenderSettings fields for one warp_spt render of a scene."""
    from warp_spt import Sky
    return dict(width=size, height=size, spp=spp, max_depth=DEPTH, sky=Sky.constant(*desc["sky"]), seed=seed,
                integrator=integrator, sampler=sampler, threads=threads)


def warp_camera(desc: dict):
    """warp_spt's pinhole camera (horizontal fov in degrees, Z up)."""
    from warp_spt import Camera
    return Camera(**desc["camera"], aperture=0.0, focus=30.0)


def warp_render(scene, desc, size, spp, integrator, sampler, seed, threads) -> np.ndarray:
    """One warp_spt render, float64 linear radiance (H, W, 3)."""
    from warp_spt import RenderSettings, render_scene
    rs = RenderSettings(**warp_settings(desc, size, spp, integrator, sampler, seed, threads))
    return render_scene(scene, warp_camera(desc), rs).image.astype(np.float64)


# ---------------------------------------------------------------------------------------------
# Mitsuba side


def pick_variant() -> str:
    """llvm_ad_rgb when a one-sample render works in a subprocess (an old libLLVM aborts it), else scalar_rgb."""
    probe = ("import mitsuba as mi; mi.set_variant('llvm_ad_rgb'); "
             "mi.render(mi.load_dict(mi.cornell_box()), spp=1)")
    ok = subprocess.run([sys.executable, "-c", probe], capture_output=True).returncode == 0
    return "llvm_ad_rgb" if ok and "llvm_ad_rgb" in mi.variants() else "scalar_rgb"


def rgb(c) -> dict:
    return {"type": "rgb", "value": [float(v) for v in c]}


def mitsuba_bsdf(kind: str, value) -> dict:
    """The Mitsuba BSDF of a material kind (the table in the module docstring)."""
    if kind == "diffuse":
        return {"type": "twosided", "material": {"type": "diffuse", "reflectance": rgb(value)}}
    if kind == "light":
        return {"type": "diffuse", "reflectance": rgb((0, 0, 0))}
    if kind == "mirror":
        return {"type": "conductor", "material": "none", "specular_reflectance": rgb(value)}
    return {"type": "dielectric", "int_ior": float(value), "ext_ior": 1.0}


def mitsuba_scene(desc: dict, folder: Path, size: int, sampler: str, spp: int):
    """The same scene for Mitsuba: one OBJ file per material (face normals keep the quads' winding)."""
    d = {"type": "scene", "integrator": {"type": "path", "max_depth": DEPTH}}
    for name, (kind, value) in desc["materials"].items():
        quads = [s for s in desc["shapes"] if s[0] == "quad" and s[1] == name]
        spheres = [s for s in desc["shapes"] if s[0] == "sphere" and s[1] == name]
        emitter = {"emitter": {"type": "area", "radiance": rgb(value)}} if kind == "light" else {}
        if quads:
            path = folder / f"mi_{name}.obj"
            path.write_text(obj_text([("quad", name, q[2]) for q in quads]).replace(f"usemtl {name}\n", ""))
            d[f"mesh_{name}"] = {"type": "obj", "filename": str(path), "face_normals": True,
                                 "bsdf": mitsuba_bsdf(kind, value), **emitter}
        for k, (_, _, centre, radius) in enumerate(spheres):
            d[f"sphere_{name}_{k}"] = {"type": "sphere", "center": list(centre), "radius": float(radius),
                                       "bsdf": mitsuba_bsdf(kind, value), **emitter}
    if max(desc["sky"]) > 0:
        d["sky"] = {"type": "constant", "radiance": rgb(desc["sky"])}
    cam = desc["camera"]
    origin = np.array(cam["position"], dtype=float)
    target = origin + np.array(cam["direction"], dtype=float)
    d["sensor"] = {
        "type": "perspective", "fov": cam["fov"], "fov_axis": "x",
        "to_world": mi.ScalarTransform4f().look_at(origin=origin.tolist(), target=target.tolist(), up=[0, 0, 1]),
        "sampler": {"type": sampler, "sample_count": spp},
        "film": {"type": "hdrfilm", "width": size, "height": size, "pixel_format": "rgb", "rfilter": {"type": "box"}}}
    return mi.load_dict(d)


def mitsuba_render(scene, spp: int, seed: int, threads: int) -> np.ndarray:
    """One Mitsuba render, evaluated to numpy (float64, H x W x 3), on ``threads`` worker threads."""
    import drjit as dr
    dr.set_thread_count(threads)
    return np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float64)[..., :3]


# ---------------------------------------------------------------------------------------------
# Agreement and efficiency


def block_stats(img: np.ndarray, var: np.ndarray, block: int):
    """Per-block means and their standard errors, from per-pixel variances of the mean."""
    h, w, _ = img.shape
    m = img.reshape(h // block, block, w // block, block, 3).mean(axis=(1, 3))
    v = var.reshape(h // block, block, w // block, block, 3).sum(axis=(1, 3)) / block**4
    return m, np.sqrt(v)


def agreement(name: str, ours, ref_a, ref_b) -> str:
    """One line: warp_spt (render_progressive result) against the Mitsuba reference (two halves), per block."""
    ref = 0.5 * (ref_a + ref_b)
    block = 16 if ref.shape[0] % 16 == 0 else 8
    m_o, se_o = block_stats(ours.image.astype(np.float64), ours.std_error.astype(np.float64) ** 2, block)
    m_r, se_r = block_stats(ref, (ref_a - ref_b) ** 2 / 4, block)
    t = (m_o - m_r) / np.maximum(np.sqrt(se_o**2 + se_r**2), 1e-12)
    n = t.size
    bound = 4.0 + 0.5 * math.log10(n)           # about a 1e-4 family-wise two-sided bound for n tests
    rel = ours.image.mean() / ref.mean() - 1
    h = ref.shape[0] // 2
    quads = [(ours.image[:h, :h].mean(), ref[:h, :h].mean()), (ours.image[:h, h:].mean(), ref[:h, h:].mean()),
             (ours.image[h:, :h].mean(), ref[h:, :h].mean()), (ours.image[h:, h:].mean(), ref[h:, h:].mean())]
    verdict = "agree" if np.abs(t).max() <= bound else "DISAGREE"
    return (f"| {name} | {verdict} | {np.abs(t).max():.2f} (bound {bound:.1f}) | {(np.abs(t) > 3).sum()} / {n} | "
            f"{rel:+.2%} | " + ", ".join(f"{a:.3f}/{b:.3f}" for a, b in quads) + " |")


def efficiency(image: np.ndarray, seconds: float, ref: np.ndarray, ref_mse: float) -> float:
    """1 / (MSE x seconds), the reference's own MSE subtracted (floored so noise cannot make it negative)."""
    mse = max(float(np.mean((image - ref) ** 2)) - ref_mse, 1e-3 * ref_mse, 1e-30)
    return 1.0 / (mse * seconds)


def sampler_spp(sampler: str, spp: int) -> int:
    """Samples per pixel a Mitsuba sampler really takes: the orthogonal sampler rounds up to the square of a
    prime (64 -> 121), so it gets the largest prime square <= spp instead (16 -> 9, 64 -> 49)."""
    if sampler != "orthogonal":
        return spp
    p = int(math.isqrt(spp))
    while p > 2 and any(p % d == 0 for d in range(2, p)):
        p -= 1
    return p * p


def timed(fn, runs: int = 2):
    """(image of the first run, least wall seconds) over ``runs`` runs of ``fn(seed)`` with different seeds."""
    best, first = math.inf, None
    for k in range(runs):
        t = time.perf_counter()
        img = fn(100 + k)
        best = min(best, time.perf_counter() - t)
        first = img if first is None else first
    return first, best


def env_scenes(folder: Path):
    """The envmap scene: (our DeviceScene, our camera, Mitsuba's scene for a sampler and spp, the
    stored reference (mean, per-run 4 x 4 block means))."""
    import warp_spt as ws
    from tests.support import mitsuba_envmap_scene as ES
    from tests.data.make_mitsuba_envmap_refs import synthetic
    from warp_spt.upload.device_scene import DeviceScene
    objs, mtls = ES.write_files(folder)
    host = ws.load_scene(objs, mtls, warn=lambda message: None)
    host.materials.multiscatter[:] = False          # as the stored reference's comparison (test_envmap.py)
    host.sky = ws.Sky.environment(synthetic(), up=(0.0, 1.0, 0.0), background=(0.0, 0.0, 0.0))
    c = ES.CAMERA
    cam = ws.Camera.look_at(c["position"], c["target"], up=c["up"], fov=c["fov"])

    def mitsuba(sampler: str, spp: int):
        d = {"type": "scene", "integrator": {"type": "path", "max_depth": -1, "hide_emitters": True},
             "sensor": {"type": "perspective", "fov": c["fov"], "fov_axis": "x",
                        "to_world": mi.ScalarTransform4f().look_at(origin=c["position"], target=c["target"], up=c["up"]),
                        "film": {"type": "hdrfilm", "width": ES.WIDTH, "height": ES.HEIGHT, "pixel_format": "rgb",
                                 "rfilter": {"type": "box"}},
                        "sampler": {"type": sampler, "sample_count": spp}},
             "sky": {"type": "envmap", "bitmap": mi.Bitmap(synthetic(pole_rows=True))}}
        for (name, _, _, bsdf), f in zip(ES.SPHERES, objs):
            d[name] = {"type": "obj", "filename": f, "face_normals": True, "bsdf": bsdf}
        return mi.load_dict(d)

    with np.load(Path(__file__).resolve().parents[1] / "tests" / "data" / "mitsuba_envmap_refs.npz") as z:
        ref = (z["mean"].astype(np.float64), z["blocks"].astype(np.float64))
    return DeviceScene(host), cam, mitsuba, ref, ES


def run_env_scene(name: str, folder: Path, spps, check_spp: int) -> list:
    """``run_scene`` for the envmap scene (its own size, depth and stored reference)."""
    from dataclasses import replace

    from warp_spt import RenderSettings, render_progressive, render_scene
    sub = folder / name
    sub.mkdir()
    wscene, cam, mitsuba, (ref, runs), ES = env_scenes(sub)
    # as tests/emitters/test_envmap.py: 8 renders of different seeds, block means per render, Welch t against the
    # stored runs' (the sun's rare bright samples make one render's own error estimate too small)
    imgs = [render_scene(wscene, cam, RenderSettings(width=ES.WIDTH, height=ES.HEIGHT, spp=max(1, check_spp // 8),
                                                     max_depth=ES.MAX_DEPTH, seed=300 + k)).image.astype(np.float64)
            for k in range(8)]
    from tests.data.make_mitsuba_envmap_refs import block_means
    from tests.support.stability_scenes import t_quantile
    ob = np.stack([block_means(x) for x in imgs])
    t = (ob.mean(axis=0) - runs.mean(axis=0)) / np.maximum(
        np.sqrt(ob.var(axis=0, ddof=1) / len(ob) + runs.var(axis=0, ddof=1) / len(runs)), 1e-12)
    bound = t_quantile(1e-3 / (2 * t.size), 7)      # the test's bound: Bonferroni, Welch's dof 7
    line = (f"| {name} | {'agree' if np.abs(t).max() <= bound else 'DISAGREE'} | {np.abs(t).max():.2f} (bound "
            f"{bound:.1f}; Welch, dof 7) | {(np.abs(t) > 3).sum()} / {t.size} | "
            f"{np.mean(imgs) / ref.mean() - 1:+.2%} | {ES.WIDTH}x{ES.HEIGHT}, 4x4 blocks, 8 x {max(1, check_spp // 8)} spp "
            f"| stored, 8 x 4096 spp |")
    print(line, flush=True)
    rows, warm = [], {}
    for spp in spps:
        for threads in (1, 2):
            row = dict(scene=name, spp=spp, threads=threads)
            for sampler in MITSUBA_SAMPLERS:
                n = sampler_spp(sampler, spp)
                if (sampler, n) not in warm:
                    warm[sampler, n] = mitsuba(sampler, n)
                    mitsuba_render(warm[sampler, n], n, 99, 2)
                ms = warm[sampler, n]
                img, sec = timed(lambda seed: mitsuba_render(ms, n, seed, threads))
                row[sampler] = (efficiency(img, sec, ref, 0.0), sec)
            for integrator, sampler in ours_pairs():
                rs = RenderSettings(width=ES.WIDTH, height=ES.HEIGHT, spp=spp, max_depth=ES.MAX_DEPTH,
                                    integrator=integrator, sampler=sampler, threads=threads)
                render_scene(wscene, cam, rs)           # compiled before it is timed
                img, sec = timed(lambda seed: render_scene(wscene, cam, replace(rs, seed=seed)).image.astype(np.float64))
                row[f"{integrator}+{sampler}"] = (efficiency(img, sec, ref, 0.0), sec)
            rows.append(row)
    return [line, rows]


def run_scene(name: str, desc: dict, folder: Path, size: int, spps, ref_spp: int, check_spp: int) -> list:
    """Agreement line and efficiency rows (dicts) of one scene."""
    from warp_spt import render_progressive
    if desc.get("env"):
        return run_env_scene(name, folder, spps, check_spp)
    sub = folder / name
    sub.mkdir()
    wscene = warp_scene(desc, sub)
    # ldsampler: at 64 spp Mitsuba's best samplers beat an independent reference of 1024 spp
    ref_scene = mitsuba_scene(desc, sub, size, "ldsampler", ref_spp // 2)
    ref_a, ref_b = (mitsuba_render(ref_scene, ref_spp // 2, seed, 2) for seed in (1, 2))
    ref, ref_mse = 0.5 * (ref_a + ref_b), float(np.mean((ref_a - ref_b) ** 2)) / 4
    ours = render_progressive(wscene, warp_camera(desc), **warp_settings(desc, size, check_spp, "nee", "sobol", 7, 2))
    line = agreement(name, ours, ref_a, ref_b) + f" RMSE {math.sqrt(ref_mse):.1e} |"
    print(line, flush=True)
    rows, warm = [], {}
    for spp in spps:
        for threads in (1, 2):
            row = dict(scene=name, spp=spp, threads=threads)
            for sampler in MITSUBA_SAMPLERS:
                n = sampler_spp(sampler, spp)
                if (sampler, n) not in warm:        # Mitsuba's JIT compiles a kernel once and caches it
                    warm[sampler, n] = mitsuba_scene(desc, sub, size, sampler, n)
                    mitsuba_render(warm[sampler, n], n, 99, 2)
                ms = warm[sampler, n]
                img, sec = timed(lambda seed: mitsuba_render(ms, n, seed, threads))
                row[sampler] = (efficiency(img, sec, ref, ref_mse), sec)
            for integrator, sampler in ours_pairs():
                img, sec = timed(lambda seed: warp_render(wscene, desc, size, spp, integrator, sampler, seed, threads))
                row[f"{integrator}+{sampler}"] = (efficiency(img, sec, ref, ref_mse), sec)
            rows.append(row)
    return [line, rows]


def print_table(rows: list) -> None:
    """The markdown efficiency table, ratios against Mitsuba's best sampler of the same row, and the targets."""
    ours = [f"{i}+{s}" for i, s in ours_pairs()]
    print("\n| scene | spp | threads | " + " | ".join(f"Mitsuba {s}" for s in MITSUBA_SAMPLERS)
          + " | " + " | ".join(f"warp_spt {o}" for o in ours)
          + " | " + " | ".join(f"ratio {o} / best" for o in ours) + " |")
    print("|" + "---|" * (3 + len(MITSUBA_SAMPLERS) + 2 * len(ours)))
    per_scene: dict[str, list[float]] = {}
    for r in rows:
        best = max(r[s][0] for s in MITSUBA_SAMPLERS)
        cells = [f"{r[k][0]:,.3g} ({r[k][1]:.2f} s)" for k in list(MITSUBA_SAMPLERS) + ours]
        ratios = [r[o][0] / best for o in ours]
        per_scene.setdefault(r["scene"], []).append(ratios[0])
        print(f"| {r['scene']} | {r['spp']} | {r['threads']} | " + " | ".join(cells) + " | "
              + " | ".join(f"**{x:.2f}**" if k == 0 else f"{x:.2f}" for k, x in enumerate(ratios)) + " |")
    print("\nTargets (issues 24 and 33), on the geometric mean of each scene's default / best ratios over its rows:\n")
    print("| scene | ratio | target (24) | met | target (33) | met |")
    print("|---|---|---|---|---|---|")
    gm = {s: math.exp(np.mean(np.log(v))) for s, v in per_scene.items()}
    for s, v in gm.items():
        if s in TARGETS:
            print(f"| {s} | {v:.2f} | >= {TARGETS[s]} | {'yes' if v >= TARGETS[s] else 'no'} "
                  f"| >= {TARGETS_33[s]} | {'yes' if v >= TARGETS_33[s] else 'no'} |")
        else:
            print(f"| {s} | {v:.2f} | none | |")
    targeted = [v for s, v in gm.items() if s in TARGETS]      # the geometric mean: the targets' scenes
    if not targeted:
        return
    g = math.exp(np.mean(np.log(targeted)))
    print(f"| geometric mean | {g:.2f} | >= {GEOMEAN_TARGET} | {'yes' if g >= GEOMEAN_TARGET else 'no'} | | |")


# ---------------------------------------------------------------------------------------------
# Whole-process time (issue 24): a fresh process per render, as a user's command runs


_WHOLE_CHILD = """
import os, resource, sys, time
from pathlib import Path
sys.path.insert(0, {bench!r})
import bench_vs_mitsuba as b
if {pythonpath!r}:
    sys.path.insert(0, {pythonpath!r})    # before the checkout bench_vs_mitsuba put first
desc, size, spp, threads, folder = b.SCENES[{scene!r}], {size}, {spp}, {threads}, Path({folder!r})
if {ours}:
    import warp as wp
    wp.config.log_level = wp.LOG_WARNING   # no banner or module-load lines (Warp 1.19 dropped config.quiet)
    from warp_spt import RenderSettings, render_scene
    from warp_spt.samplers import DEFAULT_SAMPLER     # that checkout's default
    scene = b.warp_scene(desc, folder)
    image = render_scene(scene, b.warp_camera(desc), RenderSettings(**b.warp_settings(
        desc, size, spp, "nee", DEFAULT_SAMPLER, 1, threads))).image
else:
    import mitsuba as mi
    mi.set_variant({variant!r})
    b.mi = mi
    image = b.mitsuba_render(b.mitsuba_scene(desc, folder, size, "independent", spp), spp, 1, threads)
r = resource.getrusage(resource.RUSAGE_SELF)
print(sys.modules["warp_spt"].__file__ if {ours} else "", file=sys.stderr)
print(r.ru_utime + r.ru_stime, float(image.mean()))
"""


def whole_process(scene: str, size: int, spp: int, threads: int, repeat: int, variant: str, folder: Path,
                  pythonpath: str | None = None) -> None:
    """Whole-process wall and CPU seconds of one render in a fresh Python process (imports, scene
    load, Warp's cached kernel or Mitsuba's cached JIT kernels, render, image to numpy), warp_spt
    (``nee`` + ``sobol``) against Mitsuba (``independent``, its default sampler), the two taken in
    turn ``repeat`` times after one warm-up each (which fills both kernel caches); medians.
    ``pythonpath``: where warp_spt is imported from (another checkout, for before/after figures)."""
    import os
    import statistics
    env = dict(os.environ)
    if pythonpath:
        env["PYTHONPATH"] = pythonpath
    bench = str(Path(__file__).resolve().parent)
    walls: dict[str, list[float]] = {"warp_spt": [], "Mitsuba": []}
    cpus: dict[str, list[float]] = {"warp_spt": [], "Mitsuba": []}
    for k in range(repeat + 1):
        for who in walls:
            code = _WHOLE_CHILD.format(bench=bench, scene=scene, size=size, spp=spp, threads=threads,
                                       folder=str(folder), ours=who == "warp_spt", variant=variant,
                                       pythonpath=pythonpath or "")
            t = time.perf_counter()
            out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, cwd=folder)
            wall = time.perf_counter() - t
            if out.returncode != 0:
                raise RuntimeError(f"{who} failed: {out.stderr[-2000:]}")
            if k == 0 and who == "warp_spt":
                print(f"warp_spt from {out.stderr.strip().splitlines()[-1]}")
            if k:                              # the first round warms the caches
                walls[who].append(wall)
                cpus[who].append(float(out.stdout.split()[-2]))
    w = {k: statistics.median(v) for k, v in walls.items()}
    c = {k: statistics.median(v) for k, v in cpus.items()}
    print(f"\n## Whole process: {scene}, {size}x{size}, {spp} spp, depth {DEPTH}, {threads} threads, "
          f"median of {repeat} (load average {os.getloadavg()[0]:.1f})\n")
    print("| renderer | wall s | CPU s (all threads) |")
    print("|---|---|---|")
    for who in walls:
        print(f"| {who} | {w[who]:.2f} | {c[who]:.2f} |")
    print(f"| ratio warp_spt / Mitsuba | **{w['warp_spt'] / w['Mitsuba']:.2f}** | "
          f"**{c['warp_spt'] / c['Mitsuba']:.2f}** |")


def reference_check(name: str, desc: dict, folder: Path, size: int, spp: int, seeds: int) -> None:
    """Is the reference's error what its two halves say, and is the ldsampler reference unbiased?
    Renders ``seeds`` images of ``spp`` with Mitsuba's ldsampler and its independent sampler and
    prints, per sampler, the variance of a 16x16 block's mean across seeds over the estimate the
    efficiency table uses (per-pixel (a - b)^2 / 4 of two seeds, pixels taken as independent; about
    1 if that estimate is right), then the per-block t of ldsampler's mean against independent's
    (empirical standard errors over the seeds)."""
    sub = folder / name
    sub.mkdir()
    block, means, ses = 16, {}, {}
    for sampler in ("ldsampler", "independent"):
        scene = mitsuba_scene(desc, sub, size, sampler, spp)
        imgs = [mitsuba_render(scene, spp, 21 + k, 2) for k in range(seeds)]
        _, se_pair = block_stats(0.5 * (imgs[0] + imgs[1]), (imgs[0] - imgs[1]) ** 2 / 4, block)
        bm = np.stack([block_stats(x, np.zeros_like(x), block)[0] for x in imgs])
        ratio = bm.var(axis=0, ddof=1) / np.maximum(2 * se_pair**2, 1e-30)
        means[sampler], ses[sampler] = bm.mean(axis=0), bm.std(axis=0, ddof=1) / math.sqrt(seeds)
        print(f"| {name} | {sampler} | {np.median(ratio):.2f} | {ratio.mean():.2f} | {np.percentile(ratio, 90):.2f} |",
              flush=True)
    t = (means["ldsampler"] - means["independent"]) / np.sqrt(ses["ldsampler"] ** 2 + ses["independent"] ** 2)
    rel = means["ldsampler"].mean() / means["independent"].mean() - 1
    print(f"| {name} | ldsampler against independent | max block |t| {np.abs(t).max():.2f}, |t| > 3: "
          f"{(np.abs(t) > 3).sum()} / {t.size}, mean t {t.mean():+.3f}, whole image {rel:+.3%} | | |", flush=True)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="96^2, 4 and 16 spp, small references")
    ap.add_argument("--scenes", nargs="*", default=list(SCENES), choices=list(SCENES))
    ap.add_argument("--whole-process", action="store_true",
                    help="only the whole-process time of one render per fresh process (default: cornell, 512^2, 16 spp)")
    ap.add_argument("--size", type=int, default=512, help="--whole-process: image size (default 512)")
    ap.add_argument("--spp", type=int, default=16, help="--whole-process: samples per pixel (default 16)")
    ap.add_argument("--threads", type=int, default=2, help="--whole-process: threads (default 2)")
    ap.add_argument("--repeat", type=int, default=3, help="--whole-process: runs of each (default 3)")
    ap.add_argument("--check-reference", action="store_true",
                    help="only check the reference: its error estimate and ldsampler against independent "
                         "(8 renders of 512 spp per sampler and scene)")
    ap.add_argument("--pythonpath", default=None,
                    help="--whole-process: PYTHONPATH of the children (another checkout's warp_spt)")
    args = ap.parse_args()
    global mi
    try:
        import mitsuba as mi
    except ImportError:
        mi = None
    if mi is None:
        print("Mitsuba is not installed: pip install mitsuba to run this benchmark")
        return 0
    if args.whole_process:
        variant = pick_variant()
        print(f"Mitsuba {mi.__version__}, variant {variant}")
        with tempfile.TemporaryDirectory() as tmp:
            for name in (args.scenes if "--scenes" in sys.argv else ["cornell"]):
                if SCENES[name].get("env"):
                    continue
                whole_process(name, args.size, args.spp, args.threads, args.repeat, variant, Path(tmp),
                              args.pythonpath)
        return 0
    variant = pick_variant()
    mi.set_variant(variant)
    mi.set_log_level(mi.LogLevel.Error)       # the orthogonal sampler warns that it rounds 16 spp to 25
    if args.check_reference:
        print(f"Mitsuba {mi.__version__}, variant {variant}; 256x256, 8 renders of 512 spp per sampler\n")
        print("| scene | sampler | block variance / two-half estimate, median | mean | 90th percentile |")
        print("|---|---|---|---|---|")
        with tempfile.TemporaryDirectory() as tmp:
            for name in args.scenes:
                if not SCENES[name].get("env"):         # its reference is stored (tests/data)
                    reference_check(name, SCENES[name], Path(tmp), 256, 512, 8)
        return 0
    import warp as wp
    wp.config.log_level = wp.LOG_WARNING   # no banner or module-load lines (Warp 1.19 dropped config.quiet)
    size, spps, ref_spp, check_spp = (96, (4, 16), 512, 64) if args.quick else (256, (16, 64), 1024, 128)
    print(f"Mitsuba {mi.__version__}, variant {variant}; {size}x{size}, depth {DEPTH}; reference: Mitsuba "
          f"ldsampler {ref_spp} spp (two halves with different seeds); agreement: warp_spt nee+sobol {check_spp} spp\n")
    print("| scene | agreement | max block |t| | blocks |t| > 3 | whole-image mean, ours vs ref | "
          "quadrant means ours/ref (TL, TR, BL, BR) | reference |")
    print("|---|---|---|---|---|---|---|")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for name in args.scenes:
            _, r = run_scene(name, SCENES[name], Path(tmp), size, spps, ref_spp, check_spp)
            rows += r
    print_table(rows)
    return 0


if __name__ == "__main__":
    sys.exit(main())
