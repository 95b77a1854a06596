"""Hashes of images made by a fixed set of commands and API calls: the restructure of the package
(issue 20) must leave every one of them bit-identical (tests/house/test_house_hashes.py).

Made once from the commit before the restructure (0d310d9), with only the public API and the CLI,
which the restructure keeps unchanged::

    git worktree add /tmp/house-base 0d310d9
    cd /tmp/house-base && /work/venv/bin/python /work/main/tests/data/make_house_hashes.py \
        /work/main/tests/data/house_hashes.json

The cases of plugins newer than that commit (``guided``, ``ears``, ``volpath``, ``sobol-affine``) have
no image there; theirs were made from 0c5e386 (the commit before issue 40's move of ``core/``) with
``--only-new``, which renders just the API cases missing from ``house_hashes.json``::

    git worktree add /tmp/house-40 0c5e386
    cd /tmp/house-40 && /work/venv/bin/python /work/main/tests/data/make_house_hashes.py --only-new \
        /work/main/tests/data/house_hashes_0c5e386.json

The test imports ``cases`` from this file and compares each image's hash with the stored one. A hash
covers the exact float32 bytes of the image (and, for gradients, of each gradient array), so any
change of any bit shows. Cases that need the seed's demo (../shared) or Dask are skipped where those
are absent.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

SHARED_DEMO = Path(__file__).resolve().parents[3] / "shared" / "seed" / "demo"
SIZE = ["-res", "24", "24"]


def digest(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a)
        h.update(str(a.dtype).encode() + str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def _cli(args: list[str], cwd: Path, out: Path) -> np.ndarray:
    cmd = [sys.executable, "-m", "warp_spt", *args, "--quiet", "--threads", "2", "-out", str(out)]
    subprocess.run(cmd, cwd=cwd, check=True, env={**os.environ, "PYTHONHASHSEED": "0"})
    return np.load(out)


def _demo_files():
    from warp_spt.demo import demo_files
    return demo_files()


def case_cli_builtin_demo(tmp: Path):
    return digest(_cli([*SIZE, "-sr", "4"], tmp, tmp / "demo.npy"))


def case_cli_seed_demo(tmp: Path):
    if not SHARED_DEMO.is_dir():
        return None
    args = ["-mtl", "testMiku.mtl", "-obj", "cornell_export.obj", "-obj", "baller.obj", "-sky", "1",
            *SIZE, "-sr", "4", "-depth", "8", "--integrator", "seed", "--sampler", "independent"]
    return digest(_cli(args, SHARED_DEMO, tmp / "seed.npy"))


# Issue 22 changed a bare model's defaults (Y up, the studio look, clay for usemtl names no file
# defines); these flags ask the new command for what the old one did unasked. (The old commit
# lacks --no-studio: to regenerate the hashes there, leave them out.)
OLD_BARE_DEFAULTS = ["--up", "z", "--no-studio", "--default-material", "checker"]


def case_cli_bare_model(tmp: Path):
    objs, _ = _demo_files()
    return digest(_cli(["-obj", objs[1], *OLD_BARE_DEFAULTS, *SIZE, "-sr", "4"], tmp, tmp / "bare.npy"))


def case_cli_bare_model_studio(tmp: Path):
    objs, _ = _demo_files()
    return digest(_cli(["-obj", objs[1], "--up", "y", "--studio", *SIZE, "-sr", "4"], tmp, tmp / "studio.npy"))


def case_cli_animation_frame(tmp: Path):
    objs, mtls = _demo_files()
    path = tmp / "path.json"
    path.write_text(json.dumps({"keyframes": [
        {"frame": 0, "position": [4, -55, 16], "direction": [0, 1, 0], "fov": 38, "focus": 27},
        {"frame": 2, "position": [30, -45, 16], "direction": [-0.5, 1, 0], "fov": 30}]}))
    args = ["-mtl", mtls[0], *sum((["-obj", o] for o in objs), []), "--frames", "0:3",
            "--camera-path", str(path), *SIZE, "-sr", "4"]
    cmd = [sys.executable, "-m", "warp_spt", *args, "--quiet", "--threads", "2", "-out", str(tmp / "f_{frame}.npy")]
    subprocess.run(cmd, cwd=tmp, check=True)
    return digest(np.load(tmp / "f_1.npy"))


def _cornell():
    import warp_spt
    objs, mtls = _demo_files()
    scene = warp_spt.load_scene([objs[0]], mtls)
    camera = warp_spt.Camera(position=(4, -55, 16), direction=(0, 1, 0), fov=38, aperture=0.001, focus=27)
    return scene, camera


def api_cases():
    """(name, function of no arguments returning a hash) for the in-process API cases."""
    import warp_spt

    def estimator(integrator, sampler):
        def run():
            scene, camera = _cornell()
            img = warp_spt.render(scene, camera, width=24, height=24, spp=4, max_depth=6, seed=3,
                                  sky=warp_spt.Sky.gradient(), integrator=integrator, sampler=sampler,
                                  threads=2)
            return digest(img)
        return run

    cases = [(f"api_cornell_{i}_{s}", estimator(i, s))
             for i in sorted(warp_spt.INTEGRATORS) for s in sorted(warp_spt.SAMPLERS)]

    def progressive_adaptive():
        scene, camera = _cornell()
        r = warp_spt.render_progressive(scene, camera, width=24, height=24, spp=32, adaptive=True, seed=5,
                                        threads=2)
        return digest(r.image, r.std_error, r.spp)

    def progressive_plain():
        scene, camera = _cornell()
        r = warp_spt.render_progressive(scene, camera, width=24, height=24, spp=16, seed=5, threads=2)
        return digest(r.image, r.std_error)

    def roulette():
        scene, camera = _cornell()
        return digest(warp_spt.render(scene, camera, width=24, height=24, spp=4, roulette_depth=2, seed=2,
                                      threads=2))

    def gradients(mode):
        def run():
            scene, camera = _cornell()
            params = warp_spt.parameters(scene, camera, warp_spt.Sky.gradient())
            wrt = [n for n in params.names() if n.endswith(".diffuse")][:3] + ["sky.zenith"]
            if mode == "tape":
                wrt = wrt[:2]
            r = warp_spt.render_gradients(params, warp_spt.RenderSettings(width=16, height=16, spp=2, max_depth=4,
                                                                         seed=1, threads=2),
                                          loss=warp_spt.losses.l2(np.full((16, 16, 3), 0.25, np.float32)),
                                          wrt=wrt, mode=mode)
            return digest(r.image, *(r.grads[n] for n in wrt if not n.startswith("sky.")))
        return run

    def sky_gradient():
        """The sky's gradient as numbers, not a hash: the lights' restructure (sky colours became a
        device array aliased like a material colour) sums the same adjoints in another order, so
        it agrees with the old commit to float rounding (test: rtol 1e-6), not bit for bit."""
        scene, camera = _cornell()
        params = warp_spt.parameters(scene, camera, warp_spt.Sky.gradient())
        r = warp_spt.render_gradients(params, warp_spt.RenderSettings(width=16, height=16, spp=2, max_depth=4,
                                                                     seed=1, threads=2),
                                      loss=warp_spt.losses.l2(np.full((16, 16, 3), 0.25, np.float32)),
                                      wrt=["sky.zenith", "sky.nadir"], mode="prb")
        return [float(v) for n in ("sky.zenith", "sky.nadir") for v in r.grads[n]]

    def cluster_render():
        try:
            from warp_spt import cluster
        except ImportError:
            return None
        scene, camera = _cornell()
        with cluster.local_client(n_workers=1) as client:
            img = cluster.render(client, scene, camera, width=24, height=24, spp=8, seed=1)
        return digest(img)

    cases += [("api_progressive_adaptive", progressive_adaptive), ("api_progressive_plain", progressive_plain),
              ("api_roulette", roulette), ("api_gradients_prb", gradients("prb")),
              ("api_gradients_tape", gradients("tape")), ("api_gradients_sky", sky_gradient),
              ("api_cluster", cluster_render)]
    return cases


def cli_cases():
    return [("cli_builtin_demo", case_cli_builtin_demo), ("cli_seed_demo", case_cli_seed_demo),
            ("cli_bare_model", case_cli_bare_model), ("cli_bare_model_studio", case_cli_bare_model_studio),
            ("cli_animation_frame", case_cli_animation_frame)]


def main(out: str, only_new: bool = False) -> None:
    """Hash every case into ``out``; with ``only_new``, only the API cases house_hashes.json lacks."""
    hashes = {}
    old = json.loads(Path(__file__).with_name("house_hashes.json").read_text()) if only_new else {}
    if not only_new:
        with tempfile.TemporaryDirectory() as tmp:
            for name, fn in cli_cases():
                d = Path(tmp) / name
                d.mkdir()
                hashes[name] = fn(d)
                print(name, hashes[name], flush=True)
    for name, fn in api_cases():
        if name not in old:
            hashes[name] = fn()
            print(name, hashes[name], flush=True)
    Path(out).write_text(json.dumps(hashes, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main(sys.argv[-1], only_new="--only-new" in sys.argv[1:-1])
