"""Render the Mitsuba 3 reference of the environment-map comparison (tests/emitters/test_envmap.py) into
tests/data/mitsuba_envmap_refs.npz.

Run once, from the repository root (Mitsuba 3 is needed here only):

    PYTHONPATH=$PWD python tests/data/make_mitsuba_envmap_refs.py [--spp 1024] [--batches 8]

The scene is tests/support/mitsuba_envmap_scene.py: three spheres lit by Mitsuba's ``envmap`` emitter with the
synthetic map of scripts/make_test_envmap.py, made at Mitsuba's own row latitudes (``pole_rows``),
hidden from camera rays (``hide_emitters``; ours: a black background).
Rendered as ``--batches`` independently seeded images (``path``, ``independent`` sampler, box
filter, ``scalar_rgb``); stored float32: ``mean`` (the mean image) and ``blocks`` (per batch, the
means of 4 x 4 pixel blocks), and ``settings``, a JSON string of what was run.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from tests.support import mitsuba_envmap_scene as ES

ROOT = Path(__file__).resolve().parents[2]
OUT = Path(__file__).with_name("mitsuba_envmap_refs.npz")
BLOCK = 4


def synthetic(**kw) -> np.ndarray:
    spec = importlib.util.spec_from_file_location("make_test_envmap", ROOT / "scripts" / "make_test_envmap.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.synthetic_envmap(ES.MAP_WIDTH, **ES.SUN, **kw)


def block_means(img: np.ndarray) -> np.ndarray:
    h, w, _ = img.shape
    return img.reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK, 3).mean(axis=(1, 3)).reshape(-1, 3)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--batches", type=int, default=8)
    a = ap.parse_args()
    import mitsuba as mi

    mi.set_variant("scalar_rgb")
    cam = ES.CAMERA
    with tempfile.TemporaryDirectory() as tmp:
        objs, _ = ES.write_files(Path(tmp))
        scene = {
            "type": "scene",
            # camera rays do not see the map (ours: the background, black), so the comparison is of the
            # light it sends through the scene, not of two ways to interpolate a picture
            "integrator": {"type": "path", "max_depth": -1, "hide_emitters": True},
            "sensor": {"type": "perspective", "fov": cam["fov"], "fov_axis": "x",
                       "to_world": mi.ScalarTransform4f().look_at(origin=cam["position"], target=cam["target"],
                                                                  up=cam["up"]),
                       "film": {"type": "hdrfilm", "width": ES.WIDTH, "height": ES.HEIGHT, "pixel_format": "rgb",
                                "rfilter": {"type": "box"}},
                       "sampler": {"type": "independent"}},
            "sky": {"type": "envmap", "bitmap": mi.Bitmap(synthetic(pole_rows=True))},
        }
        for (name, _, _, bsdf), f in zip(ES.SPHERES, objs):
            scene[name] = {"type": "obj", "filename": f, "face_normals": True, "bsdf": bsdf}
        ms = mi.load_dict(scene)
        start = time.perf_counter()
        imgs = np.stack([np.asarray(mi.render(ms, spp=a.spp, seed=2000 + k), dtype=np.float64)
                         for k in range(a.batches)])
    settings = {"spp": a.spp, "batches": a.batches, "variant": "scalar_rgb", "mitsuba": mi.__version__,
                "seconds": round(time.perf_counter() - start, 1), "scene": "tests/support/mitsuba_envmap_scene.py",
                "map": {"width": ES.MAP_WIDTH, **ES.SUN, "pole_rows": True}, "hide_emitters": True}
    np.savez_compressed(OUT, mean=imgs.mean(0).astype(np.float32),
                        blocks=np.stack([block_means(i) for i in imgs]).astype(np.float32),
                        settings=json.dumps(settings))
    print(f"wrote {OUT}: {settings}")


if __name__ == "__main__":
    main()
