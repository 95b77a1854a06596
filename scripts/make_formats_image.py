"""docs/formats.png: the test files of tests/support/format_files.py rendered from their own formats.

Left to right: the PLY pyramid (binary big endian, tristrips) with its vertex colours and
``--filter bilinear``; the glTF textured box (a data-URI PNG, KHR_texture_transform) seen through
the default framing; the glTF scene with two instances of one cube (a parent rotation and a
child scale, and a matrix node). Each panel is one warp-spt command line run in-process, in the
studio look; the commands are printed.

    python scripts/make_formats_image.py [--size 200] [--spp 32]
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

from tests.support.format_files import write_all  # noqa: E402
from warp_spt.cli.main import run  # noqa: E402
from warp_spt.cli.options import parse_args  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=200)
    ap.add_argument("--spp", type=int, default=32)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        write_all(Path(tmp))
        size = ["-res", str(args.size), str(args.size), "-sr", str(args.spp), "--tonemap", "srgb", "--studio"]
        panels = [("pyramid_binary_big_endian.ply", ["--filter", "bilinear", "--up", "z", "--view", "30,30"]),
                  ("textured_box.gltf", []),
                  ("two_instances.gltf", ["--view", "30,25"])]
        images = []
        for k, (name, extra) in enumerate(panels):
            out = str(Path(tmp) / f"p{k}.png")
            argv = ["-obj", str(Path(tmp) / name), *extra, *size, "-out", out]
            print("warp-spt " + " ".join(argv).replace(tmp + "/", "").replace(out, f"panel{k}.png"))
            run(parse_args(argv), stderr=io.StringIO())
            with Image.open(out) as im:
                images.append(np.asarray(im.convert("RGB")))
    gap = np.full((args.size, 4, 3), 255, np.uint8)
    strip = np.concatenate([images[0], gap, images[1], gap, images[2]], axis=1)
    Image.fromarray(strip).save(ROOT / "docs" / "formats.png")
    print("wrote docs/formats.png")


if __name__ == "__main__":
    main()
