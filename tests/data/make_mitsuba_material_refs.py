"""Render the Mitsuba 3 references of tests/bsdfs/test_materials_mitsuba.py into tests/data/mitsuba_material_refs.npz.

Run once, from the repository root (Mitsuba 3 is needed here only, not by the tests):

    PYTHONPATH=$PWD python tests/data/make_mitsuba_material_refs.py [--spp 4096] [--batches 8]

The scenes (geometry as OBJ files written here, the same files warp_spt reads; camera, light, sky,
depth; the BSDF matched to ours) are defined in tests/support/mitsuba_scenes.py. Each scene is rendered as
``--batches`` independently seeded images of ``--spp`` samples (Mitsuba's ``path`` integrator,
``independent`` sampler, box pixel filter, ``scalar_rgb``); stored per scene, float32:

* ``NAME_mean``: the mean image (32 x 32 x 3), for the figures;
* ``NAME_blocks``: per batch, the means of 4 x 4 pixel blocks (batches x 64 x 3), so the test has
  the reference's own error (their spread) without storing every batch;

and ``settings``, a JSON string of what was run (spp, batches, variant, Mitsuba's version, scenes).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from tests.support import mitsuba_scenes as MS

BLOCK = 4
OUT = Path(__file__).with_name("mitsuba_material_refs.npz")


def mitsuba_dict(scene: MS.MitsubaScene, files: list[str]) -> dict:
    import mitsuba as mi

    cam = MS.CAMERA
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": -1},
        "sensor": {
            "type": "perspective", "fov": cam["fov"], "fov_axis": "x",
            "to_world": mi.ScalarTransform4f().look_at(origin=cam["position"], target=cam["target"], up=cam["up"]),
            "film": {"type": "hdrfilm", "width": MS.WIDTH, "height": MS.HEIGHT, "pixel_format": "rgb",
                     "rfilter": {"type": "box"}},
            "sampler": {"type": "independent"},
        },
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [MS.SKY] * 3}},
        "object": {"type": "obj", "filename": files[0], "face_normals": True, "bsdf": scene.bsdf},
        "light": {"type": "obj", "filename": files[1], "face_normals": True,
                  "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [MS.LIGHT] * 3}},
                  "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}}},
    }


def block_means(img: np.ndarray) -> np.ndarray:
    h, w, _ = img.shape
    return img.reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK, 3).mean(axis=(1, 3)).reshape(-1, 3)


def render(scene: MS.MitsubaScene, spp: int, batches: int, folder: Path) -> tuple[np.ndarray, np.ndarray]:
    import mitsuba as mi

    objs, _ = MS.write_files(folder / scene.name, scene)
    ms = mi.load_dict(mitsuba_dict(scene, objs))
    imgs = np.stack([np.asarray(mi.render(ms, spp=spp, seed=1000 + k), dtype=np.float64) for k in range(batches)])
    return imgs.mean(0).astype(np.float32), np.stack([block_means(i) for i in imgs]).astype(np.float32)


def plastic_scale(n: int = 1 << 16) -> float:
    """(1 - specular albedo) / diffuse albedo of Mitsuba's roughplastic with a white base, at normal
    incidence: the factor that makes its white base conserve energy (tests/support/mitsuba_scenes.py).
    Cosine-weighted stratified directions; the diffuse part is the white base's BSDF minus the black's."""
    import mitsuba as mi

    white = mi.load_dict(MS._roughplastic([1.0] * 3))
    black = mi.load_dict(MS._roughplastic([0.0] * 3))
    si = mi.SurfaceInteraction3f()
    si.sh_frame = mi.Frame3f([0.0, 0.0, 1.0])
    si.wi = [0.0, 0.0, 1.0]
    ctx = mi.BSDFContext()
    side = int(np.sqrt(n))
    rng = np.random.default_rng(5)
    diffuse = spec = 0.0
    for i in range(side):
        for j in range(side):
            u1, u2 = (i + rng.random()) / side, (j + rng.random()) / side
            r, ph = np.sqrt(u1), 2.0 * np.pi * u2
            wo = mi.Vector3f(r * np.cos(ph), r * np.sin(ph), np.sqrt(max(0.0, 1.0 - u1)))
            cos = max(float(wo[2]), 1e-12)
            fb = float(black.eval(ctx, si, wo)[0]) / cos * np.pi       # f cos / (cos / pi)
            spec += fb
            diffuse += float(white.eval(ctx, si, wo)[0]) / cos * np.pi - fb
    diffuse, spec = diffuse / side**2, spec / side**2
    return (1.0 - spec) / diffuse


def masking_difference(ax: float, ay: float, mu: float, n: int = 1 << 20) -> tuple[float, float]:
    """Directional albedo (F = 1) at ``mu`` of a GGX lobe with height-correlated Smith masking (ours)
    and with separable masking (Mitsuba's), by numpy: microfacet normals m drawn from D(m) m.z (the
    slopes of the alpha = 1 distribution, stretched by the alphas), so f cos / pdf = G (wo.m) / (wo.z m.z)."""
    rng = np.random.default_rng(3)
    u1, u2 = rng.random(n), rng.random(n)
    ph = 2 * np.pi * u2
    t = np.sqrt(u1 / (1 - u1))
    m = np.stack([ax * t * np.cos(ph), ay * t * np.sin(ph), np.ones(n)], -1)
    m /= np.linalg.norm(m, axis=-1, keepdims=True)
    wo = np.array([np.sqrt(1 - mu * mu), 0.0, mu])
    wi = 2 * (m @ wo)[:, None] * m - wo
    ok = (wi[:, 2] > 0) & ((m @ wo) > 0)

    def lam(w):
        return 0.5 * (np.sqrt(1 + (ax**2 * w[..., 0] ** 2 + ay**2 * w[..., 1] ** 2) / w[..., 2] ** 2) - 1)

    lo, li = lam(wo), lam(np.where(ok[:, None], wi, [0, 0, 1]))
    w = np.where(ok, (m @ wo) / (mu * m[:, 2]), 0.0)
    return float(np.mean(w / (1 + lo + li))), float(np.mean(w / ((1 + lo) * (1 + li))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spp", type=int, default=4096, help="samples per pixel of each batch")
    ap.add_argument("--batches", type=int, default=8)
    ap.add_argument("--variant", default="scalar_rgb")
    ap.add_argument("--only", nargs="*", help="scene names (default: all, alternatives included)")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--check-plastic", action="store_true", help="only print the plastic's diffuse scale")
    ap.add_argument("--masking", action="store_true",
                    help="only print how much separable masking (Mitsuba) loses against height-correlated (ours)")
    a = ap.parse_args()
    if a.masking:
        for what, ax, ay in (("gold, glass (r 0.3)", 0.09, 0.09), ("gold_rough (r 0.5)", 0.25, 0.25),
                             ("brushed", 0.4624, 0.16), ("plastic (r 0.4)", 0.16, 0.16)):
            cells = []
            for mu in (1.0, 0.5, 0.2):
                hc, sep = masking_difference(ax, ay, mu)
                cells.append(f"mu {mu}: {hc:.4f} vs {sep:.4f} ({sep / hc - 1:+.2%})")
            print(f"{what:<20} alpha ({ax}, {ay}): " + "; ".join(cells))
        return

    import mitsuba as mi

    mi.set_variant(a.variant)
    k = plastic_scale()
    print(f"roughplastic's white-base diffuse scale: {k:.4f} (tests/support/mitsuba_scenes.py: {MS.PLASTIC_DIFFUSE_SCALE})")
    if a.check_plastic:
        return
    if abs(k / MS.PLASTIC_DIFFUSE_SCALE - 1.0) > 0.002:
        raise SystemExit("PLASTIC_DIFFUSE_SCALE is off: set it to the value above")
    scenes = [s for s in MS.SCENES + MS.ALTERNATIVES if not a.only or s.name in a.only]
    data: dict[str, np.ndarray] = {}
    if a.out.exists():                      # --only re-renders some scenes and keeps the others
        data = dict(np.load(a.out))
    settings = json.loads(str(data["settings"])) if "settings" in data else {"scenes": {}}
    settings.update(plastic_diffuse_scale=k, spp=a.spp, batches=a.batches, variant=a.variant,
                    mitsuba=mi.__version__, block=BLOCK,
                    width=MS.WIDTH, height=MS.HEIGHT, camera=MS.CAMERA, sky=MS.SKY, light=MS.LIGHT,
                    integrator="path, max_depth -1 (Russian roulette from depth 5)")
    with tempfile.TemporaryDirectory() as tmp:
        for s in scenes:
            t0 = time.perf_counter()
            mean, blocks = render(s, a.spp, a.batches, Path(tmp))
            data[f"{s.name}_mean"], data[f"{s.name}_blocks"] = mean, blocks
            settings["scenes"][s.name] = {"mtl": s.mtl, "bsdf": s.bsdf, "note": s.note,
                                          "spp": a.spp, "batches": a.batches}
            rel = blocks.mean(1).std(0, ddof=1).mean() / np.sqrt(a.batches) / blocks.mean()
            print(f"{s.name}: mean {mean.mean(axis=(0, 1)).round(4)}, whole-image relative standard error "
                  f"{rel:.2e}, {time.perf_counter() - t0:.0f} s", flush=True)
    data["settings"] = np.array(json.dumps(settings, default=list))
    np.savez_compressed(a.out, **data)
    print(f"wrote {a.out} ({a.out.stat().st_size / 1024:.0f} KB)")


if __name__ == "__main__":
    main()
