"""Participating media (issue 35): the trackers and volpath against analytic values.

* Henyey-Greenstein sampling against its pdf (chi-square over cos theta, g in {-0.9, 0, 0.5, 0.95}).
* Beer-Lambert: a pure absorber's transmittance exp(-sigma_t d) at sigma_t d in {0.1, 1, 5}, by
  delta tracking (free flights that reach the end) and by ratio tracking, grey and chromatic, at
  majorant 1 and 2; then through the renderer: an index-matched absorbing slab before a sky of 1.
* Furnaces: an index-matched ball of non-absorbing medium under a sky of 1 is 1 in every pixel, for
  chromatic densities and any g (albedo < 1 falls); a closed emitting box of radiance 1 filled with
  fog (scene-wide medium) is 1 everywhere inside for albedo 1, and for albedo < 1 when the medium
  emits 1 too: light sampling from inside the medium, ratio-tracked shadow rays and MIS against the
  phase function, checked per block over seeds.
* Majorant invariance: doubling the majorant leaves the image's mean unchanged (per-block t).
* A scene without media renders bit-identically through volpath and nee; nee refuses media.

Tolerances come from the estimated standard errors (seeds as independent batches).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
import warp as wp

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.media import EVENT_SURFACE, Media, hg_sample, make_media, upload_media
from warp_spt.media.phase import hg
from warp_spt.device.structs import Features
from warp_spt.io.loader import load_scene
from warp_spt.rendering import tiles as R
from warp_spt.rendering.settings import RenderSettings
from warp_spt.scene.camera import Camera
from warp_spt.scene.media import Medium, parse_medium
from warp_spt.scene.model import Material, MaterialTable
from warp_spt.scene.sky import Sky

from tests.support.scenes import box_obj, write_scene_files

UNIFORM = Sky.constant(1.0, 1.0, 1.0)
FEATURES = Features(media=("grid", "homogeneous"))       # both kinds: the dispatch between them too


class _Host:
    """The least a media upload reads of a scene: its fog, interiors and material names."""

    def __init__(self, fog):
        self.fog = fog
        self.interiors = {}
        self.materials = MaterialTable.from_rows([Material("m")])


# -- Henyey-Greenstein -------------------------------------------------------------------------------

@wp.kernel
def _hg_kernel(g: float, seed: int, out: wp.array(dtype=float)):
    i = wp.tid()
    s = wp.rand_init(seed, i)
    d = wp.normalize(wp.vec3(0.3, -0.5, 0.8))
    w = hg_sample(d, g, wp.vec2(wp.randf(s), wp.randf(s)))
    out[i] = wp.dot(d, w)


def _hg_cdf(mu: np.ndarray, g: float) -> np.ndarray:
    """P(cos <= mu) of the HG density p(mu) = (1 - g^2) / (2 (1 + g^2 - 2 g mu)^1.5), integrated."""
    if abs(g) < 1e-9:
        return (mu + 1.0) / 2.0
    return (1.0 - g * g) / (2.0 * g) * (1.0 / np.sqrt(1.0 + g * g - 2.0 * g * mu) - 1.0 / (1.0 + g))


@pytest.mark.parametrize("g", [-0.9, 0.0, 0.5, 0.95])
def test_hg_sampling_matches_its_pdf(g):
    n, bins = 200_000, 40
    out = wp.zeros(n, dtype=float, device="cpu")
    wp.launch(_hg_kernel, dim=n, inputs=[g, 7, out], device="cpu")
    mu = out.numpy().astype(np.float64)
    # bins of equal expected count: the inverse CDF at equal steps, computed by bisection
    edges = [-1.0]
    for k in range(1, bins):
        lo, hi = -1.0, 1.0
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            lo, hi = (mid, hi) if _hg_cdf(np.array(mid), g) < k / bins else (lo, mid)
        edges.append(0.5 * (lo + hi))
    edges.append(1.0 + 1e-6)
    counts, _ = np.histogram(mu, bins=np.asarray(edges))
    expected = n / bins
    chi2 = float(((counts - expected) ** 2 / expected).sum())
    df = bins - 1
    # Wilson-Hilferty: chi2/df is close to normal; z < 4 fails a correct sampler about 3e-5 of the time
    z = ((chi2 / df) ** (1 / 3) - (1 - 2 / (9 * df))) / math.sqrt(2 / (9 * df))
    assert z < 4.0, (g, chi2, df)
    # the density's own normalisation and the mean cosine (g), independently of the bins
    assert abs(mu.mean() - g) < 5 * mu.std() / math.sqrt(n)


@wp.kernel
def _hg_value_kernel(mu: wp.array(dtype=float), g: float, out: wp.array(dtype=float)):
    i = wp.tid()
    out[i] = hg(mu[i], g)


def _hg_values(mu: np.ndarray, g: float) -> np.ndarray:
    out = wp.zeros(len(mu), dtype=float, device="cpu")
    x = wp.array(mu.astype(np.float32), dtype=float, device="cpu")
    wp.launch(_hg_value_kernel, dim=len(mu), inputs=[x, g, out], device="cpu")
    return out.numpy().astype(np.float64)


@pytest.mark.parametrize("g", [-0.999999, -0.9999, 0.999, 0.9999, 0.999999])
def test_hg_is_finite_and_sampled_right_at_the_extremes(g):
    """Up to the accepted |g| <= 0.999999 (g = 0.999999 once gave NaN samples: 1 + g^2 - 2 g cos
    cancelled to 0 or below in float32): every sampled cosine and every value finite and positive,
    the sampled cosines' mean g (HG's mean cosine), and where float32 still resolves the peak
    (|g| <= 0.999) the value integrating to 1 over the sphere."""
    n = 100_000
    out = wp.zeros(n, dtype=float, device="cpu")
    wp.launch(_hg_kernel, dim=n, inputs=[g, 3, out], device="cpu")
    mu = out.numpy().astype(np.float64)
    assert np.isfinite(mu).all()
    assert abs(mu.mean() - g) < 5 * mu.std() / math.sqrt(n) + 2e-6, (mu.mean(), g)
    grid = np.concatenate([[-1.0, 1.0], np.linspace(-1, 1, 10_001), np.sign(g) * (1 - np.logspace(-9, 0, 2_000))])
    values = _hg_values(np.concatenate([mu, grid]), g)
    assert np.isfinite(values).all() and (values > 0).all()
    if abs(g) <= 0.999:
        # 2 pi times the integral over mu, on the float32 abscissae the kernel saw, finest at the peak
        t = np.unique(np.float32(1 - np.logspace(-10, np.log10(2), 20_000)).astype(np.float64))
        x = np.sign(g) * t
        x = np.sort(x)
        y = _hg_values(x, g)
        total = 2 * np.pi * float(((y[1:] + y[:-1]) / 2 * np.diff(x)).sum())
        assert abs(total - 1.0) < 2e-3, total


# -- Beer-Lambert through the trackers --------------------------------------------------------------

def _tracker_kernel():
    md = make_media(FEATURES)

    @wp.kernel
    def run(media: Media, o: wp.vec3, d: wp.vec3, d_len: float, ratio: int, seed: int, out: wp.array(dtype=wp.vec3)):
        i = wp.tid()
        rng = wp.uint32(wp.rand_init(seed, i))
        if ratio != 0:
            T, r = md.transmittance(media, 0, o, d, d_len, rng)
            out[i] = T
        else:
            hero = wp.min(int(wp.randf(rng) * 3.0), 2)      # per path, uniformly, as volpath's
            ev, t, beta, w, em, r = md.free_flight(media, 0, o, d, d_len, hero, wp.vec3(1.0, 1.0, 1.0),
                                                   wp.vec3(1.0, 1.0, 1.0), rng)
            out[i] = wp.where(ev == EVENT_SURFACE, beta, wp.vec3(0.0, 0.0, 0.0))

    return run


_TRACKER = None


def _tracked(medium: Medium, d: float, ratio: bool, n: int = 200_000, seed: int = 3, o=(0.0, 0.0, 0.0),
             direction=(0.0, 0.0, 1.0)):
    global _TRACKER
    if _TRACKER is None:
        _TRACKER = _tracker_kernel()
    out = wp.zeros(n, dtype=wp.vec3, device="cpu")
    media, volumes = upload_media(_Host(medium), "cpu")      # volumes: kept alive for the launch
    wp.launch(_TRACKER, dim=n, inputs=[media, wp.vec3(*o), wp.vec3(*direction), d, int(ratio), seed, out],
              device="cpu")
    v = out.numpy().astype(np.float64)
    return v.mean(0), v.std(0, ddof=1) / math.sqrt(n)


@pytest.mark.parametrize("ratio", [False, True], ids=["delta", "ratio"])
@pytest.mark.parametrize("majorant", [1.0, 2.0])
@pytest.mark.parametrize("tau", [0.1, 1.0, 5.0])
def test_beer_lambert_trackers(tau, majorant, ratio):
    sigma = np.array([1.0, 0.5, 2.0])           # chromatic: spectral MIS must hold in every channel
    d = tau / sigma[0]
    mean, se = _tracked(Medium(sigma_a=tuple(sigma * 0.6), sigma_s=tuple(sigma * 0.4), majorant=majorant)
                        if ratio else Medium(sigma_a=tuple(sigma), majorant=majorant), d, ratio)
    expected = np.exp(-sigma * d)
    assert np.all(np.abs(mean - expected) < 4.5 * se + 1e-7), (mean, expected, se)


def _slab_scene(folder: Path, name: str, medium_lines: str, thickness: float):
    obj = box_obj(lo=(-1.0, -thickness / 2, -1.0), hi=(1.0, thickness / 2, 1.0), material="slab")
    objs, mtls = write_scene_files(folder, name, obj, "newmtl slab\nindex_matched\n" + medium_lines)
    return DeviceScene(load_scene(objs, mtls))


SLAB_CAM = Camera(position=(0, -6, 0), direction=(0, 1, 0), fov=8.0, aperture=0.0, focus=6.0)


@pytest.mark.parametrize("tau", [0.1, 1.0, 5.0])
def test_beer_lambert_render(scene_dir, tau):
    """Camera rays through an index-matched slab of thickness 0.5 before a sky of 1: exp(-tau)."""
    sigma = np.array([1.0, 0.5, 2.0]) * tau / 0.5
    dev = _slab_scene(scene_dir, f"slab_{tau}", "medium_sigma_a " + " ".join(f"{s:.9g}" for s in sigma) + "\n", 0.5)
    res = R.render_scene(dev, SLAB_CAM, RenderSettings(width=16, height=16, spp=64, max_depth=8, seed=1,
                                                       integrator="volpath", sky=UNIFORM))
    px = res.image.reshape(-1, 3).astype(np.float64)
    mean, se = px.mean(0), px.std(0, ddof=1) / math.sqrt(len(px))
    expected = np.exp(-sigma * 0.5)
    assert np.all(np.abs(mean - expected) < 4.5 * se + 1e-6), (mean, expected, se)


# -- furnaces ---------------------------------------------------------------------------------------

# per-block Student t over 16 seeds (15 degrees of freedom), 16 blocks x 3 channels per image: 5.0 is
# two-sided p of about 2e-4 per block, 1% per image; the chromatic media's weights are heavy-tailed
T_BLOCK = 5.0
BALL_CAM = Camera(position=(0, -6, 0), direction=(0, 1, 0), fov=22.0, aperture=0.0, focus=6.0)


def _seeded_blocks(dev, camera, seeds=16, size=16, spp=16, depth=64, block=4, sky=UNIFORM):
    """Per-block means over ``seeds`` renders: (mean over seeds, its standard error), each (B, B, 3)."""
    runs = []
    for s in range(seeds):
        img = R.render_scene(dev, camera, RenderSettings(width=size, height=size, spp=spp, max_depth=depth,
                                                         seed=100 + s, integrator="volpath", sky=sky)).image
        runs.append(img.astype(np.float64).reshape(size // block, block, size // block, block, 3).mean((1, 3)))
    runs = np.asarray(runs)
    return runs.mean(0), runs.std(0, ddof=1) / math.sqrt(seeds)


def _ball(folder, name: str, sigma_s, sigma_a=(0.0, 0.0, 0.0), g=0.0):
    mtl = ("newmtl m\nindex_matched\nmedium_sigma_s " + " ".join(map(str, sigma_s))
           + "\nmedium_sigma_a " + " ".join(map(str, sigma_a)) + f"\nmedium_g {g}\n")
    objs, mtls = write_scene_files(folder, name, "usemtl m\nb 0 0 0 1\n", mtl)
    return DeviceScene(load_scene(objs, mtls))


@pytest.mark.parametrize("g", [-0.6, 0.0, 0.8])
def test_albedo_one_furnace_ball(scene_dir, g):
    dev = _ball(scene_dir, f"ball_{g}", (1.0, 3.0, 0.3), g=g)
    mean, se = _seeded_blocks(dev, BALL_CAM)
    assert np.all(np.abs(mean - 1.0) < T_BLOCK * se + 1e-5), (mean, se)


def test_albedo_below_one_falls(scene_dir):
    dev = _ball(scene_dir, "ball_grey", (2.0, 2.0, 2.0), sigma_a=(0.5, 0.5, 0.5))
    mean, se = _seeded_blocks(dev, BALL_CAM, seeds=4)
    centre = mean[1:3, 1:3]
    assert np.all(centre < 1.0 - 5 * se[1:3, 1:3] - 0.05), centre


def _glowing_box(folder, name: str, fog: Medium):
    objs, mtls = write_scene_files(folder, name, box_obj(material="glow"), "newmtl glow\nKd 0 0 0\nKs 0 0 0\nKe 1 1 1\n")
    scene = load_scene(objs, mtls)
    scene.fog = fog
    return DeviceScene(scene)


INSIDE_CAM = Camera(position=(0, -0.5, 0), direction=(0, 1, 0), fov=60.0, aperture=0.0, focus=1.0)


@pytest.mark.parametrize("fog", [
    Medium(sigma_s=(1.0, 2.5, 0.4), g=0.7),
    Medium(sigma_s=(1.0, 2.5, 0.4), g=-0.3, majorant=2.0),
    Medium(sigma_s=0.8, sigma_a=(0.5, 1.0, 0.2), emission=1.0),
], ids=["albedo1", "albedo1-majorant2", "emitting"])
def test_emitting_box_equilibrium(scene_dir, fog):
    """Inside a closed box whose walls emit 1 (and reflect nothing), a medium that absorbs nothing, or
    emits what it absorbs, leaves radiance 1 everywhere: NEE from the medium, ratio tracking, MIS."""
    dev = _glowing_box(scene_dir, "glow", fog)
    mean, se = _seeded_blocks(dev, INSIDE_CAM, sky=Sky.black())
    assert np.all(np.abs(mean - 1.0) < T_BLOCK * se + 1e-5), (mean, se)
    assert se.max() > 0          # light sampling and flights did vary the estimate


def test_majorant_invariance(scene_dir):
    """A lit floor in chromatic fog: the image's blocks at majorant 1 and 2 agree (per-block t)."""
    folder = scene_dir
    floor = box_obj(lo=(-3, -3, -1.2), hi=(3, 3, -1.0), material="floor")
    lamp = box_obj(lo=(-0.4, -0.4, 1.5), hi=(0.4, 0.4, 1.7), material="lamp")
    # two files: each box's faces number its own vertices from 1
    objs, mtls = write_scene_files(folder, "fogroom", floor,
                                   "newmtl floor\nKd 0.8 0.8 0.8\nnewmtl lamp\nKd 0 0 0\nKe 8 8 8\n")
    objs += write_scene_files(folder, "fogroom_lamp", lamp)[0]
    means = []
    for k in (1.0, 2.0):
        scene = load_scene(objs, mtls)
        scene.fog = Medium(sigma_a=(0.02, 0.05, 0.1), sigma_s=(0.3, 0.2, 0.1), g=0.4, majorant=k)
        cam = Camera(position=(0, -5, 0.5), direction=(0, 1, -0.15), fov=50.0, aperture=0.0, focus=5.0)
        means.append(_seeded_blocks(DeviceScene(scene), cam, depth=8, sky=Sky.constant(0.2, 0.2, 0.2)))
    (a, sa), (b, sb) = means
    t = (a - b) / np.sqrt(sa ** 2 + sb ** 2 + 1e-30)
    assert np.abs(t).max() < T_BLOCK, np.abs(t).max()


