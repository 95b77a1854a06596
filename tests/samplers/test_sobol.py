"""The Sobol' samplers (warp_spt.samplers.sobol_points under its two scrambles: ``sobol``, Owen's, and
``sobol-affine``) against published points, independent numpy references (tests/support/sobol_reference.py,
tests/support/sobol_affine_reference.py), the net property, Owen's pair law, and statistics with stated
error rates. A property of the points is one test parametrised over both scrambles; Owen's building
blocks have their own. ``sobol-affine``'s error against ``sobol``'s: tests/samplers/test_sobol_affine.py.

Statistical tests: each has a false-failure probability of at most 1e-6 under the hypothesis being
tested (the module is correct), so the whole file fails spuriously with probability < 1e-3. Seeds
are fixed, so a pass is reproducible; the bounds say how surprising a failure would be.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
import warp as wp

from warp_spt.samplers import get_sampler
from warp_spt.samplers import sobol as S
from warp_spt.samplers import sobol_affine as A
from warp_spt.samplers import sobol_points as P
from warp_spt.samplers.base import sampler_state

from tests.support import sobol_affine_reference as RA
from tests.support import sobol_reference as R

wp.config.log_level = wp.LOG_WARNING   # no banner or module-load lines (Warp 1.19 dropped config.quiet)
DEVICE = "cpu"
Z_1E6 = 4.8916    # two-sided standard normal quantile for probability 1e-6
Z_1E6_ONE = 4.7534  # one-sided


def _kernels(points: P.Points) -> SimpleNamespace:
    """The test kernels of one scramble's points (all made at import: the module compiles once)."""
    one, two, scramble = points.one, points.two, points.scramble
    sample, shuffle, x_of = scramble.sample, scramble.shuffle, scramble.x

    @wp.kernel
    def evaluate(seeds: wp.array(dtype=wp.uint32), pixels: wp.array(dtype=int), indices: wp.array(dtype=int),
                 dims: wp.array(dtype=int), out2: wp.array(dtype=wp.vec2), out1: wp.array(dtype=float)):
        t = wp.tid()
        out2[t] = two(seeds[t], pixels[t], indices[t], dims[t])
        out1[t] = one(seeds[t], pixels[t], indices[t], dims[t])

    @wp.kernel
    def sequence(seed: wp.uint32, pixel: int, offset: int, dim: int, out: wp.array(dtype=wp.vec2)):
        t = wp.tid()
        out[t] = two(seed, pixel, offset + t, dim)

    @wp.kernel
    def shuffled(key: wp.uint32, indices: wp.array(dtype=int), out: wp.array(dtype=wp.uint32)):
        t = wp.tid()
        out[t] = shuffle(key, sample(indices[t]))

    @wp.kernel
    def pair(a: wp.uint32, b: wp.uint32, out: wp.array2d(dtype=float)):
        """The x scramble of Sobol' indices a and b under the key of request t (one key per thread)."""
        t = wp.tid()
        key = P.request_key(P.pixel_key(wp.uint32(7), t), 3)
        out[t, 0] = x_of(key, a)
        out[t, 1] = x_of(key, b)

    return SimpleNamespace(evaluate=evaluate, sequence=sequence, shuffled=shuffled, pair=pair)


KERNELS = {"sobol": _kernels(S.POINTS), "sobol-affine": _kernels(A.POINTS)}
REFERENCES = {"sobol": (R.sobol_2d, R.sobol_1d), "sobol-affine": (RA.affine_2d, RA.affine_1d)}
SCRAMBLES = list(KERNELS)
POINTS = {"sobol": S.POINTS, "sobol-affine": A.POINTS}


def _arr(x, dtype):
    return wp.array(np.asarray(x), dtype=dtype, device=DEVICE)


def evaluate(name, seed, pixel, index, dim):
    """``two`` and ``one`` of scramble ``name`` at broadcast (seed, pixel, index, dim) arrays, as numpy."""
    seed, pixel, index, dim = (a.ravel() for a in np.broadcast_arrays(seed, pixel, index, dim))
    n = seed.size
    out2 = wp.empty(n, dtype=wp.vec2, device=DEVICE)
    out1 = wp.empty(n, dtype=float, device=DEVICE)
    inputs = [_arr(seed.astype(np.uint32), wp.uint32), _arr(pixel.astype(np.int32), int),
              _arr(index.astype(np.int32), int), _arr(dim.astype(np.int32), int), out2, out1]
    wp.launch(KERNELS[name].evaluate, n, inputs=inputs, device=DEVICE)
    return out2.numpy(), out1.numpy()


