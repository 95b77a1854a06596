"""The affine-scrambled Sobol' sampler (warp_spt.samplers.sobol_affine): an independent numpy reference
(tests/support/sobol_affine_reference.py), the net property, Owen's pair distribution, statistics with stated
error rates, and its error against ``sobol``'s on integrands with known values.

Statistical tests: each has a false-failure probability of at most 1e-6 under the hypothesis being
tested (the module is correct), so the file fails spuriously with probability < 1e-4. Seeds are
fixed, so a pass is reproducible; the bounds say how surprising a failure would be.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp

from warp_spt.samplers import get_sampler
from warp_spt.samplers import sobol as S
from warp_spt.samplers import sobol_affine as A

from tests.support import sobol_affine_reference as RA
from tests.samplers.test_sobol import Z_1E6, Z_1E6_ONE, _assert_nets, _corr, chi2_upper

wp.config.log_level = wp.LOG_WARNING
DEVICE = "cpu"


@wp.kernel
def _eval_kernel(seeds: wp.array(dtype=wp.uint32), pixels: wp.array(dtype=int), indices: wp.array(dtype=int),
                 dims: wp.array(dtype=int), out2: wp.array(dtype=wp.vec2), out1: wp.array(dtype=float)):
    t = wp.tid()
    out2[t] = A.affine_2d(seeds[t], pixels[t], indices[t], dims[t])
    out1[t] = A.affine_1d(seeds[t], pixels[t], indices[t], dims[t])


@wp.kernel
def _range_kernel(seed: wp.uint32, pixel: int, offset: int, dim: int, out: wp.array(dtype=wp.vec2)):
    t = wp.tid()
    out[t] = A.affine_2d(seed, pixel, offset + t, dim)


@wp.kernel
def _shuffle_kernel(key: wp.uint32, indices: wp.array(dtype=wp.uint32), out: wp.array(dtype=wp.uint32)):
    t = wp.tid()
    out[t] = A.shuffled(key, S.reverse_bits(indices[t]))


@wp.kernel
def _pair_kernel(a: wp.uint32, b: wp.uint32, out: wp.array2d(dtype=float)):
    """The x scramble of Sobol' indices a and b under the key of request t (one key per thread)."""
    t = wp.tid()
    key = A.request_key(S.pixel_key(wp.uint32(7), t), 3)
    out[t, 0] = A.scrambled_x(key, a)
    out[t, 1] = A.scrambled_x(key, b)


def _arr(x, dtype):
    return wp.array(np.asarray(x), dtype=dtype, device=DEVICE)


def evaluate(seed, pixel, index, dim):
    """affine_2d and affine_1d of broadcast (seed, pixel, index, dim) arrays, as numpy."""
    seed, pixel, index, dim = (a.ravel() for a in np.broadcast_arrays(seed, pixel, index, dim))
    n = seed.size
    out2 = wp.empty(n, dtype=wp.vec2, device=DEVICE)
    out1 = wp.empty(n, dtype=float, device=DEVICE)
    wp.launch(_eval_kernel, n, inputs=[_arr(seed.astype(np.uint32), wp.uint32), _arr(pixel.astype(np.int32), int),
                                       _arr(index.astype(np.int32), int), _arr(dim.astype(np.int32), int), out2, out1],
              device=DEVICE)
    return out2.numpy(), out1.numpy()


def sequence(seed, pixel, dim, n, offset=0):
    out = wp.empty(n, dtype=wp.vec2, device=DEVICE)
    wp.launch(_range_kernel, n, inputs=[wp.uint32(seed), pixel, offset, dim, out], device=DEVICE)
    return out.numpy()


