#!/usr/bin/env python3
"""Render the README's images: the gallery (the built-in demo) and the seed-versus-us comparison.

    python scripts/make_docs_images.py [--size 800] [--spp 256] [--only gallery|compare]

``docs/gallery.png`` is the built-in demo, rendered by this project. ``docs/seed_vs_warp_spt.png`` puts
the seed's own ``512p16s.png`` (from ../shared/seed/demo) next to our render of the seed's demo command
line, without its missing character model; it is skipped when ../shared is absent.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import warp  # noqa: E402

from warp_spt.demo import PRESETS, demo_files  # noqa: E402
from warp_spt.images.files import save_image, tonemap_seed  # noqa: E402
from warp_spt.io.loader import load_scene  # noqa: E402
from warp_spt.rendering.tiles import render  # noqa: E402
from warp_spt.scene.camera import Camera  # noqa: E402  (after the path set-up, to use this checkout)
from warp_spt.scene.sky import Sky  # noqa: E402

warp.config.log_level = warp.LOG_WARNING   # no banner or kernel-load lines between the progress bars

SEED_DEMO = REPO.parent / "shared" / "seed" / "demo"
DOCS = REPO / "docs"


def gallery(size: int, spp: int) -> Path:
    """The built-in demo with the seed's preset settings (gradient sky, depth 8) at ``size``, ``spp``."""
    objs, mtls = demo_files()
    preset = PRESETS["512p16s"]
    img = timed(f"gallery {size}x{size}, {spp} spp", lambda: render(
        load_scene(objs, mtls), Camera(), width=size, height=size, spp=spp, max_depth=preset.depth,
        sky=Sky.from_index(preset.sky), progress=True))
    out = DOCS / "gallery.png"
    save_image(out, img, tonemap="seed")
    return out


def comparison() -> Path | None:
    """The seed's 512p16s.png beside our render of the same command line (seed tone map)."""
    reference = SEED_DEMO / "512p16s.png"
    if not reference.is_file():
        print(f"skipping the comparison: {reference} not found")
        return None
    panels = [(None, "seed (Java), 512p16s.png")]
    for mtl, label in (("testMiku.mtl", "warp_spt, the same command line (Kn 0.5)"),
                       ("testMiku_ior1.62.mtl", "warp_spt, the other shipped MTL (Kn 1.62)")):
        here = os.getcwd()
        os.chdir(SEED_DEMO)   # the seed's MTL names textures relative to the working directory
        try:
            scene = load_scene(["cornell_export.obj", "baller.obj"], [mtl])
        finally:
            os.chdir(here)
        img = timed(f"seed demo with {mtl}, 512x512, 16 spp", lambda: render(
            scene, Camera(), width=512, height=512, spp=16, max_depth=8, sky=Sky.gradient(), progress=True))
        panels.append((Image.fromarray(tonemap_seed(img)), label))
    with Image.open(reference) as im:
        panels[0] = (im.convert("RGB"), panels[0][1])
    out = DOCS / "seed_vs_warp_spt.png"
    side_by_side(panels).save(out)
    return out


def side_by_side(panels: list[tuple[Image.Image, str]], gap: int = 8, caption: int = 24) -> Image.Image:
    """Panels in a row on white, each with a caption above it."""
    w = sum(p.width for p, _ in panels) + gap * (len(panels) + 1)
    h = max(p.height for p, _ in panels) + caption + 2 * gap
    sheet = Image.new("RGB", (w, h), "white")
    draw = ImageDraw.Draw(sheet)
    x = gap
    for image, label in panels:
        draw.text((x, gap // 2 + 4), label, fill="black")
        sheet.paste(image, (x, gap + caption))
        x += image.width + gap
    return sheet


def timed(what: str, fn):
    start = time.perf_counter()
    result = fn()
    print(f"{what}: {time.perf_counter() - start:.1f} s")
    return np.asarray(result)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=800, help="gallery image size (default 800)")
    parser.add_argument("--spp", type=int, default=256, help="gallery samples per pixel (default 256)")
    parser.add_argument("--only", choices=("gallery", "compare"), help="make just one of the two images")
    args = parser.parse_args()
    DOCS.mkdir(exist_ok=True)
    if args.only in (None, "gallery"):
        print("wrote", gallery(args.size, args.spp))
    if args.only in (None, "compare"):
        out = comparison()
        if out:
            print("wrote", out)


if __name__ == "__main__":
    main()
