"""Counts for issue 21's closing note: generated bad (and good) inputs of each class the third
hardening round closed, and how each ended: "ok" (accepted), "clean" (SceneError/ValueError/TypeError
or a one-line CLI error with status 1/2), "other" (anything else: a bug).

    python scripts/fuzz_counts.py [--n 300]
"""

from __future__ import annotations

import argparse
import json
import random
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from warp_spt.scene.errors import SceneError  # noqa: E402

CLEAN = (SceneError, ValueError, TypeError)


def outcome(fn) -> str:
    try:
        fn()
        return "ok"
    except CLEAN:
        return "clean"
    except Exception as err:          # noqa: BLE001 - counted, shown
        print("OTHER:", type(err).__name__, err, file=sys.stderr)
        return "other"


def camera_paths(rng: random.Random, tmp: Path):
    from warp_spt.animation import CameraPath

    atoms = [0, 1, -1, 1e308, 1e309, "x", None, True, [], {}, [0, 0, 0], [0, 1, 0], [1, 2], 10**5000]
    for k in range(ARGS.n):
        keys = [{f: rng.choice(atoms) for f in rng.sample(["frame", "position", "direction", "fov", "focus",
                                                             "aperture"], rng.randint(0, 6))}
                for _ in range(rng.randint(0, 4))]
        good = [{"frame": 4 * i, "position": [rng.uniform(-9, 9), -20, 5], "direction": [0, 1, rng.uniform(-1, 1)],
                 "fov": rng.choice([20, 38, 90])} for i in range(rng.randint(1, 4))]
        doc = rng.choice([{"keyframes": keys}, keys, rng.choice(atoms), "[" * rng.randint(1, 200_000),
                          {"keyframes": good}, good])
        path = tmp / f"p{k}.json"
        try:
            path.write_text(doc if isinstance(doc, str) else json.dumps(doc))
        except ValueError:            # json of 10**5000
            path.write_text('{"keyframes": [{"frame": ' + "9" * 5000 + "}]}")
        yield lambda path=path: CameraPath.load(path)


def templates(rng: random.Random, tmp: Path):
    from warp_spt.io.templates import frame_path

    pieces = ["{frame}", "{frame:04d}", "{frame:013d}", "{frame:999999999d}", "{frame.__class__}", "{frame!r}",
              "{", "}", "{0}", "a", "_", ".obj", "{frame:4d}", "{frame:012d}"]
    for _ in range(ARGS.n):
        t = "".join(rng.choice(pieces) for _ in range(rng.randint(1, 5)))
        yield lambda t=t: frame_path(t, rng.randint(0, 10**9))


def procedural(rng: random.Random, tmp: Path):
    from warp_spt.io.mtl import load_mtl

    keys = {"noise": ["scale", "color1", "color2"], "marble": ["scale", "turbulence", "color1"],
            "wood": ["scale", "rings", "color2"], "grid": ["cells", "width", "line", "fill"]}
    nums = ["0", "1", "-1", "2", "1e20", "1e38", "1e39", "nan", "inf", "0.5", "1e6", "1e7", "1_0", "\u0661"]
    for k in range(ARGS.n):
        name = rng.choice(sorted(keys))
        args = []
        for key in rng.sample(keys[name], rng.randint(0, len(keys[name]))):
            size = 3 if key.startswith(("color", "line", "fill")) else 1
            args.append(f"{key}=" + ",".join(rng.choice(nums) for _ in range(size)))
        tag = rng.choice(["map_Kd", "map_Ke", "map_Ks"])
        path = tmp / f"m{k}.mtl"
        path.write_text(f"newmtl m\n{tag} proc:{name} {' '.join(args)}\n", encoding="utf-8")
        yield lambda path=path: load_mtl(path)


def setters(rng: random.Random, tmp: Path):
    import numpy as np

    import warp_spt
    from warp_spt.scene.validate import validate_scene

    (tmp / "a.obj").write_text("mtllib a.mtl\nusemtl m\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nusemtl lamp\nb 0 0 2 0.5\n")
    (tmp / "a.mtl").write_text("newmtl m\nKd 0.5 0.5 0.5\nmap_Ks proc:noise\nnewmtl lamp\nKe 4 4 4\n")
    params = warp_spt.parameters(warp_spt.load_scene([str(tmp / "a.obj")]), sky=warp_spt.Sky.gradient())
    nums = [0.0, 0.5, 1.0, 1.5, -1.0, 1e30, 2e30, 1e38, 1e39, float("nan"), float("inf")]
    for _ in range(ARGS.n):
        name = rng.choice(params.names())
        shape = params.info(name).shape
        value = np.array([rng.choice(nums) for _ in range(int(np.prod(shape)) or 1)]).reshape(shape)

        def set_and_check(name=name, value=value):
            before = params[name].copy()
            try:
                params[name] = value
            except ValueError:
                state_ok()
                raise
            state_ok()
            params[name] = before

        def state_ok():          # never a scene the loader would refuse: a failure here is "other"
            try:
                validate_scene(params.scene.scene)
                params.camera.validate(8, 8)
            except (SceneError, ValueError) as err:
                raise RuntimeError(f"the setter left an invalid scene: {err}") from None
        yield set_and_check


if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=300, help="cases per class")
    ARGS = parser.parse_args()
    rng = random.Random(21)
    print("| class | cases | ok | clean error | other |\n|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for label, gen in (("camera paths", camera_paths), ("frame templates", templates),
                           ("procedural parameters (MTL)", procedural), ("parameter setters", setters)):
            counts = {"ok": 0, "clean": 0, "other": 0}
            for case in gen(rng, Path(tmp)):
                counts[outcome(case)] += 1
            print(f"| {label} | {sum(counts.values())} | {counts['ok']} | {counts['clean']} | {counts['other']} |")
