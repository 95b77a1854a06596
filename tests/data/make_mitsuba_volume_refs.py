"""Render the Mitsuba 3 references of tests/media/test_volumes_mitsuba.py into tests/data/mitsuba_volume_refs.npz.

Run once, from the repository root (Mitsuba 3 is needed here only, not by the tests):

    PYTHONPATH=$PWD python tests/data/make_mitsuba_volume_refs.py [--spp 1024] [--batches 8]

The scenes (a cube with a pass-through boundary around a homogeneous or a grid medium, under the
area light and sky of tests/support/mitsuba_scenes.py) are defined in tests/support/mitsuba_volume_scenes.py. Each is
rendered as ``--batches`` independently seeded images (Mitsuba's ``volpath``, ``max_depth`` -1 with
its Russian roulette, ``independent`` sampler, box filter, ``llvm_ad_rgb``); stored per scene,
float32: ``NAME_mean`` (32 x 32 x 3) and ``NAME_blocks`` (per batch, the means of 4 x 4 pixel
blocks), and ``settings`` (JSON: spp, batches, variant, Mitsuba's version). Before rendering, the
grid's placement is checked: Mitsuba's gridvolume evaluated at voxel centres gives the voxels.
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from tests.support import mitsuba_scenes as MS
from tests.support import mitsuba_volume_scenes as VS

BLOCK = 4
OUT = Path(__file__).with_name("mitsuba_volume_refs.npz")


def medium(name: str) -> dict:
    import mitsuba as mi

    if name == "homogeneous":
        h = VS.HOMOGENEOUS
        top = max(h["sigma_t"])         # Mitsuba's RGB values lie in [0, 1]: its scale carries the rest
        return {"type": "homogeneous", "scale": top,
                "sigma_t": {"type": "rgb", "value": [v / top for v in h["sigma_t"]]},
                "albedo": {"type": "rgb", "value": list(h["albedo"])}, "phase": {"type": "hg", "g": h["g"]}}
    g = VS.GRID
    rho = VS.density()
    return {"type": "heterogeneous", "scale": g["scale"],
            "sigma_t": {"type": "gridvolume", "grid": mi.VolumeGrid(np.ascontiguousarray(rho.transpose(2, 1, 0)[..., None])),
                        "filter_type": "trilinear", "to_world": _unit_to_cube()},
            "albedo": {"type": "rgb", "value": list(g["albedo"])}, "phase": {"type": "hg", "g": g["g"]}}


def _unit_to_cube():
    import mitsuba as mi

    return mi.ScalarTransform4f().translate([-VS.HALF] * 3) @ mi.ScalarTransform4f().scale(2 * VS.HALF)


def scene_dict(name: str, files: list[str]) -> dict:
    import mitsuba as mi

    cam = MS.CAMERA
    return {
        "type": "scene",
        "integrator": {"type": "volpath", "max_depth": -1},
        "sensor": {
            "type": "perspective", "fov": cam["fov"], "fov_axis": "x",
            "to_world": mi.ScalarTransform4f().look_at(origin=cam["position"], target=cam["target"], up=cam["up"]),
            "film": {"type": "hdrfilm", "width": MS.WIDTH, "height": MS.HEIGHT, "pixel_format": "rgb",
                     "rfilter": {"type": "box"}},
            "sampler": {"type": "independent"},
        },
        "sky": {"type": "constant", "radiance": {"type": "rgb", "value": [MS.SKY] * 3}},
        "cube": {"type": "obj", "filename": files[0], "face_normals": True, "bsdf": {"type": "null"},
                 "interior": medium(name)},
        "light": {"type": "obj", "filename": files[1], "face_normals": True,
                  "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [MS.LIGHT] * 3}},
                  "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0] * 3}}},
    }


def check_grid_placement() -> None:
    """Mitsuba's grid at the world position where ours puts voxel (i, j, k) returns that voxel."""
    import mitsuba as mi

    rho = VS.density()
    vol = mi.load_dict(medium("grid")["sigma_t"])
    n = VS.GRID["n"]
    vs = 2 * VS.HALF / n
    rng = np.random.default_rng(1)
    for _ in range(50):
        i, j, k = rng.integers(2, n - 2, 3)
        it = mi.Interaction3f()
        x, y, z = (float(v) for v in -VS.HALF + vs / 2 + vs * np.array([i, j, k], float))
        it.p = mi.Point3f(x, y, z)
        got = float(np.asarray(vol.eval(it)).ravel()[0])
        assert abs(got - rho[i, j, k]) < 1e-4, (i, j, k, got, rho[i, j, k])


def block_means(img: np.ndarray) -> np.ndarray:
    h, w, _ = img.shape
    return img.reshape(h // BLOCK, BLOCK, w // BLOCK, BLOCK, 3).mean(axis=(1, 3)).reshape(-1, 3)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--spp", type=int, default=1024)
    ap.add_argument("--batches", type=int, default=8)
    ap.add_argument("--variant", default="llvm_ad_rgb")
    args = ap.parse_args()
    import mitsuba as mi

    mi.set_variant(args.variant)
    check_grid_placement()
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in VS.SCENES:
            start = time.perf_counter()
            files, _ = VS.write_files(Path(tmp) / name, name)
            scene = mi.load_dict(scene_dict(name, files))
            imgs = np.stack([np.asarray(mi.render(scene, spp=args.spp, seed=2000 + k), dtype=np.float64)
                             for k in range(args.batches)])
            out[f"{name}_mean"] = imgs.mean(0).astype(np.float32)
            out[f"{name}_blocks"] = np.stack([block_means(i) for i in imgs]).astype(np.float32)
            print(f"{name}: {time.perf_counter() - start:.1f} s, mean {imgs.mean():.4f}")
    out["settings"] = np.asarray(json.dumps({"spp": args.spp, "batches": args.batches, "variant": args.variant,
                                             "mitsuba": mi.__version__, "scenes": list(VS.SCENES)}))
    np.savez_compressed(OUT, **out)
    print(f"wrote {OUT}")


if __name__ == "__main__":
    main()
