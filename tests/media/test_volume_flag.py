"""Volumes a user can bring (issue 43): a level set is refused for what it is, ``--volume FILE.nvdb``
places a density grid in the box of its own bounds, and ``--fog`` without coefficients is the same
look at any scale.

* Warp's own ``rocks.nvdb`` (a level set) and a density grid whose header says level set: one line
  naming the file, saying what it is and what was expected.
* ``--volume``: the box printed is the grid's bounds worked out here from its voxels; the image
  differs from the empty scene's where the box is, and matches the same scene built by hand (an OBJ
  box, ``index_matched``, ``medium_density``) within noise, per block over seeds.
* ``--fog g=0`` on a framed model and on the same model 100 times larger: equal image means within
  noise (the control: the same absolute coefficients on both are far apart).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import warp as wp

from warp_spt.cli.main import main
from warp_spt.media.grid import LEVEL_SET, grid_bounds
from warp_spt.scene.media import Medium

from tests.support.scenes import box_obj, write_scene_files

ORIGIN, VOXEL = np.array([-0.6, -0.5, -0.4]), 0.1
CAMERA = ["-cam", "0", "-3", "0", "0", "1", "0", "40", "3", "0"]    # the seed's convention: Z up
PLAIN = ["-res", "12", "12", "-sr", "16", "--no-studio", "--sky-color", "1", "1", "1", "-depth", "8"]
SEEDS = range(1, 7)
T_BLOCK = 5.0


def _blob() -> np.ndarray:
    """A lumpy density in a 12 x 10 x 8 grid: a ball of 2 with a ramp, zero in a border of 2 voxels."""
    i, j, k = np.meshgrid(np.arange(12), np.arange(10), np.arange(8), indexing="ij")
    r = np.sqrt(((i - 5.5) / 3.5) ** 2 + ((j - 4.5) / 3) ** 2 + ((k - 3.5) / 2) ** 2)
    a = np.where(r < 1.0, 2.0 * (1.2 - r) * (1 + i / 12), 0.0).astype(np.float32)
    a[:2], a[-2:], a[:, :2], a[:, -2:], a[:, :, :2], a[:, :, -2:] = 0, 0, 0, 0, 0, 0
    return a


def _write_grid(path: Path, a: np.ndarray) -> Path:
    wp.Volume.load_from_numpy(a, min_world=tuple(ORIGIN), voxel_size=VOXEL, bg_value=0.0,
                              device="cpu").save_to_nvdb(str(path))
    return path


def _expected_bounds(a: np.ndarray) -> np.ndarray:
    """Voxel (i, j, k) sits at ORIGIN + (i, j, k) VOXEL; trilinear interpolation reaches one voxel further."""
    nz = np.argwhere(a != 0)
    return np.array([ORIGIN + (nz.min(0) - 1) * VOXEL, ORIGIN + (nz.max(0) + 1) * VOXEL])


def test_a_level_set_is_refused_naming_the_file_and_what_was_expected(tmp_path, capsys):
    rocks = Path(wp.__file__).parent / "examples" / "assets" / "rocks.nvdb"
    fog = _write_grid(tmp_path / "fog.nvdb", _blob())
    data = bytearray(fog.read_bytes())
    data[16 + 36:16 + 40] = LEVEL_SET.to_bytes(4, "little")      # the header's grid class
    (tmp_path / "sdf.nvdb").write_bytes(bytes(data))
    files = [tmp_path / "sdf.nvdb"] + ([rocks] if rocks.is_file() else [])
    for path in files:
        with pytest.raises(ValueError) as info:
            grid_bounds(Medium(sigma_s=1.0, density=str(path)))
        assert str(info.value) == (f"{path}: a signed-distance (level-set) grid; a density (fog) grid is expected "
                                   "(OpenVDB's tools::sdfToFogVolume makes one from it)")
        assert main(["--volume", str(path), "-res", "8", "8", "-sr", "1", "-out", str(tmp_path / "x.png")]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert "signed-distance (level-set) grid" in err[-1] and str(path) in err[-1]
        assert "Traceback" not in "\n".join(err) and "voxel" not in err[-1]
    # a bad density in a file is named by its voxel's index coordinates, not its place in a list
    a = _blob()
    a[7, 5, 4] = -1.0
    with pytest.raises(ValueError, match=r"neg.nvdb: densities must be finite and >= 0; voxel \(7, 5, 4\) is -1"):
        grid_bounds(Medium(sigma_s=1.0, density=str(_write_grid(tmp_path / "neg.nvdb", a))))


def _cli_blocks(tmp_path: Path, args: list[str], name: str, block: int = 3):
    """Per-block means over SEEDS renders of ``warp-spt args``: (mean, standard error), (B, B, 3)."""
    out = []
    for seed in SEEDS:
        path = tmp_path / f"{name}_{seed}.npy"
        assert main([*args, *CAMERA, *PLAIN, "--seed", str(seed), "-out", str(path)]) == 0
        img = np.load(path)
        h, w = img.shape[:2]
        out.append(img.reshape(h // block, block, w // block, block, 3).mean(axis=(1, 3)))
    stack = np.array(out)
    return stack.mean(0), stack.std(0, ddof=1) / np.sqrt(len(stack))


def test_volume_places_the_grid_in_its_own_bounds_as_a_hand_built_box_would(tmp_path, capsys):
    a = _blob()
    path = _write_grid(tmp_path / "blob.nvdb", a)
    box = _expected_bounds(a)
    assert np.allclose(grid_bounds(Medium(sigma_s=1.0, density=str(path))), box, atol=1e-6)
    words = ["sigma_a=3", "sigma_s=2"]
    flag, sflag = _cli_blocks(tmp_path, ["--volume", str(path), *words], "flag")
    said = capsys.readouterr().err
    corner = lambda v: "(" + ", ".join(f"{x:.4g}" for x in v) + ")"    # noqa: E731
    assert f"--volume {path}: a box from {corner(box[0])} to {corner(box[1])}, the grid's own bounds" in said
    # by hand: the box as an OBJ, its material a pass-through surface holding the grid
    objs, mtls = write_scene_files(tmp_path, "by_hand", box_obj(lo=box[0], hi=box[1], material="m"),
                                   "newmtl m\nindex_matched\nmedium_sigma_a 3\nmedium_sigma_s 2\n"
                                   "medium_density blob.nvdb\n")
    hand, shand = _cli_blocks(tmp_path, ["-obj", objs[0], "-mtl", mtls[0]], "hand")
    t = (flag - hand) / np.sqrt(sflag ** 2 + shand ** 2 + 1e-12)
    assert np.abs(t).max() < T_BLOCK, np.abs(t).max()
    # the medium is seen: where the box is (the middle blocks) the sky is dimmed; the border is the
    # empty scene's image, the sky of 1
    assert flag[1:3, 1:3].mean() < 0.95 and np.allclose(flag[0, 0], 1.0, atol=1e-6), flag[..., 0]


def _model(folder: Path, scale: float) -> tuple[list[str], list[str]]:
    return write_scene_files(folder, f"model_{scale:g}", box_obj(lo=(-1 * scale, -0.5 * scale, -0.7 * scale),
                                                                 hi=(1 * scale, 0.5 * scale, 0.7 * scale), material="m"),
                             "newmtl m\nKd 0.6 0.5 0.4\n")


def _framed_means(tmp_path: Path, scale: float, fog: list[str]) -> np.ndarray:
    objs, mtls = _model(tmp_path, scale)
    means = []
    for seed in SEEDS[:4]:
        out = tmp_path / f"fog_{scale:g}_{seed}.npy"
        assert main(["-obj", objs[0], "-mtl", mtls[0], *fog, "-res", "16", "12", "-sr", "8", "-depth", "6",
                     "--seed", str(seed), "-out", str(out)]) == 0
        means.append(np.load(out).mean())
    return np.array(means)


def test_fog_without_coefficients_looks_the_same_at_any_scale(tmp_path, capsys):
    small, large = (_framed_means(tmp_path, s, ["--fog", "g=0"]) for s in (1.0, 100.0))
    said = capsys.readouterr().err
    assert "fog: sigma_s" in said and "(0.5 and 0.1 over its size: --fog without sigma_s and sigma_a)" in said
    se = np.sqrt(small.var(ddof=1) / len(small) + large.var(ddof=1) / len(large))
    assert abs(small.mean() - large.mean()) < 5 * se + 1e-4, (small, large, se)
    # the control: coefficients that are given are per scene unit, the same fog thick on the larger
    fixed = ["--fog", "sigma_s=0.2", "--fog", "sigma_a=0.05"]
    small_abs, large_abs = (_framed_means(tmp_path, s, fixed) for s in (1.0, 100.0))
    assert abs(small_abs.mean() - large_abs.mean()) > 10 * se, (small_abs, large_abs)


def test_the_api_places_the_same_box_and_a_missing_file_is_one_line_before_loading(tmp_path, capsys):
    import warp_spt
    from warp_spt.io.mtl import builtin_clay
    from warp_spt.scene.media import interface_rows

    a = _blob()
    path = _write_grid(tmp_path / "blob.nvdb", a)
    scene, box = warp_spt.add_volume(warp_spt.Scene.empty(builtin_clay()), str(path), sigma_a=0.5)
    assert np.allclose(box, _expected_bounds(a), atol=1e-6) and np.allclose(scene.bounds, box, atol=1e-6)
    (name,) = scene.interiors
    m = scene.interiors[name]
    assert name == "volume blob.nvdb"
    assert m.sigma_s == (1.0,) * 3 and m.sigma_a == (0.5,) * 3 and m.density == str(path)
    assert interface_rows(scene.materials)[scene.materials.names.index(name)]     # pass-through walls
    again, _ = warp_spt.add_volume(scene, str(path))      # a second one gets a name of its own
    assert len(again.interiors) == 2
    status = main(["--volume", str(tmp_path / "missing.nvdb"), "-out", str(tmp_path / "x.png")])
    err = capsys.readouterr().err.strip().splitlines()
    assert status == 1 and len(err) == 1 and "cannot read --volume file" in err[0], err
    assert main(["--volume", "sigma_s=2", "-out", str(tmp_path / "x.png")]) == 2
    assert "expected a .nvdb file first" in capsys.readouterr().err
    assert main(["--volume", str(path), "--frames", "0:2", "-out", str(tmp_path / "f_{frame}.png")]) == 2
    assert "--volume alone renders one image" in capsys.readouterr().err


def test_the_viewer_takes_the_same_fog_rule():
    """The viewer's --fog without coefficients leaves them to its scene-sized default, which is the
    command line's (scene.media.scene_fog); coefficients given are kept as they are."""
    from types import SimpleNamespace

    from warp_spt.cli.view import build_parser, lighting_settings
    from warp_spt.scene.media import scene_fog
    from warp_spt.viewer import lighting
    from warp_spt.viewer.session import ViewSettings

    bare = lighting_settings(build_parser().parse_args(["--fog", "g=0.4"]))
    assert bare["fog"] and bare["fog_g"] == 0.4 and not {"fog_sigma_s", "fog_sigma_a"} & set(bare)
    given = lighting_settings(build_parser().parse_args(["--fog", "sigma_s=0.2"]))
    assert given["fog_sigma_s"] == (0.2,) * 3 and "fog_sigma_a" not in given
    camera = SimpleNamespace(direction=(0.0, 1.0, 0.0))
    for size in (0.15, 500.0):
        s = lighting.placed(ViewSettings(), set(bare), (0.0, 0.0, 1.0), camera, (0.0, 0.0, 0.0), size)
        assert (s.fog_sigma_s, s.fog_sigma_a) == (scene_fog(size)["sigma_s"], scene_fog(size)["sigma_a"])
        assert abs(max(s.fog_sigma_s) * size - 0.5) < 1e-6
