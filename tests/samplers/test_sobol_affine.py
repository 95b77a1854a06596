"""``sobol-affine``'s error against ``sobol``'s on integrands with known values: the claim its scramble is
made for (the same variance, from Owen's pair law). Its points' own properties (the numpy reference
tests/support/sobol_affine_reference.py, nets, Owen's pair law, statistics, batches) are tests/samplers/
test_sobol.py's, parametrised over both scrambles.

Each test has a false-failure probability of at most 1e-6 under the hypothesis being tested (the module
is correct). Seeds are fixed, so a pass is reproducible; the bounds say how surprising a failure would be.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp

from warp_spt.samplers import sobol as S
from warp_spt.samplers import sobol_affine as A

from tests.samplers.test_sobol import Z_1E6

wp.config.log_level = wp.LOG_WARNING
DEVICE = "cpu"


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
        e_aff = _squared_errors(A.POINTS.two, kind, n, pixels)
        e_sob = _squared_errors(S.POINTS.two, kind, n, pixels)
        mse_a, mse_s = e_aff.mean(), e_sob.mean()
        rel_se = math.sqrt((e_aff.var() / mse_a**2 + e_sob.var() / mse_s**2) / pixels)
        assert abs(math.log(mse_a / mse_s)) < Z_1E6 * rel_se, (kind, n, mse_a, mse_s, rel_se)
    if kind == 0:
        plain_var = (math.e**2 - 1) / 4 - EXACT[0] ** 2      # E[f^2] - I^2 for one uniform point
        assert math.sqrt(mse_a) < 0.25 * math.sqrt(plain_var / 256)
