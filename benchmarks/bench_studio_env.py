"""The studio look: its key-light sphere and grey sky against a generated soft studio environment.

    python benchmarks/bench_studio_env.py            # a few minutes on 2 shared cores
    python benchmarks/bench_studio_env.py --quick

The question (issue 34): would a generated environment map, importance-sampled, make the first image
of a bare model better than today's studio (``scene/studio.py``: a grey constant sky of 0.2, a
ground, and a key light, an emitting sphere of radius 1.5 R at 3 R from the model, R its bounding
radius)? The criterion is the noise of the first image at equal time, for the same light: the
environments are made to light the model as the studio does, so that only the way the light is
found differs, and the look is then the same (a softer variant is tried too):

* **sphere** (today): ``first_view``'s scene and sky as the command line renders them;
* **env disc**: no sphere; the sky is a map of 0.2 with a disc of the sphere's angular radius (30
  degrees) and radiance (2.0) in the direction of the key from the model (what the sphere subtends
  from the model's centre);
* **env soft**: as "env disc", but the key is a smooth lobe (radiance falling off as cos^8 of the
  angle from the key direction, up to 50 degrees) carrying the same power.

Each is rendered as the command line's first image is (nee + Sobol', depth 6; 96 x 72 here); the
error is the relative RMSE (RMSE over the mean) of the model's and the ground's pixels against a
reference of the same look (2048 spp, two halves of different seeds, its own error subtracted).
Efficiency is 1 / (relative MSE x CPU seconds of one render thread), the least of three runs. The
look is summed up by the references' mean over the model's pixels (a pinhole probe of the model
alone) and over the ground's: issue 22 set the studio's levels for a backdrop darker than the model.
Figures are printed, never asserted.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.support.models import write_model                       # noqa: E402
from warp_spt.upload.device_scene import DeviceScene           # noqa: E402
from warp_spt.emitters import light_table                 # noqa: E402
from warp_spt.emitters.sky import sky_frame               # noqa: E402
from warp_spt.io.loader import load_scene                    # noqa: E402
from warp_spt.rendering.first_view import first_view, probe  # noqa: E402
from warp_spt.rendering.settings import RenderSettings       # noqa: E402
from warp_spt.rendering.tiles import render_scene            # noqa: E402
from warp_spt.scene import studio                            # noqa: E402
from warp_spt.scene.sky import Sky                           # noqa: E402


def texel_directions(h: int, up) -> np.ndarray:
    """(H, 2H, 3) the direction of each texel centre of an H x 2H map about ``up`` (rotation 0), as
    ``emitters.environment`` maps them."""
    t, b, u = sky_frame(up)
    theta = np.pi * (np.arange(h) + 0.5) / h
    psi = 2 * np.pi * (np.arange(2 * h) + 0.5) / (2 * h)
    st, ct = np.sin(theta)[:, None, None], np.cos(theta)[:, None, None]
    sp, cp = np.sin(psi)[None, :, None], np.cos(psi)[None, :, None]
    return t * (-st * sp) - b * (st * cp) + u * ct


def studio_map(key: np.ndarray, up, soft: bool, h: int = 256) -> np.ndarray:
    d = texel_directions(h, up)
    cos = d @ key
    half = np.arcsin(studio.LIGHT_RADIUS / studio.LIGHT_DISTANCE)        # the sphere's angular radius
    disc = np.where(cos >= np.cos(half), studio.LIGHT_EMISSION, 0.0)
    if soft:       # a cos^8 lobe (to 50 degrees) carrying the disc's power (cosine-weighted about the key)
        lobe = np.where(cos >= np.cos(np.radians(50)), np.maximum(cos, 0) ** 8, 0.0)
        sa = (np.pi / h) * (2 * np.pi / (2 * h)) * np.sin(np.pi * (np.arange(h) + 0.5) / h)[:, None]
        disc = lobe * (disc * sa * cos).sum() / (lobe * sa * cos).sum()
    return (np.asarray(studio.SKY)[None, None, :] + disc[..., None]).astype(np.float32)


def looks(folder: Path):
    obj = write_model(folder / "bunny.obj", "bunny", up="y")
    fv = first_view(load_scene([str(obj)]), width=128, height=96)
    assert fv.studio
    sub = fv.scene
    up = np.asarray(fv.camera.up, float)
    light = sub.spheres[-1]
    b = fv.subject.bounds
    key = light[:3] - 0.5 * (b[0] + b[1])
    key = key / np.linalg.norm(key)
    bare = replace(sub, spheres=sub.spheres[:-1], sphere_material=sub.sphere_material[:-1])
    return fv.camera, fv.subject, {"sphere (today)": (sub, fv.sky),
                       "env disc": (bare, Sky.environment(studio_map(key, up, False), up=tuple(up))),
                       "env soft": (bare, Sky.environment(studio_map(key, up, True), up=tuple(up)))}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--quick", action="store_true")
    q = ap.parse_args().quick
    w, h = (64, 48) if q else (96, 72)
    ref_spp, spps = (1024, [4, 16]) if q else (2048, [4, 16, 64])
    with tempfile.TemporaryDirectory() as tmp:
        cam, subject, variants = looks(Path(tmp))
    on_model = probe(subject, cam, w, h).hits.reshape(h, w)         # pixel centres that see the model
    print(f"bare bunny, studio look, {w}x{h}, nee + Sobol', depth 6; reference {ref_spp} spp per look")
    print(f"{'look':16s} {'spp':>4s} {'rel RMSE':>9s} {'CPU s':>7s} {'1/(relMSE s)':>13s} {'mean':>7s} "
          f"{'model':>7s} {'ground':>7s}")
    for name, (scene, sky) in variants.items():
        dev = DeviceScene(scene)
        if name.startswith("sphere"):       # why today's look is noisy: the light table's choice
            table = light_table(dev, sky, tuple(cam.up))
            print(f"  (its light table: key sphere {table.entry_prob.numpy()[0]:.2%} of the light samples, the sky "
                  f"the rest: the sky is weighed by the scene's radius, which the 40 R ground makes large)")
        rs = RenderSettings(width=w, height=h, max_depth=6, sky=sky, threads=1)
        render_scene(dev, cam, replace(rs, spp=1))       # compile
        a = render_scene(dev, cam, replace(rs, spp=ref_spp // 2, seed=1001, threads=None)).image.astype(np.float64)
        b = render_scene(dev, cam, replace(rs, spp=ref_spp // 2, seed=2002, threads=None)).image.astype(np.float64)
        ref = 0.5 * (a + b)
        lum = ref.mean(axis=2)       # the model and the ground: neither the bare sky nor the key itself
        fg = (np.abs(lum - np.mean(studio.SKY)) > 1e-3) & (lum < 0.9 * studio.LIGHT_EMISSION)
        ref_mse = 0.25 * np.mean(((a - b) ** 2)[fg])
        mean = ref[fg].mean()
        look = (ref[fg & on_model].mean(), ref[fg & ~on_model].mean())     # the look: model and ground
        for spp in spps:
            best = None
            for _ in range(3):
                t = time.thread_time()
                img = render_scene(dev, cam, replace(rs, spp=spp, seed=7)).image.astype(np.float64)
                s = time.thread_time() - t
                best = s if best is None else min(best, s)
            rel = max(np.mean(((img - ref) ** 2)[fg]) - ref_mse, 1e-30) / mean ** 2
            print(f"{name:16s} {spp:4d} {np.sqrt(rel):9.4f} {best:7.3f} {1 / (rel * best):13.4g} {mean:7.3f} "
                  f"{look[0]:7.3f} {look[1]:7.3f}")


if __name__ == "__main__":
    main()
