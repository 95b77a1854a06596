"""The viewer's moving preview at equal samples: its error against a converged image, per preview_scale.

    python scripts/measure_viewer_preview.py                  # the built-in demo at 384 x 288
    python scripts/measure_viewer_preview.py --size 512 384 --trials 8 --figure docs/viewer_preview.png

Each preview_scale is rendered as the session plans it (``viewer.session.preview_plan``: the view's
size over preview_scale, one sample per 16 view pixels), tone mapped and stretched over the view as
the page draws it, and compared with the mean of two 64-spp renders of the view (their own noise
taken off: tests/support/preview_error.py). Prints one row per scale: size, spp, samples, RMS error
(mean over seeds, its standard error) as rendered and as the page draws it (through the session's
3x3 median), and the median render time; ``--figure`` writes the 1/4-size 1-spp preview as it was
drawn, the default one as it is drawn now, and the converged view side by side.
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

import warp_spt
from warp_spt.demo import demo_files
from warp_spt.scene.camera import Camera
from warp_spt.upload.device_scene import DeviceScene
from warp_spt.viewer.session import ViewSettings, preview_plan

from tests.support.preview_error import Reference, plan_error, render, shown


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", nargs=2, type=int, default=(384, 288), metavar=("W", "H"))
    ap.add_argument("--trials", type=int, default=8)
    ap.add_argument("--reference-spp", type=int, default=64)
    ap.add_argument("--scales", nargs="+", type=int, default=[4, 6, 8, 12, 16])
    ap.add_argument("--figure", metavar="PNG")
    args = ap.parse_args()
    view = tuple(args.size)
    objs, mtls = demo_files()
    dev = DeviceScene(warp_spt.load_scene(objs, mtls, default_material="auto"))
    camera, base = Camera(), ViewSettings(width=view[0], height=view[1])
    common = dict(max_depth=base.max_depth, sky=warp_spt.Sky.black(), integrator=base.integrator,
                  sampler=base.sampler)
    reference = Reference(dev, camera, view, args.reference_spp, base.tonemap, **common)
    print(f"view {view[0]}x{view[1]}, reference 2 x {args.reference_spp} spp (its own RMS noise "
          f"{np.sqrt(reference.noise_ms):.4f}, taken off); {args.trials} seeds per row")
    print("preview_scale | preview | spp | samples | RMS error as rendered | as drawn (3x3 median) | median seconds")
    plans = {}
    for scale in args.scales:
        w, h, spp = preview_plan(replace(base, preview_scale=scale))
        r = plan_error(dev, camera, reference, (w, h), spp, args.trials, **common)
        plans[scale] = (w, h, spp)
        print(f"{scale}{' (default)' if scale == base.preview_scale else ''} | {w}x{h} | {spp} | {r['samples']} | "
              f"{r['raw']:.4f} +- {r['raw_se']:.4f} | {r['shown']:.4f} +- {r['shown_se']:.4f} | {r['seconds']:.4f}")
    if args.figure:
        write_figure(args.figure, dev, camera, view, reference,
                     [(*plans[4], False), (*plans[base.preview_scale], True)], common)


def write_figure(path: str, dev, camera, view, reference: Reference, plans, common) -> None:
    from PIL import Image, ImageDraw

    panels, labels = [], []
    for w, h, spp, despeckle in plans:
        image, _ = render(dev, camera, (w, h), spp, 0, **common)
        panels.append(shown(image, view, reference.tonemap, despeckle))
        labels.append(f"{w}x{h}, {spp} spp{', 3x3 median' if despeckle else ''}: "
                      f"RMS error {reference.rmse(image, despeckle):.3f}")
    panels.append(reference.image)
    labels.append("converged")
    strip = np.concatenate([np.pad(p, ((0, 22), (4, 4), (0, 0))) for p in panels], axis=1)
    img = Image.fromarray((np.clip(strip, 0, 1) * 255 + 0.5).astype(np.uint8))
    draw = ImageDraw.Draw(img)
    for k, label in enumerate(labels):
        draw.text((k * (view[0] + 8) + 8, view[1] + 5), label, fill=(230, 230, 230))
    img.save(path)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
