"""docs/volumes.png: smoke from a NanoVDB grid, fog with light shafts, a glass of red liquid.

The scenes come from scripts/make_smoke.py (procedural, deterministic). Each panel is one warp-spt
command line run in-process; the commands are printed (docs/volumes.md and the README quote them).

    python scripts/make_volumes_image.py [--size 200] [--spp 64]      (the shafts get 4x the samples)
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from scripts.make_smoke import write_scenes  # noqa: E402
from warp_spt.cli.main import run  # noqa: E402
from warp_spt.cli.options import parse_args  # noqa: E402

PANELS = [
    ("smoke", ["-cam", "0", "-6.5", "1.6", "0", "1", "0", "36", "6.5", "0", "-depth", "16",
               "--sky-color", "0.05", "0.06", "0.08"]),
    ("shafts", ["-cam", "0", "-10", "1.4", "0", "1", "0", "40", "10", "0", "-depth", "6",
                "--fog", "sigma_s=0.05", "--fog", "sigma_a=0.004", "--fog", "g=0.6"]),
    ("liquid", ["-cam", "0", "-4.5", "1.8", "0", "1", "-0.3", "36", "4.6", "0", "-depth", "16",
                "--sky-color", "0.3", "0.3", "0.35"]),
]

# fog lit through slats: half of the light samples are blocked, so it takes more samples to settle
SPP_FACTOR = {"shafts": 4}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=200)
    ap.add_argument("--spp", type=int, default=64)
    args = ap.parse_args()
    images = []
    with tempfile.TemporaryDirectory() as tmp:
        write_scenes(Path(tmp), 64)
        for name, extra in PANELS:
            out = str(Path(tmp) / f"{name}.png")
            spp = args.spp * SPP_FACTOR.get(name, 1)
            argv = ["-obj", str(Path(tmp) / f"{name}.obj"), "-mtl", str(Path(tmp) / f"{name}.mtl"), *extra,
                    "-res", str(args.size), str(args.size), "-sr", str(spp), "--tonemap", "srgb", "-out", out]
            print("warp-spt " + " ".join(argv).replace(tmp + "/", "").replace(out, f"{name}.png"))
            start = time.perf_counter()
            status = run(parse_args(argv), stderr=io.StringIO())
            print(f"  status {status}, {time.perf_counter() - start:.1f} s")
            with Image.open(out) as im:
                images.append(np.asarray(im.convert("RGB")))
    gap = np.full((args.size, 4, 3), 255, np.uint8)
    strip = np.concatenate([images[0], gap, images[1], gap, images[2]], axis=1)
    Image.fromarray(strip).save(ROOT / "docs" / "volumes.png")
    print("wrote docs/volumes.png")


if __name__ == "__main__":
    main()