def sequence(name, seed, pixel, dim, n, offset=0):
    """Points offset .. offset+n-1 of one pixel and dimension pair, through the range kernel."""
    out = wp.empty(n, dtype=wp.vec2, device=DEVICE)
    wp.launch(KERNELS[name].sequence, n, inputs=[wp.uint32(seed), pixel, offset, dim, out], device=DEVICE)
    return out.numpy()


def _assert_nets(points: np.ndarray, k: int, where: str) -> None:
    """Every aligned block of 2**k points is a (0,k,2)-net: for each split k = a + b, the 2**k cells
    of size 2**-a x 2**-b hold one point each."""
    q = (points.astype(np.float64) * 2.0**24).astype(np.int64)        # exact 24-bit integers
    blocks = q.reshape(-1, 1 << k, 2)
    for a in range(k + 1):
        cells = (blocks[..., 0] >> (24 - a)) << (k - a) | (blocks[..., 1] >> (24 - (k - a)))
        ok = (np.sort(cells, axis=1) == np.arange(1 << k)).all(axis=1)
        assert ok.all(), f"{where}: block {np.argmin(ok)} of 2**{k} is not a net for cells 2**-{a} x 2**-{k - a}"


def chi2_upper(dof: int, z: float) -> float:
    """Wilson-Hilferty approximation of the chi-square quantile at standard-normal quantile z (relative
    error < 1e-3 for dof >= 30 at these tails, far below the margin a real defect produces)."""
    c = 2.0 / (9.0 * dof)
    return dof * (1.0 - c + z * math.sqrt(c)) ** 3