# -- grids -------------------------------------------------------------------------------------------

def _ramp(nx=24, seed=0):
    """A density varying along x only (random in [0, 3]), constant across y and z."""
    rho = np.random.default_rng(seed).uniform(0.0, 3.0, nx).astype(np.float32)
    return np.ascontiguousarray(np.broadcast_to(rho[:, None, None], (nx, 6, 6))), rho


@pytest.mark.parametrize("ratio", [False, True], ids=["delta", "ratio"])
@pytest.mark.parametrize("cells", [1, 4, 16])
def test_grid_optical_depth(ratio, cells):
    """Along x through the middle of the ramp, trilinear interpolation is piecewise linear between
    voxel centres and falls to 0 one voxel beyond the ends: the optical depth is the sum of the
    densities times the voxel size, whatever the majorant grid's cells. The grid is turned by 90
    degrees about z and moved (to_world), so the ray runs along the scene's y."""
    a, rho = _ramp()
    vs = 0.05
    turn = np.array([[0, -1, 0, 0.3], [1, 0, 0, -0.2], [0, 0, 1, 0.1], [0, 0, 0, 1]], float)
    sigma = np.array([1.0, 0.5, 2.0])
    m = Medium(sigma_a=tuple(sigma * 0.7), sigma_s=tuple(sigma * 0.3), density=a, voxel_size=vs, to_world=turn,
               majorant_cells=cells, density_scale=2.0) if ratio else \
        Medium(sigma_a=tuple(sigma), density=a, voxel_size=vs, to_world=turn, majorant_cells=cells, density_scale=2.0)
    # the grid's own point (x, 2.7 vs, 2.7 vs) is the scene's (0.3 - 2.7 vs, x - 0.2, 0.1 + 2.7 vs)
    o = (0.3 - 2.7 * vs, -0.2 - 2.0, 0.1 + 2.7 * vs)
    mean, se = _tracked(m, 4.0, ratio, n=100_000, o=o, direction=(0.0, 1.0, 0.0))
    expected = np.exp(-sigma * 2.0 * vs * rho.sum())
    assert np.all(np.abs(mean - expected) < 4.5 * se + 1e-7), (mean, expected, se)


