"""The pbr kind against Mitsuba 3: the same scenes, Mitsuba's images stored (tests/data/mitsuba_material_refs.npz,
made by tests/data/make_mitsuba_material_refs.py; Mitsuba is not needed here).

Scenes (tests/support/mitsuba_scenes.py): a rough gold sphere (Mitsuba ``principled``, metallic 1), rough
glass (``roughdielectric``) and an anisotropic brushed disc (``principled``, anisotropic), each under
a constant sky and an area light. Mitsuba has no multiple-scattering compensation, so ours is
rendered with it off.

Both images are batches of independent renders. Per 4 x 4 pixel block and channel the two means are
held against a Welch t bound from both sides' spread (Student's t with the smaller side's degrees of
freedom, Bonferroni over the blocks: a correct renderer fails with probability 1e-4 per scene), and so
is the whole image's mean. Mitsuba's Smith masking is separable, ours height-correlated: at these
roughnesses that changes the albedo by at most 0.2% down to 78 degrees, below the bound. The last
test shows the comparison has power: ours with the brushing direction turned a quarter turn fails it.

Not compared here, measured instead (``python -m tests.bsdfs.test_materials_mitsuba`` prints every scene,
the alternatives included; docs/materials.md, "Against Mitsuba 3", has the figures):

* gold at roughness 0.5: there the separable masking takes up to 2% off the albedo at 78 degrees,
  and this comparison resolves it at the sphere's rim;
* the rough plastic: its layer's Fresnel is Schlick's in ours (glTF's) and exact in every Mitsuba
  plugin, which differ by up to 20% around 60 degrees: 6% in the block of the highlight.

The glass is compared through both integrators: nee's shadow rays once started on the reflection
side only, so a light seen through the glass was always occluded (2% dark; fixed: nee.shadow_ray).
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.device.structs import Features
from warp_spt.io.loader import load_scene
from warp_spt.rendering import tiles as R
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.camera import Camera
from warp_spt.scene.sky import Sky

from tests.support import mitsuba_scenes as MS
from tests.support.stability_scenes import t_quantile

REFS = Path(__file__).parents[1] / "data" / "mitsuba_material_refs.npz"
BATCHES = 32
SPP = 32            # per batch: 1024 samples per pixel in all
ALPHA = 1e-4        # family-wise false-failure probability per scene

pytestmark = pytest.mark.skipif(not REFS.exists(), reason=f"{REFS.name} absent (make_mitsuba_material_refs.py)")


def camera() -> Camera:
    c = MS.CAMERA
    return Camera.look_at(c["position"], c["target"], up=c["up"], fov=c["fov"])


def load_ours(folder: Path, scene: MS.MitsubaScene, **mtl_changes) -> DeviceScene:
    if mtl_changes:
        scene = dataclasses.replace(scene, mtl={**scene.mtl, **mtl_changes})
    host = load_scene(*MS.write_files(folder / scene.name, scene), warn=lambda message: None)
    host.materials.multiscatter[:] = False          # Mitsuba has no multiple-scattering compensation
    return DeviceScene(host)


def union(features: list[Features]) -> Features:
    """One feature set covering every scene here: one kernel compile for the whole file."""
    first = features[0]
    out = {}
    for f in dataclasses.fields(Features):
        values = [getattr(x, f.name) for x in features]
        if isinstance(values[0], bool):
            out[f.name] = any(values)
        elif f.name == "lobes":
            out[f.name] = int(np.bitwise_or.reduce(values))
        elif f.name == "bvh_stack":
            out[f.name] = max(values)
        elif f.name == "material_kinds":
            kinds = set().union(*values)
            out[f.name] = tuple(k for k in Features().material_kinds if k in kinds)
        else:
            out[f.name] = tuple(sorted(set().union(*values)))
    return dataclasses.replace(first, **out)


def render_blocks(dev: DeviceScene, features: Features, integrator: str = "nee") -> np.ndarray:
    """(BATCHES, blocks, 3): per batch (disjoint sample ranges), the 4 x 4 block means of our image."""
    out = []
    for k in range(BATCHES):
        res = R.render_scene(dev, camera(), RenderSettings(
            width=MS.WIDTH, height=MS.HEIGHT, spp=SPP, sample_offset=k * SPP, max_depth=MS.MAX_DEPTH, seed=7,
            integrator=integrator, sky=Sky.constant(MS.SKY, MS.SKY, MS.SKY), features=features))
        assert res.stats.dropped_samples == 0
        img = res.image.astype(np.float64)
        b = 4
        out.append(img.reshape(MS.HEIGHT // b, b, MS.WIDTH // b, b, 3).mean(axis=(1, 3)).reshape(-1, 3))
    return np.stack(out)


def welch_t(a: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Welch's t of the means of a and b over axis 0, and its standard error; where neither side
    varies (blocks of sky alone) the means must agree to float32 rounding."""
    se = np.sqrt(a.var(axis=0, ddof=1) / len(a) + b.var(axis=0, ddof=1) / len(b))
    diff = a.mean(0) - b.mean(0)
    exact = np.abs(diff) <= 1e-6 * np.abs(b.mean(0))
    return np.where(se > 0, diff / np.where(se > 0, se, 1.0), np.where(exact, 0.0, np.inf)), se