def _corr(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Pearson correlation along the last axis."""
    u = u - u.mean(axis=-1, keepdims=True)
    v = v - v.mean(axis=-1, keepdims=True)
    return (u * v).sum(axis=-1) / np.sqrt((u * u).sum(axis=-1) * (v * v).sum(axis=-1))


# --- the points under either scramble ---------------------------------------------------------------

@pytest.mark.parametrize("name", SCRAMBLES)
def test_samples_equal_the_reference_bit_for_bit(name):
    """Integer arithmetic throughout, and an exact 24-bit -> float32 conversion: no rounding to allow."""
    rng = np.random.default_rng(12)
    n = 30000
    seed = rng.integers(0, 2**32, n, dtype=np.uint64)
    pixel = rng.integers(0, 2**31, n)
    index = np.where(rng.random(n) < 0.5, rng.integers(0, 2**16, n), rng.integers(0, 2**31, n))
    dim = rng.integers(0, 1000, n)
    seed[:6], pixel[:6], index[:6], dim[:6] = 0, 0, [0, 1, 2, 3, 2**31 - 2, 2**31 - 1], 0
    got2, got1 = evaluate(name, seed, pixel, index, dim)
    ref2, ref1 = REFERENCES[name]
    np.testing.assert_array_equal(got2, ref2(seed, pixel, index, dim))
    np.testing.assert_array_equal(got1, ref1(seed, pixel, index, dim))
    np.testing.assert_array_equal(got1, got2[:, 0])          # documented: 1D at d is 2D's x at d
    assert got2.min() >= 0.0 and got2.max() < 1.0


@pytest.mark.parametrize("name", SCRAMBLES)
def test_values_are_a_pure_function_of_their_arguments(name):
    """Determinism: the same request gives the same bits whatever the launch, its size and order."""
    rng = np.random.default_rng(22)
    n = 5000
    args = [rng.integers(0, 2**32, n, dtype=np.uint64), rng.integers(0, 2**31, n), rng.integers(0, 2**31, n),
            rng.integers(0, 200, n)]
    whole, _ = evaluate(name, *args)
    perm = rng.permutation(n)
    again, _ = evaluate(name, *(a[perm] for a in args))
    np.testing.assert_array_equal(again, whole[perm])
    np.testing.assert_array_equal(evaluate(name, *(a[:7] for a in args))[0], whole[:7])


@pytest.mark.parametrize("name", SCRAMBLES)
def test_index_shuffle_maps_aligned_blocks_onto_aligned_blocks(name):
    rng = np.random.default_rng(13)
    out = wp.empty(1 << 12, dtype=wp.uint32, device=DEVICE)
    for m in (1, 3, 8, 12):
        for j in (0, 1, int(rng.integers(0, 2**(31 - m)))):
            block = np.arange(j << m, (j + 1) << m, dtype=np.int32)
            key = int(rng.integers(0, 2**32))
            o = out[:block.size]
            wp.launch(KERNELS[name].shuffled, block.size, inputs=[wp.uint32(key), _arr(block, int), o], device=DEVICE)
            got = o.numpy().astype(np.uint64)
            assert np.unique(got >> np.uint64(m)).size == 1, (m, j)
            np.testing.assert_array_equal(np.sort(got & np.uint64((1 << m) - 1)), np.arange(1 << m))


@pytest.mark.parametrize("seed,pixel,dim", [(0, 0, 0), (1, 7, 2), (99, 123456, 17), (2**32 - 1, 2**31 - 1, 999)])
@pytest.mark.parametrize("name", SCRAMBLES)
def test_every_aligned_power_of_two_block_is_a_net(name, seed, pixel, dim):
    n = 1 << 12
    for offset in (0, 1 << 20, 2**31 - n):                               # first, middle and last block
        pts = sequence(name, seed, pixel, dim, n, offset)
        for k in range(13):
            _assert_nets(pts, k, f"{name}: seed {seed} pixel {pixel} dim {dim} offset {offset}")


@pytest.mark.parametrize("name", SCRAMBLES)
def test_a_large_block_is_a_net(name):
    """Beyond 2**15 samples ``sobol``'s scrambles use their shortcuts (shared tail flips, digitally
    shifted index blocks); they are still nested scrambles, so a 2**17 block is a (0,17,2)-net."""
    _assert_nets(sequence(name, 5, 77, 6, 1 << 17, 1 << 17), 17, f"{name}: 2**17 samples")


@pytest.mark.parametrize("name", SCRAMBLES)
def test_1d_is_stratified_in_every_aligned_block(name):
    n = 1 << 12
    _, vals = evaluate(name, 3, 42, np.arange(n), 5)
    q = (vals.astype(np.float64) * 2.0**24).astype(np.int64)
    for k in range(13):
        strata = np.sort(q.reshape(-1, 1 << k) >> (24 - k), axis=1)
        assert (strata == np.arange(1 << k)).all(), k


# ``sobol``'s value scramble is Owen's exactly within an aligned block of 2**15 samples (first differing
# digit k <= 14); beyond, points sharing a 15-bit prefix share their tail flips (sobol.py's Limits)
PAIR_CASES = [(name, k) for name in SCRAMBLES for k in (0, 1, 4, 9, 14)] + [("sobol-affine", k) for k in (15, 20)]


@pytest.mark.parametrize("name,k", PAIR_CASES)
def test_pairs_of_points_have_owens_joint_distribution(name, k):
    """The estimator's variance depends only on the joint law of each pair of points, so this is the
    property that gives Owen's error. Two Sobol' values whose first differing digit is k, scrambled
    under 2**16 keys: Owen's scrambling makes them share digits 0..k-1 (uniform), differ at digit k,
    and gives digits k+1, k+2, k+3 of each independent uniform bits. Checked jointly: A's two digits
    above k (where k >= 2), then the three digits below k of A and of B: a 256-cell (64 for k < 2)
    chi-square, and the shared and differing digits exactly. Several pairs per k, from close (the
    next digit differs too) to far."""
    rng = np.random.default_rng(100 + k)
    n = 1 << 16
    out = wp.empty((n, 2), dtype=float, device=DEVICE)
    for trial in range(3):
        a = int(rng.integers(0, 2**32))
        below = (1 << k) - 1                    # Sobol' dim 0 of index i has digit j = bit j of i
        b = (a & below) | ((~a) & (1 << k)) | (int(rng.integers(0, 2**32)) & ~((1 << (k + 1)) - 1))
        wp.launch(KERNELS[name].pair, n, inputs=[wp.uint32(a), wp.uint32(b), out], device=DEVICE)
        q = (out.numpy().astype(np.float64) * 2.0**24).astype(np.int64)
        qa, qb = q[:, 0], q[:, 1]
        assert (qa >> (24 - k) == qb >> (24 - k)).all() and (((qa ^ qb) >> (23 - k)) & 1 == 1).all()
        tail_a = (qa >> (20 - k)) & 7
        tail_b = (qb >> (20 - k)) & 7
        cells = tail_a * 8 + tail_b
        count = 64
        if k >= 2:
            cells = cells + 64 * ((qa >> (24 - k)) & 3)
            count = 256
        counts = np.bincount(cells, minlength=count)
        expected = n / count
        stat = float(((counts - expected) ** 2 / expected).sum())
        assert stat < chi2_upper(count - 1, Z_1E6_ONE), (k, trial, stat)


@pytest.mark.parametrize("index", [0, 1, 77777, 2**31 - 1])
@pytest.mark.parametrize("name", SCRAMBLES)
def test_values_at_one_sample_are_uniform_across_pixels(name, index):
    """At a fixed sample index, different pixels use independent scrambles, so their values are i.i.d.
    uniform: chi-square of 64 marginal bins per component and of an 8x8 grid of the pairs."""
    pixels = np.arange(1 << 14)
    limit = chi2_upper(63, Z_1E6_ONE)
    for dim in (0, 5):
        pts, _ = evaluate(name, 21, pixels, index, dim)
        expected = pixels.size / 64
        for counts in (np.bincount((pts[:, 0] * 64).astype(int), minlength=64),
                       np.bincount((pts[:, 1] * 64).astype(int), minlength=64),
                       np.bincount((pts[:, 0] * 8).astype(int) * 8 + (pts[:, 1] * 8).astype(int), minlength=64)):
            stat = float(((counts - expected) ** 2 / expected).sum())
            assert stat < limit, (dim, stat, limit)


@pytest.mark.parametrize("name", SCRAMBLES)
def test_dims_pixels_and_seeds_are_decorrelated_across_pixels(name):
    """Same sample index, M pixels: the pairs are i.i.d., so sqrt(M) r is standard normal."""
    m = 1 << 14
    pixels = np.arange(m)
    for index in (0, 5, 2**30 + 3):
        base, _ = evaluate(name, 8, pixels, index, 0)
        others = {"dim pair 2": evaluate(name, 8, pixels, index, 2)[0],
                  "seed 9": evaluate(name, 9, pixels, index, 0)[0],
                  "pixel + M": evaluate(name, 8, pixels + m, index, 0)[0],
                  "overlapping pair 1": evaluate(name, 8, pixels, index, 1)[0]}
        checks = {"x vs y": (base[:, 0], base[:, 1])}
        for other, o in others.items():
            checks[f"x vs {other} x"] = (base[:, 0], o[:, 0])
            checks[f"y vs {other} y"] = (base[:, 1], o[:, 1])
        for check, (u, v) in checks.items():
            assert abs(_corr(u, v)) * math.sqrt(m) < Z_1E6, (index, check)


@pytest.mark.parametrize("name", SCRAMBLES)
def test_dims_pixels_and_seeds_are_decorrelated_within_a_pixel(name):
    """N = 4096 consecutive samples of one pixel. Two dimension pairs are paired by independent
    nested shuffles; each aligned pair of samples then has both pairs' first digits in the
    configuration (lo,lo)+(hi,hi) or (lo,hi)+(hi,lo), one coin per aligned sample pair, so the
    correlation's variance is at most 2/N, twice that of independent numbers (the price of
    stratifying every aligned pair; see sobol_points' docstring). So N r^2 / 2 is at most chi-square(1)
    and its sum over M independent pixels at most chi-square(M)."""
    n, m = 1 << 12, 32
    pixel = np.arange(m)[:, None]
    idx = np.arange(n)[None, :]
    a = evaluate(name, 4, pixel, idx, 0)[0].reshape(m, n, 2)
    pairs = {"dims 0 vs 2": evaluate(name, 4, pixel, idx, 2)[0].reshape(m, n, 2),
             "seed 4 vs 5": evaluate(name, 5, pixel, idx, 0)[0].reshape(m, n, 2),
             "pixel p vs p + M": evaluate(name, 4, pixel + m, idx, 0)[0].reshape(m, n, 2)}
    limit = chi2_upper(m, Z_1E6_ONE)
    for pair, b in pairs.items():
        for ca in (0, 1):
            for cb in (0, 1):
                stat = float((n * _corr(a[..., ca], b[..., cb]) ** 2 / 2).sum())
                assert stat < limit, (pair, ca, cb, stat, limit)


@pytest.mark.parametrize("name", SCRAMBLES)
def test_a_slice_of_indices_equals_that_part_of_the_whole_run(name):
    whole = sequence(name, 17, 31, 4, 1 << 12)
    for offset, n in ((0, 1), (1000, 300), (2048, 2048), (4095, 1)):
        np.testing.assert_array_equal(sequence(name, 17, 31, 4, n, offset), whole[offset:offset + n])
    parts_mean = (sequence(name, 17, 31, 4, 1000).sum(axis=0, dtype=np.float64)
                  + sequence(name, 17, 31, 4, 3096, 1000).sum(axis=0, dtype=np.float64)) / 4096
    np.testing.assert_array_equal(parts_mean, whole.sum(axis=0, dtype=np.float64) / 4096)


@pytest.mark.parametrize("offsets", [(3,), (1, 4, 5), (0, 1, 3, 4, 5, 7), (7, 2, 9, 0, 11)])
@pytest.mark.parametrize("name", SCRAMBLES)
def test_a_batch_equals_its_requests_one_by_one(name, offsets):
    """make_batch's lanes (padded to a power of two) are ``two``'s numbers at base + offset (so a 1-D
    request's, its x), bit for bit as the numpy reference gives them, for indices on both sides of
    ``sobol``'s exactly scrambled 2**15 and keys of the whole range."""
    batch = get_sampler(name).make_batch(offsets)
    lanes = 1 << (max(len(offsets), 2) - 1).bit_length()

    @wp.kernel(module="unique")
    def run(seeds: wp.array(dtype=wp.uint32), pixels: wp.array(dtype=int), indices: wp.array(dtype=int),
            bases: wp.array(dtype=int), out: wp.array2d(dtype=float)):
        t = wp.tid()
        st = sampler_state(seeds[t], pixels[t], indices[t], P.pixel_key(seeds[t], pixels[t]))
        v = batch(st, bases[t])
        for j in range(wp.static(2 * lanes)):
            out[t, j] = v[j]

    rng = np.random.default_rng(11)
    n = 4000
    seed = rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32)
    pixel = rng.integers(0, 2**31, n).astype(np.int32)
    index = np.where(rng.random(n) < 0.5, rng.integers(0, 2**15, n), rng.integers(0, 2**31, n)).astype(np.int32)
    base = rng.integers(0, 1000, n).astype(np.int32)
    out = wp.empty((n, 2 * lanes), dtype=float, device=DEVICE)
    wp.launch(run, n, inputs=[_arr(seed, wp.uint32), _arr(pixel, int), _arr(index, int), _arr(base, int), out],
              device=DEVICE)
    got = out.numpy().reshape(n, 2, lanes)
    padded = tuple(offsets) + (offsets[-1],) * (lanes - len(offsets))
    ref2 = REFERENCES[name][0]
    for k, off in enumerate(padded):
        want = ref2(seed.astype(np.uint64), pixel.astype(np.int64), index.astype(np.int64), base + off)
        np.testing.assert_array_equal(got[:, 0, k], want[:, 0], err_msg=f"offset {off}: x")
        np.testing.assert_array_equal(got[:, 1, k], want[:, 1], err_msg=f"offset {off}: y")


