"""Cheaper forms of the path kernel's computations that must not change a bit (docs/performance.md,
"Cheaper vertices, same bits").

Each one skips work whose result no decision or value uses, or computes the same bits another way;
these tests compare it with the full computation on many inputs, concentrated where a decision flips
and on the special values (zeros, subnormals, infinities, NaN).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from warp_spt.accel.ray_queries import safe_inverse, safe_inverse_from
from warp_spt.emitters.triangle import MAX_SPHERICAL, MIN_SPHERICAL, sampled_solid_angle
from warp_spt.device.sampling import triangle_solid_angle
from warp_spt.accel.wide_traversal import mesh_ray
from warp_spt.integrators.common import FAST_KERNEL_OPTIONS, finite3


@wp.kernel(enable_backward=False)
def _both(p0: wp.array(dtype=wp.vec3), p1: wp.array(dtype=wp.vec3), p2: wp.array(dtype=wp.vec3),
          x: wp.array(dtype=wp.vec3), full: wp.array(dtype=float), quick: wp.array(dtype=float)):
    i = wp.tid()
    full[i] = triangle_solid_angle(p0[i], p1[i], p2[i], x[i])
    quick[i] = sampled_solid_angle(p0[i], p1[i], p2[i], x[i])


def _threshold_points(rng, tri: np.ndarray, n: int) -> np.ndarray:
    """Points on random rays from the triangle's centroid at which it subtends about MIN_SPHERICAL
    (bisection in float64 on the distance), jittered by a few float32 ulps either way."""
    c = tri.mean(axis=0)
    out = []
    for _ in range(n):
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        lo, hi = 1e-4, 1e4

        def omega(t):
            e = tri - (c + d * t)
            ln = np.linalg.norm(e, axis=1)
            num = np.dot(e[0], np.cross(tri[1] - tri[0], tri[2] - tri[0]))
            den = ln.prod() + e[0] @ e[1] * ln[2] + e[1] @ e[2] * ln[0] + e[2] @ e[0] * ln[1]
            return abs(2 * np.arctan2(num, den))
        if omega(lo) < MIN_SPHERICAL or omega(hi) > MIN_SPHERICAL:
            continue
        for _ in range(80):
            mid = np.sqrt(lo * hi)
            lo, hi = (mid, hi) if omega(mid) > MIN_SPHERICAL else (lo, mid)
        p = (c + d * lo).astype(np.float32)
        out.append(p)
        for toward in (np.float32(np.inf), np.float32(-np.inf)):
            q = p
            for _ in range(8):
                q = np.nextafter(q, toward)
                out.append(q)
    return np.array(out, dtype=np.float32)


def test_sampled_solid_angle_makes_the_same_choice_and_value():
    """Wherever the full solid angle would choose spherical sampling, the shortcut returns it bit for
    bit; where it returns 0 the full one is below MIN_SPHERICAL (so area sampling, as before)."""
    rng = np.random.default_rng(7)
    tris, xs = [], []
    for scale in (1e-3, 1.0, 1e3):
        for _ in range(40):
            tri = rng.normal(size=(3, 3)) * scale
            pts = _threshold_points(rng, tri, 6)
            tris.append(np.repeat(tri[None], len(pts), axis=0))
            xs.append(pts)
            # and points anywhere: near, far, in the plane
            more = (rng.normal(size=(200, 3)) * scale * rng.choice([0.05, 1, 20], size=(200, 1))).astype(np.float32)
            tris.append(np.repeat(tri[None], len(more), axis=0))
            xs.append(more)
    tri = np.concatenate(tris).astype(np.float32)
    x = np.concatenate(xs)
    n = len(x)
    args = [wp.array(tri[:, k], dtype=wp.vec3) for k in range(3)] + [wp.array(x, dtype=wp.vec3)]
    full, short = wp.zeros(n, dtype=float), wp.zeros(n, dtype=float)
    wp.launch(_both, dim=n, inputs=[*args, full, short])
    full, short = full.numpy(), short.numpy()
    chosen = (full >= np.float32(MIN_SPHERICAL)) & (full <= np.float32(MAX_SPHERICAL))
    skipped = short == 0.0
    assert chosen.sum() > 1000 and (~chosen).sum() > 1000      # both sides of the choice are exercised
    assert skipped.sum() > 1000
    assert not (chosen & skipped).any(), "the shortcut skipped a triangle that spherical sampling takes"
    assert np.array_equal(full[~skipped], short[~skipped])
    # the points bracketing the threshold decide both ways and the shortcut still agrees
    near = np.abs(full / np.float32(MIN_SPHERICAL) - 1) < 1e-3
    assert near.sum() > 100 and (near & chosen).any() and (near & ~chosen).any()



@wp.kernel(enable_backward=False)
def _inverses(d: wp.array(dtype=wp.vec3), full: wp.array(dtype=wp.vec3), reused: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    full[i] = safe_inverse(d[i])
    reused[i] = safe_inverse_from(mesh_ray(wp.vec3(0.0, 0.0, 0.0), d[i]).inv, d[i])


def test_safe_inverse_from_the_mesh_ray_is_safe_inverse():
    """The top-level box tests take 1/d from the mesh ray's (which replaces only exact zeros, by 1e-20)
    instead of dividing again (safe_inverse replaces |d| <= 1e-30 by +-1e-30): the same bits, zeros,
    signed zeros, subnormals and the components at and around 1e-30 included."""
    rng = np.random.default_rng(11)
    special = np.array([0.0, -0.0, 1e-45, -1e-45, 1e-38, 1e-31, -1e-31, 1e-30, -1e-30, 1e-29, -1e-29,
                        1.0, -1.0, 3e38, np.nan], dtype=np.float32)
    edge = np.float32(1e-30)
    around = [np.nextafter(edge, np.float32(0)), np.nextafter(edge, np.float32(1))]
    special = np.concatenate([special, around, np.negative(around)]).astype(np.float32)
    d = rng.choice(special, size=(4000, 3)).astype(np.float32)
    d[:1000] = rng.normal(size=(1000, 3)).astype(np.float32)
    full, reused = wp.zeros(len(d), dtype=wp.vec3), wp.zeros(len(d), dtype=wp.vec3)
    wp.launch(_inverses, dim=len(d), inputs=[wp.array(d, dtype=wp.vec3), full, reused])
    a, b = full.numpy(), reused.numpy()
    assert np.array_equal(a.view(np.uint32), b.view(np.uint32))
    assert (np.abs(d) <= np.float32(1e-30)).sum() > 1000      # the replaced components are exercised


@wp.kernel(enable_backward=False, module="unique", module_options=FAST_KERNEL_OPTIONS)
def _finite(v: wp.array(dtype=wp.vec3), warp_says: wp.array(dtype=int), ours: wp.array(dtype=int)):
    i = wp.tid()
    warp_says[i] = wp.where(wp.isfinite(v[i]), 1, 0)
    ours[i] = wp.where(finite3(v[i]), 1, 0)


def test_finite3_is_isfinite():
    """The inline test of the path kernel's guards agrees with wp.isfinite on every special value, in a
    kernel compiled with the path kernel's flags (a fast-math flag would fold it to True)."""
    f32 = np.finfo(np.float32)
    special = np.array([0.0, -0.0, 1.0, -2.5, f32.max, -f32.max, f32.tiny, 1e-45, -1e-45, np.inf, -np.inf, np.nan,
                        np.nextafter(f32.max, np.float32(0))], dtype=np.float32)
    rng = np.random.default_rng(5)
    v = rng.choice(special, size=(3000, 3)).astype(np.float32)
    a, b = wp.zeros(len(v), dtype=int), wp.zeros(len(v), dtype=int)
    wp.launch(_finite, dim=len(v), inputs=[wp.array(v, dtype=wp.vec3), a, b])
    expected = np.isfinite(v).all(axis=1).astype(int)
    assert np.array_equal(a.numpy(), expected)
    assert np.array_equal(b.numpy(), expected)
    assert 0 < expected.sum() < len(v)
