"""The demo animation: the built-in vase twisting over 24 frames while the camera swings around it.

Writes one vase OBJ per frame (``sculpture_{frame:02d}.obj``, from scripts/make_demo.py with a
twist) and a JSON camera path next to the demo's other files, then renders them through
``warp_spt.animation.render_animation`` (on a local Dask cluster with ``--workers N``) into a GIF.

    python scripts/make_animation.py                      # docs/animation.gif, 192x192, 24 spp
    python scripts/make_animation.py --workers 2 --size 320 --spp 64 --out anim.gif
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "scripts"))
sys.path.insert(0, str(REPO))

import make_demo  # noqa: E402

import warp_spt  # noqa: E402
from warp_spt.animation import CameraPath, render_animation  # noqa: E402
from warp_spt.images.files import save_gif  # noqa: E402

FRAMES = 24
MAX_TWIST = 0.9            # radians of the rim against the foot, at the extremes of the loop
ORBIT_RADIUS = 40.0
SWING_DEG = 22.0           # the camera swings this far either side of straight ahead
TARGET = (make_demo.VASE_CENTRE[0], make_demo.VASE_CENTRE[1], 8.0)


def twist(frame: int) -> float:
    """The vase's twist at ``frame``: one full back-and-forth over the loop, so the GIF loops."""
    return MAX_TWIST * math.sin(2.0 * math.pi * frame / FRAMES)


def camera_path(step: int = 3) -> dict:
    """Keyframes every ``step`` frames on a circle around the vase, looking at its middle."""
    keys = []
    for f in range(0, FRAMES + 1, step):
        a = math.radians(-90.0 + SWING_DEG * math.sin(2.0 * math.pi * f / FRAMES))
        pos = (TARGET[0] + ORBIT_RADIUS * math.cos(a), TARGET[1] + ORBIT_RADIUS * math.sin(a), 12.0)
        d = [t - p for t, p in zip(TARGET, pos)]
        keys.append({"frame": f, "position": [round(x, 4) for x in pos], "direction": [round(x, 4) for x in d],
                     "fov": 34.0, "focus": round(math.dist(pos, TARGET), 4), "aperture": 0.05})
    return {"keyframes": keys}


def write_scene(folder: Path) -> tuple[list[str], list[str]]:
    """The demo's static files, the per-frame vases and the camera path; returns (objs, mtls)."""
    make_demo.generate(folder)
    for k in range(FRAMES):
        (folder / f"sculpture_{k:02d}.obj").write_text(make_demo.vase_obj(twist(k)), encoding="ascii")
    (folder / "camera_path.json").write_text(json.dumps(camera_path(), indent=1))
    objs = [str(folder / "cornell.obj"), str(folder / "sculpture_{frame:02d}.obj"), str(folder / "spheres.obj")]
    return objs, [str(folder / "demo.mtl")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "animation.gif")
    parser.add_argument("--size", type=int, default=192)
    parser.add_argument("--spp", type=int, default=24)
    parser.add_argument("--workers", type=int, default=0, help="local Dask worker processes (0: render here)")
    parser.add_argument("--keep", type=Path, help="keep the scene files and camera path in this folder")
    args = parser.parse_args()
    folder = Path(args.keep or tempfile.mkdtemp(prefix="warp_spt_anim_"))
    try:
        objs, mtls = write_scene(folder)
        path = CameraPath.load(folder / "camera_path.json")
        kw = dict(width=args.size, height=args.size, spp=args.spp, max_depth=6, sky=warp_spt.Sky.gradient(),
                  seed=1)
        start = time.perf_counter()
        if args.workers:
            from warp_spt import cluster
            with cluster.local_client(args.workers) as client:
                frames = dict(render_animation(objs, mtls, range(FRAMES), path, client=client, progress=True, **kw))
        else:
            frames = dict(render_animation(objs, mtls, range(FRAMES), path, progress=True, **kw))
        save_gif(args.out, [frames[k] for k in range(FRAMES)], fps=12, tonemap="srgb")
        print(f"{args.out}: {FRAMES} frames of {args.size}x{args.size}, {args.spp} spp in "
              f"{time.perf_counter() - start:.0f} s, {args.out.stat().st_size:,} bytes")
    finally:
        if not args.keep:
            shutil.rmtree(folder, ignore_errors=True)


if __name__ == "__main__":
    main()
