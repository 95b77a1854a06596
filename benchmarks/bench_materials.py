"""The cost per sample of the physically based material kind: one scene, once with the seed's
materials and once with ``pbr`` materials of the same roles (same geometry, light, camera, depth).

    PYTHONPATH=$PWD python benchmarks/bench_materials.py              # 96x96, 32 spp, 9 rounds (seconds)
    PYTHONPATH=$PWD python benchmarks/bench_materials.py --quick      # 48x48, 4 spp, 3 rounds

The scene: a ground, three spheres (diffuse / glossy metal / glass) and an area light under a dim
sky. Seed kind: Lambert, the seed's fuzzy mirror, smooth glass. pbr: a rough plastic (roughness 0.6),
rough gold (0.3), rough glass (0.2), the ground a rough plastic (1.0). Each variant compiles its own
kernel first (not timed); then the renders alternate (seed, pbr, seed, pbr, ...) so that a change
in the machine's load falls on both alike; the table gives the median milliseconds per sample per
pixel, the pbr/seed ratio, and the closest-hit rays per sample (how long the paths are: the
materials' albedos differ) with the time per ray. Printed, never asserted.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

import warp as wp  # noqa: E402

wp.config.log_level = wp.LOG_WARNING

from warp_spt.upload.device_scene import DeviceScene  # noqa: E402
from warp_spt.io.loader import load_scene  # noqa: E402
from warp_spt.rendering import tiles as R  # noqa: E402
from warp_spt.rendering.settings import RenderSettings  # noqa: E402
from warp_spt.scene.camera import Camera  # noqa: E402
from warp_spt.scene.sky import Sky  # noqa: E402

OBJ = """v -4 -4 0
v 4 -4 0
v 4 4 0
v -4 4 0
v -1 -1 5
v -1 1 5
v 1 1 5
v 1 -1 5
usemtl ground
f 1 2 3
f 1 3 4
usemtl light
f 5 6 7
f 5 7 8
usemtl diffuse
b -2.2 0 1 1
usemtl metal
b 0 0.5 1 1
usemtl glass
b 2.2 0 1 1
"""

SEED_MTL = """newmtl ground
Kd 0.6 0.6 0.6
Roughness 1
newmtl light
Kd 0 0 0
Kl 8 8 8
Roughness 1
newmtl diffuse
Kd 0.8 0.25 0.1
Roughness 1
newmtl metal
Kd 1 0.766 0.336
Roughness 0
Fuzz 0.3
newmtl glass
Kd 1 1 1
Kt 1 1 1
Kn 1.5
Roughness 0
Refractable
"""

PBR_MTL = """newmtl ground
Kd 0.6 0.6 0.6
Pr 1
newmtl light
Kd 0 0 0
Ks 0
Ke 8 8 8
newmtl diffuse
Kd 0.8 0.25 0.1
Pr 0.6
newmtl metal
Kd 1 0.766 0.336
Pm 1
Pr 0.3
newmtl glass
Kd 1 1 1
Pr 0.2
d 0
Ni 1.5
"""


def cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return "unknown CPU"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, default=96)
    ap.add_argument("--spp", type=int, default=32)
    ap.add_argument("--depth", type=int, default=8)
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--threads", type=int, default=1, help="render threads (1: least disturbed by other jobs)")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args()
    if a.quick:
        a.size, a.spp, a.rounds = 48, 4, 3

    cam = Camera.look_at((0, -9, 3.5), (0, 0, 1), fov=50.0)
    sky = Sky.constant(0.1, 0.1, 0.12)
    folder = Path(tempfile.mkdtemp())
    (folder / "scene.obj").write_text(OBJ)
    devs = {}
    for name, mtl in (("seed", SEED_MTL), ("pbr", PBR_MTL)):
        (folder / f"{name}.mtl").write_text(mtl)
        devs[name] = DeviceScene(load_scene([str(folder / "scene.obj")], [str(folder / f"{name}.mtl")]))
    kinds = {name: dev.features.material_kinds for name, dev in devs.items()}
    assert kinds == {"seed": ("seed",), "pbr": ("pbr",)}, kinds

    def run(dev, spp):
        rs = RenderSettings(width=a.size, height=a.size, spp=spp, max_depth=a.depth, seed=1, sky=sky,
                            integrator="nee", threads=a.threads)
        t = time.perf_counter()
        res = R.render_scene(dev, cam, rs)
        return time.perf_counter() - t, res.stats.rays

    for dev in devs.values():                       # compile and warm up, not timed
        run(dev, 1)
    times = {name: [] for name in devs}
    rays = {}
    for _ in range(a.rounds):
        for name, dev in devs.items():
            secs, rays[name] = run(dev, a.spp)
            times[name].append(secs / a.spp * 1e3)

    print(f"{cpu_model()}; {os.cpu_count()} logical CPUs, {a.threads} render thread(s), load average "
          f"{os.getloadavg()[0]:.2f}")
    print(f"{a.size}x{a.size}, {a.spp} spp, depth {a.depth}, integrator nee, {a.rounds} interleaved rounds")
    print(f"{'materials':<10} {'ms per spp (median)':>20} {'min':>8} {'max':>8} {'ratio':>7} "
          f"{'rays per sample':>16} {'ns per ray':>11}")
    base = statistics.median(times["seed"])
    samples = a.size * a.size * a.spp
    for name, ts in times.items():
        med = statistics.median(ts)
        per_ray = med * 1e-3 * a.spp / rays[name] * 1e9
        print(f"{name:<10} {med:>20.1f} {min(ts):>8.1f} {max(ts):>8.1f} {med / base:>7.2f} "
              f"{rays[name] / samples:>16.2f} {per_ray:>11.0f}")


if __name__ == "__main__":
    main()