def test_samples_equal_the_reference_bit_for_bit():
    rng = np.random.default_rng(21)
    n = 30000
    seed = rng.integers(0, 2**32, n, dtype=np.uint64)
    pixel = rng.integers(0, 2**31, n)
    index = np.where(rng.random(n) < 0.5, rng.integers(0, 2**16, n), rng.integers(0, 2**31, n))
    dim = rng.integers(0, 1000, n)
    seed[:6], pixel[:6], index[:6], dim[:6] = 0, 0, [0, 1, 2, 3, 2**31 - 2, 2**31 - 1], 0
    got2, got1 = evaluate(seed, pixel, index, dim)
    np.testing.assert_array_equal(got2, RA.affine_2d(seed, pixel, index, dim))
    np.testing.assert_array_equal(got1, RA.affine_1d(seed, pixel, index, dim))
    np.testing.assert_array_equal(got1, got2[:, 0])          # the contract: 1D at d is 2D's x at d
    assert got2.min() >= 0.0 and got2.max() < 1.0


def test_values_are_a_pure_function_of_their_arguments():
    """Determinism: the same request gives the same bits whatever the launch, its size and order."""
    rng = np.random.default_rng(22)
    n = 5000
    args = [rng.integers(0, 2**32, n, dtype=np.uint64), rng.integers(0, 2**31, n), rng.integers(0, 2**31, n),
            rng.integers(0, 200, n)]
    whole, _ = evaluate(*args)
    perm = rng.permutation(n)
    again, _ = evaluate(*(a[perm] for a in args))
    np.testing.assert_array_equal(again, whole[perm])
    np.testing.assert_array_equal(evaluate(*(a[:7] for a in args))[0], whole[:7])


def test_index_shuffle_maps_aligned_blocks_onto_aligned_blocks():
    rng = np.random.default_rng(23)
    out = wp.empty(1 << 12, dtype=wp.uint32, device=DEVICE)
    for m in (1, 3, 8, 12):
        for j in (0, 1, int(rng.integers(0, 2**(31 - m)))):
            block = np.arange(j << m, (j + 1) << m, dtype=np.uint32)
            key = int(rng.integers(0, 2**32))
            o = out[:block.size]
            wp.launch(_shuffle_kernel, block.size, inputs=[wp.uint32(key), _arr(block, wp.uint32), o], device=DEVICE)
            got = o.numpy().astype(np.uint64)
            assert np.unique(got >> np.uint64(m)).size == 1, (m, j)
            np.testing.assert_array_equal(np.sort(got & np.uint64((1 << m) - 1)), np.arange(1 << m))


@pytest.mark.parametrize("seed,pixel,dim", [(0, 0, 0), (1, 7, 2), (99, 123456, 17), (2**32 - 1, 2**31 - 1, 999)])
def test_every_aligned_power_of_two_block_is_a_net(seed, pixel, dim):
    n = 1 << 12
    for offset in (0, 1 << 20, 2**31 - n):
        pts = sequence(seed, pixel, dim, n, offset)
        for k in range(13):
            _assert_nets(pts, k, f"seed {seed} pixel {pixel} dim {dim} offset {offset}")


def test_a_large_block_is_a_net():
    _assert_nets(sequence(5, 77, 6, 1 << 17, 1 << 17), 17, "2**17 samples")


def test_1d_is_stratified_in_every_aligned_block():
    n = 1 << 12
    _, vals = evaluate(3, 42, np.arange(n), 5)
    q = (vals.astype(np.float64) * 2.0**24).astype(np.int64)
    for k in range(13):
        strata = np.sort(q.reshape(-1, 1 << k) >> (24 - k), axis=1)
        assert (strata == np.arange(1 << k)).all(), k


@pytest.mark.parametrize("k", [0, 1, 4, 9, 15, 20])
def test_pairs_of_points_have_owens_joint_distribution(k):
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
        wp.launch(_pair_kernel, n, inputs=[wp.uint32(a), wp.uint32(b), out], device=DEVICE)
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
def test_values_at_one_sample_are_uniform_across_pixels(index):
    pixels = np.arange(1 << 14)
    limit = chi2_upper(63, Z_1E6_ONE)
    for dim in (0, 5):
        pts, _ = evaluate(21, pixels, index, dim)
        expected = pixels.size / 64
        for counts in (np.bincount((pts[:, 0] * 64).astype(int), minlength=64),
                       np.bincount((pts[:, 1] * 64).astype(int), minlength=64),
                       np.bincount((pts[:, 0] * 8).astype(int) * 8 + (pts[:, 1] * 8).astype(int), minlength=64)):
            stat = float(((counts - expected) ** 2 / expected).sum())
            assert stat < limit, (dim, stat, limit)


