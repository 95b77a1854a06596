"""Texture atlas packing and the kernel-side lookups (nearest, bilinear, checker)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp

from warp_spt.device.textures import (
    checker,
    checker_np,
    pack_atlas,
    sample_texture,
    sample_texture_np,
    tile_view,
)

DEVICE = "cpu"
GREEN = (0.25, 0.75, 0.25)
WHITE = (1.0, 1.0, 1.0)


@wp.kernel(enable_backward=False)
def sample_kernel(
    texels: wp.array(dtype=wp.vec3),
    tiles: wp.array(dtype=wp.vec4i),
    tex: int,
    uv: wp.array(dtype=wp.vec2),
    bilinear: int,
    out: wp.array(dtype=wp.vec3),
):
    i = wp.tid()
    out[i] = sample_texture(texels, tiles, tex, uv[i], bilinear)


@wp.kernel(enable_backward=False)
def checker_kernel(uv: wp.array(dtype=wp.vec2), out: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    out[i] = checker(uv[i])


def run_sample(atlas, tex: int, uv, bilinear: bool, device: str = DEVICE) -> np.ndarray:
    uv = np.asarray(uv, dtype=np.float32).reshape(-1, 2)
    out = wp.zeros(len(uv), dtype=wp.vec3, device=device)
    wp.launch(sample_kernel, dim=len(uv), device=device, inputs=[
        wp.array(atlas.texels, dtype=wp.vec3, device=device),
        wp.array(atlas.tiles, dtype=wp.vec4i, device=device),
        tex, wp.array(uv, dtype=wp.vec2, device=device), int(bilinear), out])
    return out.numpy()


def run_checker(uv, device: str = DEVICE) -> np.ndarray:
    uv = np.asarray(uv, dtype=np.float32).reshape(-1, 2)
    out = wp.zeros(len(uv), dtype=wp.vec3, device=device)
    wp.launch(checker_kernel, dim=len(uv), device=device,
              inputs=[wp.array(uv, dtype=wp.vec2, device=device), out])
    return out.numpy()


def distinct_image(h: int, w: int, base: float = 0.0) -> np.ndarray:
    """Every texel different and >= 1 (so bleeding from empty atlas space would show):
    channel 0 = row + 1, 1 = column + 1, 2 = a unique id."""
    r, c = np.meshgrid(np.arange(1, h + 1), np.arange(1, w + 1), indexing="ij")
    return np.stack([r, c, r * w + c + base], axis=-1).astype(np.float32)


@pytest.fixture(scope="module")
def scene_textures():
    """Non-square 3x5 (H x W) and 7x2 textures, a square one, and a neighbour full of 1000s."""
    imgs = [distinct_image(3, 5), distinct_image(7, 2, 100.0), distinct_image(4, 4, 200.0),
            np.full((6, 6, 3), 1000.0, dtype=np.float32)]
    return imgs, pack_atlas(imgs)


# ------------------------------------------------------------------ packing


def test_packing_no_overlap_and_exact_copies():
    rng = np.random.default_rng(1)
    imgs = [rng.random((int(rng.integers(1, 40)), int(rng.integers(1, 40)), 3)).astype(np.float32)
            for _ in range(25)]
    atlas = pack_atlas(imgs)
    assert atlas.texels.dtype == np.float32 and atlas.tiles.dtype == np.int32
    # exactly the sum of the areas: every texel belongs to exactly one texture
    assert atlas.texels.shape == (sum(im.shape[0] * im.shape[1] for im in imgs), 3)
    cover = np.zeros(len(atlas.texels), dtype=int)
    for k, ((offset, w, h, stride), im) in enumerate(zip(atlas.tiles, imgs)):
        assert (w, h, stride) == (im.shape[1], im.shape[0], im.shape[1])
        assert 0 <= offset and offset + h * stride <= len(atlas.texels)
        cover[offset:offset + h * stride] += 1
        # independent of tile_view: row r of the image is texels[offset + r*w : offset + (r+1)*w]
        rows = np.stack([atlas.texels[offset + r * w:offset + (r + 1) * w] for r in range(h)])
        assert np.array_equal(rows, im) and np.array_equal(atlas.texture(k), im)
    assert (cover == 1).all()


def test_tile_view_writes_through_and_fits_gradients():
    atlas = pack_atlas([np.zeros((2, 3, 3), np.float32), np.zeros((3, 2, 3), np.float32)])
    tile_view(atlas.texels, atlas.tiles[1])[0, 1] = 7.0          # row 0 (top), column 1 of texture 1
    assert np.flatnonzero(atlas.texels[:, 0]).tolist() == [6 + 1]
    grad = np.arange(len(atlas.texels) * 3, dtype=np.float64).reshape(-1, 3)
    assert tile_view(grad, atlas.tiles[0]).shape == (2, 3, 3)


def test_packing_empty_and_limits():
    empty = pack_atlas([])
    assert empty.texels.shape == (1, 3) and empty.tiles.tolist() == [[0, 1, 1, 1]]
    # zero-copy views of absurd size: rejected from the shapes alone, naming the sizes
    huge = np.broadcast_to(np.float32(0.0), (50_000, 50_000, 3))
    with pytest.raises(ValueError, match="50000x50000"):
        pack_atlas([huge])
    with pytest.raises(ValueError, match=r"texture 1: expected an \(H, W, 3\)"):
        pack_atlas([np.zeros((2, 2, 3)), np.zeros((2, 2))])
    with pytest.raises(ValueError, match="texture 0: texel values must be finite"):
        pack_atlas([np.full((2, 2, 3), np.nan)])


# ------------------------------------------------------------------ nearest


def expected_nearest(img: np.ndarray, u: float, v: float) -> np.ndarray:
    """Direct indexing of the source image: repeat wrap, v = 0 at the bottom row (row 0 = top)."""
    h, w = img.shape[:2]
    col = math.floor(float(np.float32(u) * np.float32(w))) % w     # Python % is already non-negative
    row_from_bottom = math.floor(float(np.float32(v) * np.float32(h))) % h
    return img[h - 1 - row_from_bottom, col]


def test_nearest_known_points(scene_textures):
    imgs, atlas = scene_textures
    img = imgs[0]                                    # 3 rows x 5 columns
    cases = {
        (0.0, 0.0): img[2, 0],                       # bottom-left
        (0.99, 0.99): img[0, 4],                     # top-right
        (-0.01, 0.5): img[1, 4],                     # floor, not trunc: wraps to the last column
        (0.5, 1.0): img[2, 2],                       # v = 1 wraps to the bottom row
        (1.2, -0.2): img[0, 1],                      # u: floor(6) % 5 = 1; v: floor(-0.6) = -1 -> top
        (0.5, 0.7): img[0, 2],                       # rows use the real height 3 (Q5), not the width
    }
    got = run_sample(atlas, 0, list(cases), bilinear=False)
    assert np.array_equal(got, np.array(list(cases.values())))


@pytest.mark.parametrize("tex", [0, 1, 2])
def test_nearest_matches_source_indexing(scene_textures, tex):
    imgs, atlas = scene_textures
    img = imgs[tex]
    h, w = img.shape[:2]
    rng = np.random.default_rng(tex)
    uv = np.concatenate([
        rng.uniform(-3, 3, size=(400, 2)),
        rng.uniform(-1e5, 1e5, size=(50, 2)),
        np.array([[i / w, j / h] for i in range(-w, 2 * w + 1) for j in range(-h, 2 * h + 1)]),  # edges
    ]).astype(np.float32)
    got = run_sample(atlas, tex, uv, bilinear=False)
    want = np.array([expected_nearest(img, u, v) for u, v in uv])
    assert np.array_equal(got, want)
    assert np.array_equal(got, sample_texture_np(img, uv))


def test_nearest_non_finite_and_huge_stay_in_tile(scene_textures):
    imgs, atlas = scene_textures
    img = imgs[1]
    uv = np.array([[np.nan, np.nan], [np.inf, -np.inf], [1e30, -1e30], [-3e9, 7e9], [np.nan, 0.5]])
    got = run_sample(atlas, 1, uv, bilinear=False)
    assert np.array_equal(got[0], img[-1, 0])        # NaN behaves as 0: bottom-left texel
    assert np.array_equal(got[4], expected_nearest(img, 0.0, 0.5))
    ids = set(img[..., 2].ravel().tolist())
    assert {float(x) for x in got[:, 2]} <= ids      # always a texel of this texture
    assert np.array_equal(got, sample_texture_np(img, uv))


def test_out_of_range_texture_index_is_black(scene_textures):
    _, atlas = scene_textures
    assert np.array_equal(run_sample(atlas, 99, [[0.5, 0.5]], False), np.zeros((1, 3)))
    assert np.array_equal(run_sample(atlas, -1, [[0.5, 0.5]], True), np.zeros((1, 3)))


# ------------------------------------------------------------------ bilinear


def test_bilinear_hand_computed(scene_textures):
    imgs, atlas = scene_textures
    img = imgs[0]                                    # 3 x 5; texel centres at (i + 0.5) / n
    bottom = img[2]
    cases = [
        ((0.5 / 5, 0.5 / 3), bottom[0]),                                   # a texel centre
        ((1.0 / 5, 0.5 / 3), 0.5 * (bottom[0] + bottom[1])),              # between two columns
        ((0.0, 0.5 / 3), 0.5 * (bottom[4] + bottom[0])),                  # wraps to the last column
        ((0.0, 0.0), 0.25 * (img[2, 0] + img[2, 4] + img[0, 0] + img[0, 4])),  # corner: 4-way wrap
        ((1.25 / 5, 1.0 / 3), 0.5 * (0.25 * bottom[0] + 0.75 * bottom[1])
         + 0.5 * (0.25 * img[1, 0] + 0.75 * img[1, 1])),
    ]
    got = run_sample(atlas, 0, [c[0] for c in cases], bilinear=True)
    np.testing.assert_allclose(got, np.array([c[1] for c in cases]), rtol=0, atol=1e-5)


@pytest.mark.parametrize("tex", [0, 1, 2])
def test_bilinear_matches_reference_and_never_bleeds(scene_textures, tex):
    imgs, atlas = scene_textures
    img = imgs[tex]
    rng = np.random.default_rng(10 + tex)
    uv = np.concatenate([rng.uniform(-4, 4, size=(500, 2)), rng.uniform(-1e4, 1e4, size=(50, 2)),
                         [[np.nan, 0.3], [1e30, -1e30]]]).astype(np.float32)
    got = run_sample(atlas, tex, uv, bilinear=True)
    np.testing.assert_allclose(got, sample_texture_np(img, uv, bilinear=True), rtol=0, atol=1e-4)
    # the neighbouring tile holds 1000s: any bleed would leave the image's value range
    assert (got >= img.min(axis=(0, 1)) - 1e-4).all() and (got <= img.max(axis=(0, 1)) + 1e-4).all()


# ------------------------------------------------------------------ checker


def test_checker_hand_computed():
    cases = [
        ((0.5, 0.003), WHITE),     # k = trunc(1.5) = 1: odd
        ((0.5, 0.004), GREEN),     # k = 2
        ((0.5, 0.007), WHITE),     # k = 3
        ((-0.5, 0.003), GREEN),    # k = -1: Java's remainder is -1, not 1
        ((-0.5, -0.003), WHITE),   # k = 1
        ((0.0, 0.0), GREEN),       # spheres have uv = 0
        ((0.0009, 1.0), GREEN),    # k = trunc(0.9) = 0
        ((np.nan, 0.5), GREEN),    # Java: (int) NaN = 0
        ((1e20, 1e20), WHITE),     # saturates to Integer.MAX_VALUE, which is odd
        ((-1e20, 1e20), GREEN),    # saturates to Integer.MIN_VALUE, which is even
    ]
    got = run_checker([c[0] for c in cases])
    want = np.array([c[1] for c in cases], dtype=np.float32)
    assert np.array_equal(got, want)
    assert np.array_equal(checker_np([c[0] for c in cases]), want)


def test_checker_matches_reference():
    rng = np.random.default_rng(5)
    uv = np.concatenate([rng.uniform(-1, 1, size=(3000, 2)), rng.uniform(-3e3, 3e3, size=(300, 2))])
    uv = uv.astype(np.float32)
    got = run_checker(uv)
    assert np.array_equal(got, checker_np(uv))
    assert 0.15 < (got[:, 0] == 1.0).mean() < 0.35     # only positive odd k: about 1/4