@pytest.mark.parametrize("name", SCRAMBLES)
def test_the_registry_record(name):
    """``SAMPLERS[name]`` is the points of its scramble: random access, with a batch, and a batch of
    no requests is an error."""
    s = get_sampler(name)
    assert s.name == name and s.random_access and s.make_batch is not None
    assert s.summary == POINTS[name].scramble.summary
    with pytest.raises(ValueError, match="at least one dimension offset"):
        s.make_batch(())


# --- Owen's scramble (sobol) and the unscrambled points ------------------------------------------------

@wp.kernel
def _parts_kernel(values: wp.array(dtype=wp.uint32), seeds: wp.array(dtype=wp.uint32),
                  out: wp.array2d(dtype=wp.uint32), unit: wp.array(dtype=float)):
    """The building blocks: Sobol' dims 0 and 1, the Owen scramble and the index shuffle."""
    t = wp.tid()
    v = values[t]
    out[t, 0] = P.reverse_bits(v)
    out[t, 1] = P.sobol_dim1(v)
    out[t, 2] = S.owen_scramble(v, seeds[t])
    out[t, 3] = S.exact_flips(v, seeds[t])
    out[t, 4] = S.shuffled_index(seeds[t], int(v & wp.uint32(0x7FFFFFFF)))
    unit[t] = P.to_unit(v)