def test_dims_pixels_and_seeds_are_decorrelated_across_pixels():
    m = 1 << 14
    pixels = np.arange(m)
    for index in (0, 5, 2**30 + 3):
        base, _ = evaluate(8, pixels, index, 0)
        others = {"dim pair 2": evaluate(8, pixels, index, 2)[0], "seed 9": evaluate(9, pixels, index, 0)[0],
                  "pixel + M": evaluate(8, pixels + m, index, 0)[0],
                  "overlapping pair 1": evaluate(8, pixels, index, 1)[0]}
        checks = {"x vs y": (base[:, 0], base[:, 1])}
        for name, o in others.items():
            checks[f"x vs {name} x"] = (base[:, 0], o[:, 0])
            checks[f"y vs {name} y"] = (base[:, 1], o[:, 1])
        for name, (u, v) in checks.items():
            assert abs(_corr(u, v)) * math.sqrt(m) < Z_1E6, (index, name)


def test_dims_pixels_and_seeds_are_decorrelated_within_a_pixel():
    """As tests/samplers/test_sobol.py's: two dimension pairs of a sample are paired by independent nested
    shuffles, so N r^2 / 2 is at most chi-square(1) (variance at most 2/N), summed over M pixels."""
    n, m = 1 << 12, 32
    pixel = np.arange(m)[:, None]
    idx = np.arange(n)[None, :]
    a = evaluate(4, pixel, idx, 0)[0].reshape(m, n, 2)
    pairs = {"dims 0 vs 2": evaluate(4, pixel, idx, 2)[0].reshape(m, n, 2),
             "seed 4 vs 5": evaluate(5, pixel, idx, 0)[0].reshape(m, n, 2),
             "pixel p vs p + M": evaluate(4, pixel + m, idx, 0)[0].reshape(m, n, 2)}
    limit = chi2_upper(m, Z_1E6_ONE)
    for name, b in pairs.items():
        for ca in (0, 1):
            for cb in (0, 1):
                stat = float((n * _corr(a[..., ca], b[..., cb]) ** 2 / 2).sum())
                assert stat < limit, (name, ca, cb, stat, limit)


@pytest.mark.parametrize("offsets", [(3,), (1, 4, 5), (0, 1, 3, 4, 5, 7)])
def test_a_batch_equals_its_requests_one_by_one(offsets):
    batch = A.make_batch(offsets)
    lanes = 1 << (max(len(offsets), 2) - 1).bit_length()

    @wp.kernel(module="unique")
    def run(seeds: wp.array(dtype=wp.uint32), pixels: wp.array(dtype=int), indices: wp.array(dtype=int),
            bases: wp.array(dtype=int), out: wp.array2d(dtype=float)):
        t = wp.tid()
        st = S.sampler_state(seeds[t], pixels[t], indices[t], S.pixel_key(seeds[t], pixels[t]))
        v = batch(st, bases[t])
        for j in range(wp.static(2 * lanes)):
            out[t, j] = v[j]

    rng = np.random.default_rng(24)
    n = 4000
    seed = rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32)
    pixel = rng.integers(0, 2**31, n).astype(np.int32)
    index = rng.integers(0, 2**31, n).astype(np.int32)
    base = rng.integers(0, 1000, n).astype(np.int32)
    out = wp.empty((n, 2 * lanes), dtype=float, device=DEVICE)
    wp.launch(run, n, inputs=[_arr(seed, wp.uint32), _arr(pixel, int), _arr(index, int), _arr(base, int), out],
              device=DEVICE)
    got = out.numpy().reshape(n, 2, lanes)
    padded = tuple(offsets) + (offsets[-1],) * (lanes - len(offsets))
    for k, off in enumerate(padded):
        want = RA.affine_2d(seed.astype(np.uint64), pixel.astype(np.int64), index.astype(np.int64), base + off)
        np.testing.assert_array_equal(got[:, :, k], want, err_msg=f"offset {off}")


