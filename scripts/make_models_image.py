"""docs/models.png: a generated Y-up "bunny" as the previous release first showed it, as it does now, and --view left.

The model comes from tests/support/models.py (procedural, no downloaded data). Each panel is one warp-spt
command line run in-process; the commands are printed.

    python scripts/make_models_image.py [--size 240] [--spp 64]
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
from pathlib import Path

import numpy as np
from PIL import Image

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from tests.support.models import write_model  # noqa: E402
from warp_spt.cli.options import parse_args  # noqa: E402
from warp_spt.cli.main import run  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=240)
    ap.add_argument("--spp", type=int, default=64)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        obj = str(write_model(Path(tmp) / "bunny.obj", "bunny", up="y"))
        size = ["-res", str(args.size), str(args.size), "-sr", str(args.spp), "--tonemap", "srgb"]
        panels = [["--up", "z", "--no-studio"],    # before issue 22: Z up, framed, clay on the seed's blue sky
                  [],                              # a new user's first command now
                  ["--view", "left"]]
        images = []
        for k, extra in enumerate(panels):
            out = str(Path(tmp) / f"p{k}.png")
            argv = ["-obj", obj, *extra, *size, "-out", out]
            print("warp-spt " + " ".join(argv).replace(obj, "bunny.obj").replace(out, f"panel{k}.png"))
            run(parse_args(argv), stderr=io.StringIO())
            with Image.open(out) as im:
                images.append(np.asarray(im.convert("RGB")))
    gap = np.full((args.size, 4, 3), 255, np.uint8)
    strip = np.concatenate([images[0], gap, images[1], gap, images[2]], axis=1)
    Image.fromarray(strip).save(ROOT / "docs" / "models.png")
    print("wrote docs/models.png")


if __name__ == "__main__":
    main()