def parts(values, seeds):
    """Columns: reverse_bits, sobol_dim1, owen_scramble, exact_flips, shuffled_index."""
    n = len(values)
    out = wp.empty((n, 5), dtype=wp.uint32, device=DEVICE)
    unit = wp.empty(n, dtype=float, device=DEVICE)
    wp.launch(_parts_kernel, n, inputs=[_arr(np.asarray(values, dtype=np.uint32), wp.uint32),
                                        _arr(np.asarray(seeds, dtype=np.uint32), wp.uint32), out, unit], device=DEVICE)
    return out.numpy().astype(np.uint64), unit.numpy()


# The first 16 points of the standard 2D Sobol' sequence (Joe & Kuo's direction numbers; dimension 2 has
# s = 1, m_1 = 1) in the Gray-code order that common libraries emit, e.g.
# scipy.stats.qmc.Sobol(d=2, scramble=False). Written out by hand, not produced by the code under test.
PUBLISHED_GRAY_ORDER = np.array([
    [0, 0], [0.5, 0.5], [0.75, 0.25], [0.25, 0.75], [0.375, 0.375], [0.875, 0.875],
    [0.625, 0.125], [0.125, 0.625], [0.1875, 0.3125], [0.6875, 0.8125], [0.9375, 0.0625],
    [0.4375, 0.5625], [0.3125, 0.1875], [0.8125, 0.6875], [0.5625, 0.4375], [0.0625, 0.9375]])


