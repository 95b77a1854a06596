"""Write a synthetic equirectangular HDR environment: a sky gradient (blue at the zenith, pale at the
horizon, dark ground) plus a small bright sun-like blob. Used by the tests (written into a temporary
folder) and the environment benchmark; nothing it makes is committed.

    python scripts/make_test_envmap.py out.hdr [--width 256] [--sun-elevation 35] [--sun-azimuth 60]
"""

from __future__ import annotations

import argparse
import sys

import numpy as np


def synthetic_envmap(width: int = 256, sun_elevation: float = 35.0, sun_azimuth: float = 60.0,
                     sun_radius: float = 3.0, sun_radiance: float = 2000.0, pole_rows: bool = False) -> np.ndarray:
    """(width / 2, width, 3) float32 radiance, Z up: row 0 the zenith, column c at the map's azimuth
    psi = 2 pi (c + 0.5) / width, the direction (-sin theta sin psi, -sin theta cos psi, cos theta)
    (warp_spt.scene.environment's convention, Mitsuba's); the sun at elevation ``sun_elevation`` and
    map azimuth ``sun_azimuth`` (degrees: 0 along -Y, 90 along -X), a disc of ``sun_radius``
    degrees whose radiance falls off smoothly to its edge. ``pole_rows``: rows at Mitsuba's latitudes
    (row r at pi r / (H - 1), the first and last at the poles) instead of ours (pi (r + 0.5) / H), so
    that each renderer gets the same sky sampled where it reads it."""
    h = width // 2
    theta = np.pi * np.arange(h) / (h - 1) if pole_rows else np.pi * (np.arange(h) + 0.5) / h
    phi = 2 * np.pi * (np.arange(width) + 0.5) / width
    th, ph = np.meshgrid(theta, phi, indexing="ij")
    z = np.cos(th)
    up = np.clip(z, 0.0, 1.0)[..., None]
    zenith, horizon, ground = np.array([0.25, 0.45, 1.0]), np.array([0.9, 0.95, 1.0]), np.array([0.15, 0.12, 0.1])
    img = np.where(z[..., None] >= 0, horizon + (zenith - horizon) * up ** 0.5, ground)
    d = np.stack([-np.sin(th) * np.sin(ph), -np.sin(th) * np.cos(ph), z], axis=-1)
    el, az = np.radians(sun_elevation), np.radians(sun_azimuth)
    s = np.array([-np.cos(el) * np.sin(az), -np.cos(el) * np.cos(az), np.sin(el)])
    angle = np.degrees(np.arccos(np.clip(d @ s, -1.0, 1.0)))
    blob = np.clip(1.0 - (angle / sun_radius) ** 2, 0.0, 1.0)
    img = img + sun_radiance * blob[..., None] * np.array([1.0, 0.9, 0.75])
    return img.astype(np.float32)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", help="the .hdr (or .pfm, .npy) file to write")
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--sun-elevation", type=float, default=35.0)
    ap.add_argument("--sun-azimuth", type=float, default=60.0)
    a = ap.parse_args(argv)
    img = synthetic_envmap(a.width, a.sun_elevation, a.sun_azimuth)
    if a.out.lower().endswith(".npy"):
        np.save(a.out, img)
    elif a.out.lower().endswith(".pfm"):
        from warp_spt.images.files import save_image
        save_image(a.out, img)
    else:
        from warp_spt.images.hdr import write_hdr
        write_hdr(a.out, img)
    print(f"wrote {a.out} ({img.shape[1]}x{img.shape[0]})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