def test_nvdb_file_equals_array(tmp_path):
    a, _ = _ramp(nx=16, seed=1)
    path = tmp_path / "ramp.nvdb"
    wp.Volume.load_from_numpy(a, voxel_size=0.1, bg_value=0.0, device="cpu").save_to_nvdb(str(path))
    common = dict(sigma_a=(1.0, 0.4, 2.0), majorant=1.5)
    kw = dict(n=20_000, o=(-1.0, 0.27, 0.27), direction=(1.0, 0.0, 0.0))
    from_file = _tracked(Medium(density=str(path), **common), 4.0, False, **kw)
    from_array = _tracked(Medium(density=a, voxel_size=0.1, **common), 4.0, False, **kw)
    assert np.array_equal(from_file[0], from_array[0])


def test_bad_grids(tmp_path):
    a, _ = _ramp(nx=8)
    path = tmp_path / "ok.nvdb"
    wp.Volume.load_from_numpy(a, bg_value=0.0, device="cpu").save_to_nvdb(str(path))
    data = path.read_bytes()
    short = tmp_path / "short.nvdb"
    short.write_bytes(data[: len(data) // 2])
    junk = tmp_path / "junk.nvdb"
    junk.write_bytes(b"not a grid at all" * 10)
    for bad in (short, junk):
        with pytest.raises(ValueError, match=rf"{bad.name}: not a valid NanoVDB grid") as info:
            upload_media(_Host(Medium(sigma_s=1.0, density=str(bad))), "cpu")
        assert "\n" not in str(info.value)
    with pytest.raises(ValueError, match="cannot read"):
        upload_media(_Host(Medium(sigma_s=1.0, density=str(tmp_path / "missing.nvdb"))), "cpu")
    # the index-to-world map: NaN or infinite (the medium was dropped without a word), singular (it was
    # "internal error: LinAlgError"); the voxel size's float32 entries of a 0.1 grid rewritten
    import struct
    wp.Volume.load_from_numpy(a, voxel_size=0.1, bg_value=0.0, device="cpu").save_to_nvdb(str(path))
    tenth = struct.pack("<f", 0.1)
    data = path.read_bytes()
    assert data.count(tenth) == 3
    for value, mentions in ((np.nan, "NaN or infinite"), (np.inf, "NaN or infinite"), (0.0, "no scale"),
                            ("one axis", "singular")):
        bad = tmp_path / "map.nvdb"
        if value == "one axis":
            bad.write_bytes(data.replace(tenth, struct.pack("<f", 0.0), 1))
        else:
            bad.write_bytes(data.replace(tenth, struct.pack("<f", value)))
        with pytest.raises(ValueError, match=rf"map.nvdb: the grid's index-to-world map .*{mentions}"):
            upload_media(_Host(Medium(sigma_s=1.0, density=str(bad))), "cpu")
    for value in (-1.0, np.nan, np.inf):
        b = a.copy()
        b[3, 2, 1] = value
        with pytest.raises(ValueError, match=r"finite and >= 0; voxel \(3, 2, 1\)"):
            Medium(sigma_s=1.0, density=b).check()
    with pytest.raises(ValueError, match="3-D array"):
        Medium(sigma_s=1.0, density=np.ones((4, 4))).check()


def test_constant_grid_matches_homogeneous(scene_dir):
    """The scattering, absorbing ball filled by a constant grid (larger than the ball) and by the
    homogeneous medium of the same coefficients: the same image within its error, per block."""
    homog = _ball(scene_dir, "ball_h", (1.5, 2.0, 0.5), sigma_a=(0.3, 0.1, 0.6), g=0.3)
    objs, mtls = write_scene_files(scene_dir, "ball_grid", "usemtl m\nb 0 0 0 1\n", "newmtl m\nindex_matched\n")
    scene = load_scene(objs, mtls)
    scene.interiors = {"m": Medium(sigma_s=(1.5, 2.0, 0.5), sigma_a=(0.3, 0.1, 0.6), g=0.3, density_scale=0.5,
                                   density=np.full((12, 12, 12), 2.0, np.float32), origin=(-1.5, -1.5, -1.5),
                                   voxel_size=0.25)}
    grid = DeviceScene(scene)
    assert grid.features.media == ("grid", "interface")
    (a, sa), (b, sb) = _seeded_blocks(homog, BALL_CAM), _seeded_blocks(grid, BALL_CAM)
    t = (a - b) / np.sqrt(sa ** 2 + sb ** 2 + 1e-30)
    assert np.abs(t).max() < T_BLOCK, np.abs(t).max()


def test_open_mesh_with_a_medium_warns(scene_dir):
    quad = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl m\nf 1 2 3\nf 1 3 4\n"
    objs, mtls = write_scene_files(scene_dir, "open", quad, "newmtl m\nindex_matched\nmedium_sigma_s 1\n")
    assert any("not closed" in w for w in load_scene(objs, mtls).warnings)
    objs, mtls = write_scene_files(scene_dir, "closed", box_obj(material="m"), "newmtl m\nindex_matched\nmedium_sigma_s 1\n")
    assert not any("not closed" in w for w in load_scene(objs, mtls).warnings)


# -- no media, and the wrong integrator -------------------------------------------------------------

def test_no_media_volpath_is_nee(scene_dir):
    objs, mtls = write_scene_files(scene_dir, "plain", "usemtl m\nb 0 0 0 1\n", "newmtl m\nKd 0.7 0.5 0.3\n")
    dev = DeviceScene(load_scene(objs, mtls))
    assert dev.features.media == ()
    imgs = [R.render_scene(dev, BALL_CAM, RenderSettings(width=12, height=12, spp=4, seed=5, integrator=i,
                                                         sky=UNIFORM)).image for i in ("nee", "volpath")]
    assert np.array_equal(imgs[0], imgs[1])


def test_nee_refuses_media(scene_dir):
    dev = _ball(scene_dir, "ball_nee", (1.0, 1.0, 1.0))
    with pytest.raises(ValueError, match="volpath"):
        R.render_scene(dev, BALL_CAM, RenderSettings(width=4, height=4, spp=1, integrator="nee", sky=UNIFORM))


@pytest.mark.parametrize("integrator, mode", [("nee", "prb"), ("nee", "tape"), ("volpath", "tape")])
def test_gradients_refuse_media(scene_dir, mode, integrator):
    """Gradients of a scene with media through an integrator that ignores them, or through the tape
    (volpath's are path replay's, tests/diff/test_volumes_gradients.py): refused, not rendered as if the
    media were absent."""
    from warp_spt.diff.gradients import render_gradients
    from warp_spt.diff.params import parameters
    dev = _ball(scene_dir, "ball_grad", (1.0, 1.0, 1.0))
    p = parameters(dev, BALL_CAM, UNIFORM)
    with pytest.raises(ValueError, match="participating media|integrator 'volpath'|tape"):
        render_gradients(p, RenderSettings(width=4, height=4, spp=1, integrator=integrator), mode=mode,
                         adjoint=np.ones((4, 4, 3)), wrt=["sky.color"])


# -- bad input --------------------------------------------------------------------------------------

@pytest.mark.parametrize("words, match", [
    (["g=1"], r"\[-0.999999, 0.999999\]"), (["g=-1.5"], r"\[-0.999999, 0.999999\]"),
    (["g=0.9999995"], r"\[-0.999999, 0.999999\]"), (["sigma_s=-1"], "sigma_s"),
    (["sigma_a=1,2"], "1 or 3"), (["colour=1"], "KEY=VALUE"), (["sigma_s=nan"], "plain numbers"),
    (["majorant=0.5"], "majorant"),
])
def test_bad_fog_words(words, match):
    with pytest.raises(ValueError, match=match):
        parse_medium(words)


def test_mtl_medium_errors_name_file_and_line(tmp_path):
    from warp_spt.io.mtl import load_mtl
    from warp_spt.scene.errors import SceneError

    p = tmp_path / "bad.mtl"
    p.write_text("newmtl a\nindex_matched\nmedium_sigma_s 1 1 1\nmedium_g 1.2\n")
    with pytest.raises(SceneError, match=r"bad.mtl:4: .*\[-0.999999, 0.999999\]"):
        load_mtl(p)
    p.write_text("newmtl a\nmedium_sigma_a -1\n")
    with pytest.raises(SceneError, match=r"bad.mtl:2"):
        load_mtl(p)
    p.write_text("newmtl a\nmedium_sigma_a 0.5 0.25 1\nmedium_g 0.3\n")
    assert load_mtl(p)["a"].interior == Medium(sigma_a=(0.5, 0.25, 1.0), g=0.3)


def test_cli_fog_and_a_corrupt_grid(scene_dir, capsys):
    """--fog renders through volpath (said in one line); a corrupt .nvdb named in an MTL is one error
    line naming the file, exit status 1, no traceback."""
    from warp_spt.cli.main import main

    objs, mtls = write_scene_files(scene_dir, "cli_fog", box_obj(lo=(-1, -1, -1), hi=(1, 1, 1), material="m"),
                                   "newmtl m\nKd 0.5 0.5 0.5\n")
    out = scene_dir / "fog.npy"
    assert main(["-obj", objs[0], "-mtl", mtls[0], "--fog", "sigma_s=0.1", "--fog", "g=0.3", "-res", "8", "8",
                 "-sr", "2", "-cam", "0", "-6", "0", "0", "1", "0", "40", "6", "0", "-out", str(out)]) == 0
    assert "integrator volpath" in capsys.readouterr().err
    assert np.isfinite(np.load(out)).all()
    (scene_dir / "bad.nvdb").write_bytes(b"\x00" * 100)
    objs, mtls = write_scene_files(scene_dir, "cli_grid", box_obj(material="m"),
                                   "newmtl m\nindex_matched\nmedium_sigma_s 1\nmedium_density bad.nvdb\n")
    status = main(["-obj", objs[0], "-mtl", mtls[0], "-res", "8", "8", "-sr", "1", "-out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 1
    assert "bad.nvdb: not a valid NanoVDB grid" in err[-1] and "Traceback" not in "\n".join(err)
    assert main(["-obj", objs[0], "--fog", "g=2", "-out", str(out)]) == 2
    assert "[-0.999999, 0.999999]" in capsys.readouterr().err
    # an integrator that ignores media, asked for by the flag: a usage error (2), not "internal error"
    objs, mtls = write_scene_files(scene_dir, "cli_interior", box_obj(material="m"),
                                   "newmtl m\nindex_matched\nmedium_sigma_s 1\n")
    for args in (["--fog", "sigma_s=0.1"], ["-mtl", mtls[0]]):
        assert main(["-obj", objs[0], *args, "--integrator", "nee", "-res", "8", "8", "-out", str(out)]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and "--integrator nee ignores them" in err[0] and "internal" not in err[0], err


def test_far_off_grid_moves_with_the_scene(scene_dir):
    """A scene 2e5 from the origin is recentred before upload: its grid moves with the geometry
    (to_world shifted), so the far-off constant-grid ball renders as the one at the origin."""
    from dataclasses import replace as dc_replace

    far = np.array([2.0e5, 0.0, 0.0])
    images = []
    for shift in (np.zeros(3), far):
        obj = f"usemtl m\nb {shift[0]:.9g} {shift[1]:.9g} {shift[2]:.9g} 1\n"
        objs, mtls = write_scene_files(scene_dir, f"ball_far_{int(shift[0])}", obj, "newmtl m\nindex_matched\n")
        scene = load_scene(objs, mtls)
        place = np.eye(4)
        place[:3, 3] = shift
        scene.interiors = {"m": Medium(sigma_s=(1.5, 2.0, 0.5), sigma_a=(0.3, 0.1, 0.6), g=0.3,
                                       density=np.full((12, 12, 12), 1.0, np.float32), origin=(-1.5, -1.5, -1.5),
                                       voxel_size=0.25, to_world=place)}
        cam = dc_replace(BALL_CAM, position=tuple(np.asarray(BALL_CAM.position) + shift))
        images.append(_seeded_blocks(scene, cam, seeds=8))
    (a, sa), (b, sb) = images
    t = (a - b) / np.sqrt(sa ** 2 + sb ** 2 + 1e-30)
    assert np.abs(t).max() < T_BLOCK, np.abs(t).max()
    assert a[1:3, 1:3].mean() < 0.9          # the medium is there: it absorbs


def test_viewer_picks_volpath_for_a_scene_with_media(scene_dir):
    import time

    from warp_spt.viewer.session import Session

    objs, mtls = write_scene_files(scene_dir, "view_fog", box_obj(material="m"), "newmtl m\nKd 0.5 0.5 0.5\n")
    scene = load_scene(objs, mtls)
    scene.fog = Medium(sigma_s=0.1)
    s = Session(scene, width=16, height=16, max_spp=2)
    try:
        deadline = time.monotonic() + 120
        while s.settings.integrator != "volpath" and time.monotonic() < deadline:
            time.sleep(0.1)
        assert s.settings.integrator == "volpath"
    finally:
        s.close()


@pytest.mark.parametrize("g", [-0.999999, 0.999999])
def test_hg_takes_cosines_an_ulp_beyond_one_as_one(g):
    """A dot product of two unit float32 vectors can come out an ulp or two above 1 (or below -1); at
    |g| near 1 that made 1 + g^2 - 2 g cos negative in hg's two-term form: the square root of it NaN.
    Checked against HG's closed form at cos = +-1, (1 + |g|) / (4 pi (1 - |g|)^2) forward."""
    one = np.float32(1.0)
    beyond = [np.nextafter(one, np.float32(2)), np.nextafter(np.nextafter(one, np.float32(2)), np.float32(2))]
    mu = np.array([*beyond, *(-b for b in beyond), 1.0, -1.0], np.float32)
    values = _hg_values(mu, g)
    a = float(np.float32(abs(g)))
    peak, back = (1 + a) / (4 * math.pi * (1 - a) ** 2), (1 - a) / (4 * math.pi * (1 + a) ** 2)
    forward = values[[0, 1, 4]] if g > 0 else values[[2, 3, 5]]
    backward = values[[2, 3, 5]] if g > 0 else values[[0, 1, 4]]
    assert np.isfinite(values).all()                               # before: NaN beyond +-1 on the peak's side
    assert np.allclose(forward, peak, rtol=1e-3) and np.allclose(backward, back, rtol=1e-3), (values, peak, back)


def test_a_fog_at_the_largest_accepted_g_drops_no_sample(scene_dir, capsys):
    from warp_spt.cli.main import main

    objs, _ = write_scene_files(scene_dir, "fog_g", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", None)
    out = scene_dir / "fog_g.npy"
    for g in ("0.999999", "-0.999999"):
        assert main(["-obj", objs[0], "--fog", "sigma_s=0.5", "--fog", f"g={g}", "-res", "16", "16", "-sr", "8",
                     "-out", str(out)]) == 0
        assert "not finite" not in capsys.readouterr().err           # before: 2 samples dropped at 8x8, 4 spp
        assert np.isfinite(np.load(out)).all()
