#!/usr/bin/env python3
"""Render the README's environment-map figure: three spheres (grey, rough gold, rough glass) on a
ground, lit only by the synthetic sun + sky HDR of scripts/make_test_envmap.py, sampled uniformly
(left) and by importance (right) at equal render time.

    python scripts/make_envmap_figure.py [--width 240] [--spp 32] [--out docs/envmap_sampling.png]

The importance-sampled panel gets ``--spp``; the uniform panel as many samples (in passes of 2) as
fit in the time the first took (measured here, printed).
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import warp_spt as ws  # noqa: E402
from warp_spt.images.files import to_display  # noqa: E402
from warp_spt.scene.environment import EnvironmentMap  # noqa: E402
from tests import mitsuba_envmap_scene as ES  # noqa: E402  (the spheres of the Mitsuba comparison)

GROUND = "v -30 -1 -30\nv 30 -1 -30\nv 30 -1 30\nv -30 -1 30\nusemtl ground\nf 1 4 3\nf 1 3 2\n"


def synthetic(width: int) -> np.ndarray:
    spec = importlib.util.spec_from_file_location("make_test_envmap", REPO / "scripts" / "make_test_envmap.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod.synthetic_envmap(width, sun_elevation=35.0, sun_azimuth=150.0, sun_radius=2.0, sun_radiance=4000.0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=240)
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--out", default=str(REPO / "docs" / "envmap_sampling.png"))
    a = ap.parse_args()
    w, h = a.width, a.width // 2
    img = synthetic(1024)
    with tempfile.TemporaryDirectory() as tmp:
        objs, mtls = ES.write_files(Path(tmp))
        (Path(tmp) / "ground.obj").write_text(GROUND)
        with open(mtls[0], "a") as f:
            f.write("\nnewmtl ground\nKd 0.5 0.5 0.5\nKs 0\nPm 0\nPr 1\n")
        scene = ws.load_scene(objs + [str(Path(tmp) / "ground.obj")], mtls, warn=lambda m: None)
    c = ES.CAMERA
    cam = ws.Camera.look_at(c["position"], c["target"], up=c["up"], fov=c["fov"])
    panels, labels = [], []
    seconds = None
    for sampling in ("importance", "uniform"):
        scene.sky = ws.Sky.environment(EnvironmentMap(img, "synthetic sun + sky", sampling), up=(0.0, 1.0, 0.0))
        rs = ws.RenderSettings(width=w, height=h, spp=1, max_depth=8)
        ws.render_scene(scene, cam, rs)                                  # compile and upload
        # passes of 2 spp (disjoint sample ranges, averaged): the importance panel until --spp, the
        # uniform panel until it has taken as long
        total, spp, took = np.zeros((h, w, 3)), 0, 0.0
        while (spp < a.spp) if seconds is None else (took < seconds):
            t = time.perf_counter()
            res = ws.render_scene(scene, cam, ws.RenderSettings(width=w, height=h, spp=2, sample_offset=spp,
                                                                max_depth=8))
            took += time.perf_counter() - t
            total += res.image
            spp += 2
        seconds = seconds or took
        print(f"{sampling}: {spp} spp in {took:.1f} s")
        panels.append(Image.fromarray(to_display((total / (spp // 2)).astype(np.float32), "srgb")))
        labels.append(f"{sampling} sampling, {spp} spp, {took:.1f} s")
    out = Image.new("RGB", (2 * w, h + 18), "white")
    draw = ImageDraw.Draw(out)
    for i, (p, text) in enumerate(zip(reversed(panels), reversed(labels))):
        out.paste(p, (i * w, 0))
        draw.text((i * w + 4, h + 3), text, fill="black")
    out.save(a.out)
    print(f"wrote {a.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