def test_unscrambled_points_are_the_published_sobol_points():
    n = np.arange(16, dtype=np.uint64)
    gray = n ^ (n >> np.uint64(1))            # Gray-code order visits index gray(n) at step n
    out, _ = parts(gray, np.zeros(16))
    warp_pts = out[:, :2].astype(np.float64) / 2.0**32
    ref_pts = np.stack([R.sobol_u32(gray, 0), R.sobol_u32(gray, 1)], axis=1).astype(np.float64) / 2.0**32
    np.testing.assert_array_equal(warp_pts, PUBLISHED_GRAY_ORDER)
    np.testing.assert_array_equal(ref_pts, PUBLISHED_GRAY_ORDER)


def test_building_blocks_equal_the_reference_bit_for_bit():
    rng = np.random.default_rng(11)
    v = rng.integers(0, 2**32, 4000, dtype=np.uint64)
    v[:4] = [0, 1, 2**31, 2**32 - 1]
    seeds = rng.integers(0, 2**32, 4000, dtype=np.uint64)
    out, unit = parts(v, seeds)
    np.testing.assert_array_equal(out[:, 0], R.sobol_u32(v, 0))
    np.testing.assert_array_equal(out[:, 1], R.sobol_u32(v, 1))
    np.testing.assert_array_equal(out[:, 2], R.owen(v, seeds))
    top15 = np.uint64(0xFFFE0000)
    np.testing.assert_array_equal(out[:, 3], (R.owen(v, seeds, 15) ^ v) & top15)
    np.testing.assert_array_equal(out[:, 4], R.shuffle(v & np.uint64(0x7FFFFFFF), seeds))
    np.testing.assert_array_equal(unit, R.to_unit(v))
    assert unit.max() < 1.0 and unit[3] == np.float32(1 - 2.0**-24)   # 0xFFFFFFFF -> 1 - 2**-24
