"""Noise and tone of the first image (issue 43, item 5): the time and the error of a bare model's
first image at the default 16 spp, raw and denoised (Open Image Denoise, when pyoidn is installed),
against a high-spp reference rendered with another seed (so that its samples are not the 16-spp
image's own), and the share of nearly white pixels of a sunlit scene under each tone curve.

    python benchmarks/bench_first_image.py [--size 192 144] [--ref-spp 1024]

Each render is one warp-spt command run in-process after a warm-up run (kernels compiled); the
times are the whole command's (load, view checks, render, feature buffers, denoise, save). The
errors: RMSE over the image in linear radiance and in filmic display values (0..1), relative RMSE
(RMSE over the reference's mean), and the same at equal time for the raw render (its spp raised to
take the denoised command's time).
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from tests.support.models import write_model  # noqa: E402
from warp_spt.cli.main import run  # noqa: E402
from warp_spt.cli.options import parse_args  # noqa: E402
from warp_spt.images.files import filmic_curve, tonemap_filmic, tonemap_seed  # noqa: E402
from warp_spt.rendering.denoise import available  # noqa: E402


def render(argv: list[str], out: Path) -> tuple[np.ndarray, float]:
    err = io.StringIO()
    t = time.perf_counter()
    if run(parse_args([*argv, "-out", str(out)]), stderr=err) != 0:
        raise SystemExit(err.getvalue())
    return np.load(out), time.perf_counter() - t


def errors(image: np.ndarray, ref: np.ndarray) -> str:
    rmse = float(np.sqrt(np.mean((image - ref) ** 2)))
    shown = float(np.sqrt(np.mean((filmic_curve(image) - filmic_curve(ref)) ** 2)))
    return f"RMSE {rmse:.4f} (relative {rmse / float(ref.mean()):.3f}), display RMSE {shown:.4f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, nargs=2, default=(192, 144))
    ap.add_argument("--ref-spp", type=int, default=1024)
    args = ap.parse_args()
    size = ["-res", str(args.size[0]), str(args.size[1])]
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        obj = str(write_model(d / "bunny.obj", "bunny", up="y"))
        for scene, extra in (("studio", []), ("sun 16", ["--sun", "-0.6", "1.5", "0.4", "--sun-color", "16", "16", "16"])):
            base = ["-obj", obj, *extra, *size]
            render([*base, "-sr", "1"], d / "warm.npy")
            ref, t_ref = render([*base, "-sr", str(args.ref_spp), "--seed", "7"], d / "ref.npy")
            raw, t_raw = render([*base, "-sr", "16"], d / "raw.npy")
            print(f"{scene}, {args.size[0]}x{args.size[1]}; reference {args.ref_spp} spp (seed 7) in {t_ref:.1f} s")
            print(f"  16 spp raw        {t_raw:5.2f} s  {errors(raw, ref)}")
            if available():
                render([*base, "-sr", "16", "--denoise"], d / "warm.npy")
                den, t_den = render([*base, "-sr", "16", "--denoise"], d / "den.npy")
                print(f"  16 spp denoised   {t_den:5.2f} s  {errors(den, ref)}")
                spp = max(16, round(16 * t_den / t_raw))
                same, t_same = render([*base, "-sr", str(spp)], d / "same.npy")
                print(f"  {spp:3d} spp raw       {t_same:5.2f} s  {errors(same, ref)}  (the denoised command's time)")
            else:
                print("  (pyoidn is not installed: pip install \".[denoise]\" for the denoised figures)")
            near = lambda rgb: 100 * float((rgb.max(axis=2) >= 230).mean())     # noqa: E731
            print(f"  nearly white (>= 230 of 255) in the reference: seed curve {near(tonemap_seed(ref)):.1f}%, "
                  f"filmic {near(tonemap_filmic(ref)):.1f}%")


if __name__ == "__main__":
    main()