def test_the_registry_record():
    s = get_sampler("sobol-affine")
    assert s.name == "sobol-affine" and s.random_access and s.make_batch is not None


# --- the error against sobol's at equal samples ---------------------------------------------------

@wp.func
def _integrand(kind: int, u: wp.vec4) -> float:
    if kind == 0:                                   # smooth: e^x sin(pi y), integral 2 (e - 1) / pi
        return wp.exp(u[0]) * wp.sin(3.14159265358979 * u[1])
    if kind == 1:                                   # a disk's indicator, radius 0.4: 0.16 pi
        dx = u[0] - 0.5
        dy = u[1] - 0.5
        return wp.where(dx * dx + dy * dy < 0.16, 1.0, 0.0)
    # two dimension pairs: prod (pi/2) sin(pi u_k), integral 1
    f = float(1.0)
    for k in range(4):
        f = f * (1.5707963267948966 * wp.sin(3.14159265358979 * u[k]))
    return f


EXACT = [2.0 * (math.e - 1.0) / math.pi, 0.16 * math.pi, 1.0]


def _make_estimator(draw):
    @wp.kernel(module="unique")
    def estimate(kind: int, n: int, out: wp.array(dtype=wp.float64)):
        p = wp.tid()
        acc = wp.float64(0.0)
        for j in range(n):
            a = draw(wp.uint32(5), p, j, 0)
            b = draw(wp.uint32(5), p, j, 2)
            acc += wp.float64(_integrand(kind, wp.vec4(a[0], a[1], b[0], b[1])))
        out[p] = acc / wp.float64(n)
    return estimate


def _squared_errors(draw, kind: int, n: int, pixels: int) -> np.ndarray:
    out = wp.empty(pixels, dtype=wp.float64, device=DEVICE)
    wp.launch(_make_estimator(draw), pixels, inputs=[kind, n, out], device=DEVICE)
    return (out.numpy() - EXACT[kind]) ** 2


@pytest.mark.parametrize("kind", [0, 1, 2])
def test_error_equals_sobols_at_equal_samples(kind):
    """Both scrambles give each pair of points Owen's joint law, so their estimators have the same
    variance. Each pixel is an independent estimate from N samples; the MSE over P pixels has a
    standard error from the spread of the squared errors, and the log of the two MSEs' ratio must lie
    within Z_1E6 of its standard error (delta method) of 0. Checked at two sample counts; and both
    must beat independent sampling's error by the margin the nets give (smooth integrand: RMSE
    slope -1.5, so 16x below the 1/sqrt(N) bound of plain Monte Carlo at N = 256, asked only 4x)."""
    pixels = 4096
    for n in (16, 256):
        e_aff = _squared_errors(A.affine_2d, kind, n, pixels)
        e_sob = _squared_errors(S.sobol_2d, kind, n, pixels)
        mse_a, mse_s = e_aff.mean(), e_sob.mean()
        rel_se = math.sqrt((e_aff.var() / mse_a**2 + e_sob.var() / mse_s**2) / pixels)
        assert abs(math.log(mse_a / mse_s)) < Z_1E6 * rel_se, (kind, n, mse_a, mse_s, rel_se)
    if kind == 0:
        plain_var = (math.e**2 - 1) / 4 - EXACT[0] ** 2      # E[f^2] - I^2 for one uniform point
        assert math.sqrt(mse_a) < 0.25 * math.sqrt(plain_var / 256)
