"""docs/lights_before_after.png: a bare model with --sun as the previous release rendered it and as it does now.

Before issue 43 a light of the user's turned the studio off: the seed's blue sky, no ground for the
sun's shadow to fall on (what --no-studio renders now). Now the sun is the studio's key: the ground,
a dim grey fill, no key sphere. The model comes from tests/support/models.py (procedural, no
downloaded data); each panel is one warp-spt command line run in-process; the commands are printed.

    python scripts/make_lights_image.py [--size 128] [--spp 64]
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
from warp_spt.cli.main import run  # noqa: E402
from warp_spt.cli.options import parse_args  # noqa: E402

SUN = ["--sun", "-0.6", "1.5", "0.4"]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=128)
    ap.add_argument("--spp", type=int, default=64)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        obj = str(write_model(Path(tmp) / "bunny.obj", "bunny", up="y"))
        size = ["-res", str(args.size), str(args.size), "-sr", str(args.spp)]
        images = []
        for k, extra in enumerate([["--no-studio"], []]):     # before issue 43 (the seed's sky), now
            out = str(Path(tmp) / f"p{k}.png")
            argv = ["-obj", obj, *SUN, *extra, *size, "-out", out]
            print("warp-spt " + " ".join(argv).replace(obj, "bunny.obj").replace(out, f"panel{k}.png"))
            run(parse_args(argv), stderr=io.StringIO())
            with Image.open(out) as im:
                images.append(np.asarray(im.convert("RGB")))
    Image.fromarray(np.concatenate(images, axis=1)).save(ROOT / "docs" / "lights_before_after.png")
    print("wrote docs/lights_before_after.png")


if __name__ == "__main__":
    main()