def comparison(ours: np.ndarray, ref: np.ndarray) -> dict:
    """Block and whole-image Welch statistics with their Student t bounds (dof: the smaller side's)."""
    dof = min(len(ours), len(ref)) - 1
    t, _ = welch_t(ours, ref)
    tot_t, tot_se = welch_t(ours.mean(axis=(1, 2))[:, None], ref.mean(axis=(1, 2))[:, None])
    mean = ref.mean()
    return {"worst": float(np.abs(t).max()), "bound": t_quantile(ALPHA / (4 * t.size), dof),
            "total": float(abs(tot_t[0])), "bound_total": t_quantile(ALPHA / 4, dof),
            "rel_diff": float((ours.mean() - mean) / mean), "rel_se": float(tot_se[0] / mean)}


def describe(c: dict) -> str:
    return (f"worst block |t| {c['worst']:.2f} (bound {c['bound']:.2f}); whole image differs by "
            f"{c['rel_diff']:+.2%} (standard error {c['rel_se']:.2%}, |t| {c['total']:.2f}, "
            f"bound {c['bound_total']:.2f})")


@pytest.fixture(scope="module")
def refs() -> dict:
    with np.load(REFS) as z:
        return {k: z[k] for k in z.files}


class Ours:
    """Our side: every scene loaded, one feature set (one kernel per integrator), renders cached."""

    def __init__(self, folder: Path):
        self.devs = {s.name: load_ours(folder, s) for s in MS.SCENES + MS.ALTERNATIVES}
        self.devs["brushed_turned"] = load_ours(folder, MS.by_name("brushed"), anisor=0.25)
        self.features = union([d.features for d in self.devs.values()])
        self.cache: dict = {}

    def blocks(self, name: str, integrator: str = "nee") -> np.ndarray:
        if (name, integrator) not in self.cache:
            self.cache[name, integrator] = render_blocks(self.devs[name], self.features, integrator)
        return self.cache[name, integrator]


@pytest.fixture(scope="module")
def ours(tmp_path_factory) -> Ours:
    return Ours(tmp_path_factory.mktemp("mitsuba"))


def test_the_references_say_how_they_were_made(refs):
    settings = json.loads(str(refs["settings"]))
    for s in MS.SCENES:
        assert settings["scenes"][s.name]["bsdf"] == json.loads(json.dumps(s.bsdf)), s.name
        assert refs[f"{s.name}_blocks"].shape == (settings["batches"], (MS.WIDTH // 4) * (MS.HEIGHT // 4), 3)
    assert settings["width"] == MS.WIDTH and settings["camera"]["fov"] == MS.CAMERA["fov"]


# The glass through pure path tracing (the seed's integrator, which takes the pbr kind too) and through
# nee, whose shadow rays cross the glass from the light's side (nee.shadow_ray).
CASES = [("gold", "nee"), ("glass", "seed"), ("brushed", "nee"), ("glass", "nee")]
# Measured, not asserted (the module's docstring says why).
MEASURED = [("gold_rough", "gold_rough", "nee"), ("plastic", "plastic", "nee"), ("plastic_unscaled", "plastic", "nee"),
            ("plastic_principled", "plastic", "nee")]


@pytest.mark.parametrize("name,integrator", CASES)
def test_pbr_matches_mitsuba(refs, ours, name, integrator):
    c = comparison(ours.blocks(name, integrator), refs[f"{name}_blocks"].astype(np.float64))
    assert c["worst"] <= c["bound"] and c["total"] <= c["bound_total"], f"{name} ({integrator}): {describe(c)}"


def test_the_comparison_sees_the_brushing_direction(refs, ours):
    """The brushed disc with its anisotropy turned a quarter turn (alpha_x along v): not Mitsuba's image."""
    c = comparison(ours.blocks("brushed_turned"), refs["brushed_blocks"].astype(np.float64))
    assert c["worst"] > 2 * c["bound"], describe(c)


def main() -> None:
    """Print the comparison of every scene, the measured ones included (``--spp`` per batch)."""
    import argparse
    import tempfile

    global SPP
    ap = argparse.ArgumentParser(description=main.__doc__)
    ap.add_argument("--spp", type=int, default=SPP)
    SPP = ap.parse_args().spp
    with np.load(REFS) as z:
        refs = {k: z[k] for k in z.files}
    ours = Ours(Path(tempfile.mkdtemp()))
    cases = [(name, name, integ) for name, integ in
             [("gold", "nee"), ("glass", "seed"), ("glass", "nee"), ("brushed", "nee")]] + MEASURED
    cases.append(("brushed (turned a quarter)", "brushed_turned", "nee"))
    print(f"ours: {BATCHES} batches x {SPP} spp; Mitsuba: {json.loads(str(refs['settings']))['batches']} batches x "
          f"{json.loads(str(refs['settings']))['spp']} spp")
    for ref_name, our_name, integ in cases:
        key = ref_name.split(" ")[0] if ref_name.startswith("brushed") else ref_name
        c = comparison(ours.blocks(our_name, integ), refs[f"{key}_blocks"].astype(np.float64))
        print(f"{ref_name:<28} {integ:<5} {describe(c)}", flush=True)


if __name__ == "__main__":
    main()
