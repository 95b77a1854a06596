"""The GGX lobes of warp_spt.bsdfs.microfacet, checked against things the code does not compute.

* sampling against the pdf: a chi-square test over a sphere grid (as Mitsuba's and pbrt's test
  suites do): sampled directions are binned; each bin's expected count is the pdf integrated over
  it by a fine midpoint quadrature (a grid whose pole sits on the lobe's peak, with bins crowded
  there); bins expecting fewer than 5 are pooled; a bin for "no sample" expects N (1 - integral).
  p must exceed 0.01 / (number of tests) (Bonferroni), and a wrong pdf must be rejected;
* the pdf's integral equals the fraction of successful samples (binomial tolerance);
* a sample's value and pdf equal ``eval`` and ``pdf`` at its direction;
* reciprocity, and transmission's generalised reciprocity f(wi, wo) = eta^2 f(wo, wi);
* energy: the directional albedo (flux for transmission) never exceeds 1 beyond 4 standard errors;
* white furnace: f0 = 1 conductor with compensation within 1% of 1; without, it equals the F = 1
  albedo integrated here directly over wi (not over microfacet normals, as the table script does);
* the tables against that direct integral; Fresnel against the angle form of Fresnel's equations;
* the smooth limits against the mirror law, Snell's law and Fresnel.

All random numbers come from fixed-seed numpy generators, so the outcome is deterministic; the
tolerances are what those sample counts warrant.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import warp as wp

from warp_spt.bsdfs import microfacet as mf

wp.config.log_level = wp.LOG_WARNING
DEVICE = "cpu"

CONDUCTOR, DIELECTRIC, THIN = 0, 1, 2
ROUGHNESSES = (0.1, 0.3, 0.6, 1.0)
ANISOTROPIES = (0.0, 0.8)
COS_OUT = (0.9, 0.5, 0.15)
PHI_OUT = 0.6            # an azimuth off the tangent, so anisotropy is not aligned with wo
N_SAMPLES = 100_000
THETA_BINS, PHI_BINS = 16, 32
# Quadrature points per bin and axis; lobes with an alpha below 0.05 are narrow enough to need
# more (a 0.01 x 0.64 anisotropic transmission lobe at grazing fails the test at 20, passes at 40).
SUPER, SUPER_NARROW = 20, 40


# ---------------------------------------------------------------- kernels (one module, one compile)


@wp.func
def _sample(kind: int, wo: wp.vec3, p: wp.vec4, u: wp.vec3) -> mf.LobeSample:
    """p = (f0 or eta, alpha_x, alpha_y, compensate)."""
    if kind == 0:
        return mf.conductor_sample(wo, wp.vec3(p[0]), p[1], p[2], int(p[3]), wp.vec2(u[1], u[2]))
    if kind == 1:
        return mf.dielectric_sample(wo, p[0], p[1], p[2], u[0], wp.vec2(u[1], u[2]))
    return mf.thin_dielectric_sample(wo, p[0], p[1], p[2], u[0], wp.vec2(u[1], u[2]))


@wp.func
def _eval(kind: int, wo: wp.vec3, wi: wp.vec3, p: wp.vec4) -> float:
    if kind == 0:
        return mf.conductor_eval(wo, wi, wp.vec3(p[0]), p[1], p[2], int(p[3]))[0]
    if kind == 1:
        return mf.dielectric_eval(wo, wi, p[0], p[1], p[2])[0]
    return mf.thin_dielectric_eval(wo, wi, p[0], p[1], p[2])[0]


@wp.func
def _pdf(kind: int, wo: wp.vec3, wi: wp.vec3, p: wp.vec4) -> float:
    if kind == 0:
        return mf.conductor_pdf(wo, wi, p[1], p[2])
    if kind == 1:
        return mf.dielectric_pdf(wo, wi, p[0], p[1], p[2])
    return mf.thin_dielectric_pdf(wo, wi, p[0], p[1], p[2])


@wp.kernel
def _sample_kernel(kind: int, wo: wp.vec3, p: wp.vec4, u: wp.array(dtype=wp.vec3),
                   wi: wp.array(dtype=wp.vec3), value: wp.array(dtype=float),
                   pdf: wp.array(dtype=float), flags: wp.array(dtype=int), ok: wp.array(dtype=int),
                   ev: wp.array(dtype=float), pv: wp.array(dtype=float)):
    k = wp.tid()
    s = _sample(kind, wo, p, u[k])
    wi[k] = s.wi
    value[k] = s.value[0]
    pdf[k] = s.pdf
    flags[k] = s.flags
    ok[k] = s.ok
    ev[k] = _eval(kind, wo, s.wi, p)
    pv[k] = _pdf(kind, wo, s.wi, p)


@wp.kernel
def _pair_kernel(kind: int, p: wp.vec4, wo: wp.array(dtype=wp.vec3), wi: wp.array(dtype=wp.vec3),
                 ev: wp.array(dtype=float), pv: wp.array(dtype=float)):
    k = wp.tid()
    ev[k] = _eval(kind, wo[k], wi[k], p)
    pv[k] = _pdf(kind, wo[k], wi[k], p)


@wp.kernel
def _distribution_kernel(wo: wp.vec3, ax: float, ay: float, m: wp.array(dtype=wp.vec3),
                         d: wp.array(dtype=float), pvn: wp.array(dtype=float)):
    k = wp.tid()
    d[k] = mf.ggx_d(m[k], ax, ay)
    pvn[k] = mf.ggx_pdf_vn(wo, m[k], ax, ay)


@wp.kernel
def _table_kernel(mu: wp.array(dtype=float), alpha: wp.array(dtype=float),
                  f0: wp.array(dtype=wp.vec3), e: wp.array(dtype=float),
                  e_avg: wp.array(dtype=float), spec: wp.array(dtype=wp.vec3),
                  spec_avg: wp.array(dtype=wp.vec3)):
    k = wp.tid()
    e[k] = mf.ggx_albedo(mu[k], alpha[k])
    e_avg[k] = mf.ggx_albedo_avg(alpha[k])
    spec[k] = mf.specular_albedo(mu[k], alpha[k], f0[k])
    spec_avg[k] = mf.specular_albedo_avg(alpha[k], f0[k])


@wp.kernel
def _fresnel_kernel(c: wp.array(dtype=float), eta: wp.array(dtype=float), out: wp.array(dtype=float)):
    k = wp.tid()
    out[k] = mf.fresnel_dielectric(c[k], eta[k])


@wp.kernel
def _alphas_kernel(r: wp.array(dtype=float), s: wp.array(dtype=float), out: wp.array(dtype=wp.vec2)):
    k = wp.tid()
    out[k] = mf.ggx_alphas(r[k], s[k])


def _arr(x, dtype):
    return wp.array(np.ascontiguousarray(x, dtype=np.float32 if dtype is not int else np.int32),
                    dtype=dtype, device=DEVICE)


def sample(kind: int, wo: np.ndarray, params: tuple, n: int = N_SAMPLES, seed: int = 1) -> dict:
    u = np.random.default_rng(seed).random((n, 3))
    outs = dict(wi=wp.empty(n, dtype=wp.vec3, device=DEVICE),
                **{k: wp.empty(n, dtype=float, device=DEVICE) for k in ("value", "pdf", "ev", "pv")},
                **{k: wp.empty(n, dtype=int, device=DEVICE) for k in ("flags", "ok")})
    wp.launch(_sample_kernel, n, inputs=[kind, wp.vec3(*wo), wp.vec4(*params), _arr(u, wp.vec3),
                                         outs["wi"], outs["value"], outs["pdf"], outs["flags"],
                                         outs["ok"], outs["ev"], outs["pv"]], device=DEVICE)
    return {k: v.numpy().astype(np.float64) if k not in ("flags", "ok") else v.numpy()
            for k, v in outs.items()}


def pairs(kind: int, params: tuple, wo: np.ndarray, wi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = len(wo)
    ev = wp.empty(n, dtype=float, device=DEVICE)
    pv = wp.empty(n, dtype=float, device=DEVICE)
    wp.launch(_pair_kernel, n, inputs=[kind, wp.vec4(*params), _arr(wo, wp.vec3), _arr(wi, wp.vec3),
                                       ev, pv], device=DEVICE)
    return ev.numpy().astype(np.float64), pv.numpy().astype(np.float64)


# ---------------------------------------------------------------- independent references (numpy)


def alphas(roughness: float, anisotropy: float) -> tuple[float, float]:
    """KHR_materials_anisotropy: alpha = r^2, alpha_t = mix(alpha, 1, s^2), alpha_b = alpha."""
    a = roughness * roughness
    return a + (1 - a) * anisotropy ** 2, a


def direction(cos_theta: float, phi: float = PHI_OUT) -> np.ndarray:
    s = math.sqrt(max(0.0, 1 - cos_theta * cos_theta))
    return np.array([s * math.cos(phi), s * math.sin(phi), cos_theta])


def snell(wo: np.ndarray, eta: float) -> np.ndarray | None:
    """Refraction through the plane z = 0 by Snell's law n1 sin t1 = n2 sin t2 (wo.z > 0, index
    1 above, eta below); None under total internal reflection."""
    sin_o = math.hypot(wo[0], wo[1])
    sin_t = sin_o / eta
    if sin_t >= 1:
        return None
    phi = math.atan2(wo[1], wo[0]) + math.pi
    return np.array([sin_t * math.cos(phi), sin_t * math.sin(phi), -math.sqrt(1 - sin_t ** 2)])


def fresnel_angles(cos_i: float, eta: float) -> float:
    """Fresnel's equations in their angle form: r_s = -sin(ti - tt) / sin(ti + tt),
    r_p = tan(ti - tt) / tan(ti + tt)."""
    if cos_i < 0:
        cos_i, eta = -cos_i, 1 / eta
    ti = math.acos(min(1.0, cos_i))
    s = math.sin(ti) / eta
    if s >= 1:
        return 1.0
    tt = math.asin(s)
    if ti < 1e-7:
        return ((eta - 1) / (eta + 1)) ** 2
    rs = math.sin(ti - tt) / math.sin(ti + tt)
    rp = math.tan(ti - tt) / math.tan(ti + tt)
    return 0.5 * (rs * rs + rp * rp)


def ggx_albedo_direct(mu: float, alpha: float, n: int = 400) -> float:
    """The F = 1 albedo of the GGX reflection lobe, D G2 / (4 mu) integrated over wi in
    (theta, phi) by the midpoint rule, with D and Smith's G2 written out here."""
    th = (np.arange(n) + 0.5) / n * (np.pi / 2)
    ph = (np.arange(2 * n) + 0.5) / (2 * n) * (2 * np.pi)
    t, p = np.meshgrid(th, ph, indexing="ij")
    wi = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)
    wo = np.array([math.sqrt(1 - mu * mu), 0.0, mu])
    h = wi + wo
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    d = 1 / (np.pi * alpha ** 2 * ((h[..., 0] ** 2 + h[..., 1] ** 2) / alpha ** 2 + h[..., 2] ** 2) ** 2)

    def lam(w):
        return 0.5 * (np.sqrt(1 + alpha ** 2 * (w[..., 0] ** 2 + w[..., 1] ** 2) / w[..., 2] ** 2) - 1)

    g2 = 1 / (1 + lam(wo) + lam(wi))
    area = (np.pi / 2 / n) * (np.pi / n) * np.sin(t)
    return float(np.sum(d * g2 / (4 * mu) * area))


def chi2_sf(x: float, dof: int) -> float:
    """P(chi2_dof > x): the regularised upper incomplete gamma Q(dof/2, x/2), by its power series
    below a + 1 and by its continued fraction above (Lentz's method)."""
    a, z = 0.5 * dof, 0.5 * x
    if z <= 0:
        return 1.0
    log_pref = -z + a * math.log(z) - math.lgamma(a)
    if z < a + 1:
        term = total = 1.0 / a
        k = a
        while abs(term) > 1e-16 * abs(total):
            k += 1
            term *= z / k
            total += term
        return max(0.0, 1.0 - total * math.exp(log_pref))
    tiny = 1e-300
    b = z + 1 - a
    c, d = 1 / tiny, 1 / b
    h = d
    for i in range(1, 100_000):
        an = -i * (i - a)
        b += 2
        d = an * d + b
        d = tiny if abs(d) < tiny else d
        c = b + an / c
        c = tiny if abs(c) < tiny else c
        d = 1 / d
        h *= d * c
        if abs(d * c - 1) < 1e-15:
            break
    return math.exp(log_pref) * h


def test_chi2_sf_matches_the_tables():
    """Critical values from a standard table (5% and 1% points)."""
    for x, dof, p in ((3.841, 1, 0.05), (18.307, 10, 0.05), (6.635, 1, 0.01), (124.342, 100, 0.05),
                      (37.566, 20, 0.01)):
        assert chi2_sf(x, dof) == pytest.approx(p, rel=2e-3)


# ---------------------------------------------------------------- the chi-square machinery


class PoleGrid:
    """Bins over the sphere in (t, phi') about a pole: theta' = pi t^2 (bins crowd towards the pole,
    where a lobe peaks), THETA_BINS x PHI_BINS, and a midpoint quadrature sup x sup per bin."""

    def __init__(self, pole: np.ndarray, sup: int = SUPER):
        self.n = pole / np.linalg.norm(pole)
        helper = np.array([1.0, 0.0, 0.0]) if abs(self.n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        self.t = np.cross(helper, self.n)
        self.t /= np.linalg.norm(self.t)
        self.b = np.cross(self.n, self.t)
        nt, np_ = THETA_BINS * sup, PHI_BINS * sup
        tt = (np.arange(nt) + 0.5) / nt
        pp = (np.arange(np_) + 0.5) / np_ * 2 * np.pi
        t, p = np.meshgrid(tt, pp, indexing="ij")
        theta = np.pi * t * t
        # d omega = sin(theta) dtheta dphi, dtheta = 2 pi t dt
        self.weight = (np.sin(theta) * 2 * np.pi * t * (1 / nt) * (2 * np.pi / np_)).ravel()
        self.dirs = self._to_world(theta.ravel(), p.ravel())
        ti, pi_ = np.meshgrid(np.arange(nt) // sup, np.arange(np_) // sup, indexing="ij")
        self.bin = (ti * PHI_BINS + pi_).ravel()

    def _to_world(self, theta, phi):
        s = np.sin(theta)
        return (np.outer(s * np.cos(phi), self.t) + np.outer(s * np.sin(phi), self.b)
                + np.outer(np.cos(theta), self.n))

    def bin_of(self, w: np.ndarray) -> np.ndarray:
        theta = np.arccos(np.clip(w @ self.n, -1, 1))
        phi = np.mod(np.arctan2(w @ self.b, w @ self.t), 2 * np.pi)
        ti = np.minimum((np.sqrt(theta / np.pi) * THETA_BINS).astype(int), THETA_BINS - 1)
        pi_ = np.minimum((phi / (2 * np.pi) * PHI_BINS).astype(int), PHI_BINS - 1)
        return ti * PHI_BINS + pi_


def histograms(kind: int, wo: np.ndarray, params: tuple, poles: tuple, pdf_params: tuple | None = None):
    """(observed, expected probability, samples): bins of the upper hemisphere about poles[0], of
    the lower about poles[1] (the lobe's two peaks), then one bin for 'no sample'."""
    s = sample(kind, wo, params)
    nb = THETA_BINS * PHI_BINS
    expected = np.zeros(2 * nb + 1)
    observed = np.zeros(2 * nb + 1)
    ok = s["ok"] == 1
    for side, pole in enumerate(poles):
        if pole is None:
            continue
        grid = PoleGrid(pole, SUPER_NARROW if min(params[1], params[2]) < 0.05 else SUPER)
        keep = grid.dirs[:, 2] > 0 if side == 0 else grid.dirs[:, 2] < 0
        wos = np.broadcast_to(wo, grid.dirs.shape)
        _, pv = pairs(kind, pdf_params or params, wos, grid.dirs)
        expected[side * nb:(side + 1) * nb] = np.bincount(grid.bin[keep], (pv * grid.weight)[keep], nb)
        mine = ok & ((s["wi"][:, 2] > 0) if side == 0 else (s["wi"][:, 2] < 0))
        observed[side * nb:(side + 1) * nb] = np.bincount(grid.bin_of(s["wi"][mine]), minlength=nb)
    observed[-1] = np.count_nonzero(~ok)
    expected[-1] = max(0.0, 1.0 - expected[:-1].sum())
    return observed, expected, s


def chi2_pvalue(observed: np.ndarray, expected_prob: np.ndarray) -> float:
    n = observed.sum()
    expected = expected_prob * n
    low = expected < 5
    obs = list(observed[~low])
    exp = list(expected[~low])
    if expected[low].sum() >= 5:
        obs.append(observed[low].sum())
        exp.append(expected[low].sum())
    elif observed[low].sum() > 10 + 10 * expected[low].sum():
        return 0.0          # samples where the pdf says there are (almost) none
    obs, exp = np.array(obs), np.array(exp)
    stat = float(np.sum((obs - exp) ** 2 / exp))
    return chi2_sf(stat, len(obs) - 1)


def mirror(wo):
    return np.array([-wo[0], -wo[1], wo[2]])


def lobe_cases():
    """(label, kind, wo, params, poles): every lobe at every roughness, anisotropy and angle."""
    cases = []
    for r in ROUGHNESSES:
        for s in ANISOTROPIES:
            ax, ay = alphas(r, s)
            for c in COS_OUT:
                wo = direction(c)
                cases.append((f"conductor r={r} s={s} cos={c}", CONDUCTOR, wo, (1.0, ax, ay, 0.0),
                              (mirror(wo), None)))
                for eta in (1.5, 1 / 1.5):
                    t = snell(wo, eta)
                    cases.append((f"dielectric eta={eta:.3f} r={r} s={s} cos={c}", DIELECTRIC, wo,
                                  (eta, ax, ay, 0.0), (mirror(wo), -wo if t is None else t)))
    for r in (0.3, 1.0):
        for s in ANISOTROPIES:
            ax, ay = alphas(r, s)
            for c in (0.9, 0.3):
                wo = direction(c)
                cases.append((f"thin r={r} s={s} cos={c}", THIN, wo, (1.5, ax, ay, 0.0),
                              (mirror(wo), -wo)))
    return cases


CASES = tuple(lobe_cases())


@pytest.fixture(scope="module")
def lobe_runs():
    """Every case's histograms, computed once for the tests that read them."""
    return [(label, kind, wo, params) + histograms(kind, wo, params, poles)
            for label, kind, wo, params, poles in CASES]


def test_sampled_directions_follow_the_pdf(lobe_runs):
    threshold = 0.01 / len(lobe_runs)
    worst = []
    for label, _kind, _wo, _params, observed, expected, _s in lobe_runs:
        p = chi2_pvalue(observed, expected)
        worst.append((p, label))
    worst.sort()
    failed = [f"{label}: p = {p:.2e}" for p, label in worst if p < threshold]
    assert not failed, f"threshold {threshold:.1e}:\n" + "\n".join(failed)


def test_the_chi_square_test_rejects_a_wrong_pdf():
    """The same machinery, with the samples of roughness 0.6 against the pdf of roughness 0.63
    (a 10% change of alpha), and of an anisotropic lobe against its 90-degree turn."""
    wo = direction(0.5)
    ax, ay = alphas(0.6, 0.0)
    bx, by = alphas(0.63, 0.0)
    obs, exp, _ = histograms(CONDUCTOR, wo, (1.0, ax, ay, 0.0), (mirror(wo), None),
                             pdf_params=(1.0, bx, by, 0.0))
    assert chi2_pvalue(obs, exp) < 1e-6
    ax, ay = alphas(0.3, 0.8)
    obs, exp, _ = histograms(DIELECTRIC, wo, (1.5, ax, ay, 0.0), (mirror(wo), snell(wo, 1.5)),
                             pdf_params=(1.5, ay, ax, 0.0))
    assert chi2_pvalue(obs, exp) < 1e-6


def test_pdf_integrates_to_the_probability_of_a_sample(lobe_runs):
    """Over the sphere, the pdf integrates to the fraction of draws that give a direction (all
    but those reflected below the horizon or refracted back up), within 4 binomial standard
    errors plus the quadrature's error (0.002)."""
    bad = []
    for label, _kind, _wo, _params, observed, expected, _s in lobe_runs:
        n = observed.sum()
        frac = 1 - observed[-1] / n
        total = expected[:-1].sum()
        tol = 4 * math.sqrt(max(frac * (1 - frac), 1 / n) / n) + 2e-3
        if abs(total - frac) > tol:
            bad.append(f"{label}: integral {total:.4f}, sampled {frac:.4f}")
        if total > 1 + 2e-3:
            bad.append(f"{label}: integral {total:.4f} > 1")
    assert not bad, "\n".join(bad)


def test_sample_value_and_pdf_equal_eval_and_pdf(lobe_runs):
    bad = []
    for label, _kind, _wo, _params, _obs, _exp, s in lobe_runs:
        ok = s["ok"] == 1
        for got, want, name in ((s["value"][ok], s["ev"][ok], "value"), (s["pdf"][ok], s["pv"][ok], "pdf")):
            rel = np.abs(got - want) / np.maximum(np.abs(want), 1e-12)
            if np.quantile(rel, 0.999) > 1e-4 or rel.max() > 1e-2:
                bad.append(f"{label}: {name} vs eval: 99.9% {np.quantile(rel, 0.999):.1e}, max {rel.max():.1e}")
    assert not bad, "\n".join(bad)


def test_directional_albedo_never_exceeds_one(lobe_runs):
    """Mean throughput weight over all draws (failed ones weigh 0), f0 = 1 for the conductor;
    transmission's radiance weight times eta'^2 is its flux (radiance is compressed into the
    denser medium: the 1/eta'^2 factor)."""
    bad = []
    for label, kind, wo, params, _obs, _exp, s in lobe_runs:
        ok = s["ok"] == 1
        w = np.where(ok, s["value"] / np.where(ok, s["pdf"], 1.0), 0.0)
        if kind == DIELECTRIC:
            w = np.where(s["wi"][:, 2] < 0, w * params[0] ** 2, w)
        mean = w.mean()
        se = w.std() / math.sqrt(len(w))
        if mean > 1 + 4 * se + 1e-6:
            bad.append(f"{label}: albedo {mean:.5f} +- {se:.5f}")
    assert not bad, "\n".join(bad)


# ---------------------------------------------------------------- the distribution alone


@pytest.mark.parametrize("r,s,cos", [(0.3, 0.0, 0.7), (0.6, 0.8, 0.3), (1.0, 0.0, 0.95), (0.45, 0.5, 0.1)])
def test_ggx_d_projects_to_one_and_visible_normals_to_one(r, s, cos):
    """Integral of D(m) m.z = 1 (the microsurface projects onto the macrosurface) and of the
    visible-normal density = 1, by quadrature over m with bins crowded at the pole z."""
    ax, ay = alphas(r, s)
    grid = PoleGrid(np.array([0.0, 0.0, 1.0]))
    wo = direction(cos)
    d = wp.empty(len(grid.dirs), dtype=float, device=DEVICE)
    pvn = wp.empty(len(grid.dirs), dtype=float, device=DEVICE)
    wp.launch(_distribution_kernel, len(grid.dirs),
              inputs=[wp.vec3(*wo), ax, ay, _arr(grid.dirs, wp.vec3), d, pvn], device=DEVICE)
    assert np.sum(d.numpy() * grid.dirs[:, 2] * grid.weight) == pytest.approx(1.0, abs=2e-3)
    assert np.sum(pvn.numpy() * grid.weight) == pytest.approx(1.0, abs=2e-3)


# ---------------------------------------------------------------- reciprocity


def assert_close_float32(a: np.ndarray, b: np.ndarray, rtol: float = 2e-4) -> None:
    rel = np.abs(a - b) / np.maximum(np.maximum(np.abs(a), np.abs(b)), 1e-12)
    assert rel.max() < rtol, (np.argmax(rel), rel.max())


def _random_dirs(rng, n, lower=False):
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v[:, 2] = np.abs(v[:, 2]) * (-1 if lower else 1)
    return v[np.abs(v[:, 2]) > 0.05]


@pytest.mark.parametrize("kind,name", [(CONDUCTOR, "conductor"), (DIELECTRIC, "dielectric"), (THIN, "thin")])
@pytest.mark.parametrize("r,s", [(0.3, 0.0), (0.7, 0.8)])
def test_reflection_is_reciprocal(kind, name, r, s):
    """f(wo, wi) / |cos wi| = f(wi, wo) / |cos wo| (conductor without compensation: Turquin's
    factor depends on wo alone, so the compensated lobe is reciprocal only to within it)."""
    rng = np.random.default_rng(7)
    wo = _random_dirs(rng, 4000)
    wi = _random_dirs(rng, 4000)[: len(wo)]
    wo = wo[: len(wi)]
    ax, ay = alphas(r, s)
    params = (0.6 if kind == CONDUCTOR else 1.5, ax, ay, 0.0)
    f_oi, _ = pairs(kind, params, wo, wi)
    f_io, _ = pairs(kind, params, wi, wo)
    a, b = f_oi / wi[:, 2], f_io / wo[:, 2]
    assert np.count_nonzero(a > 0) > len(a) // 2
    assert_close_float32(a, b)


@pytest.mark.parametrize("eta", [1.5, 1 / 1.33])
@pytest.mark.parametrize("r,s", [(0.3, 0.0), (0.7, 0.8)])
def test_transmission_obeys_generalised_reciprocity(eta, r, s):
    """With index 1 above and eta below, radiance transport gives f(wi, wo) = eta^2 f(wo, wi)
    for wo above and wi below (Veach 1997, 5.2: f / n^2 of the outgoing side is symmetric)."""
    rng = np.random.default_rng(11)
    wo = _random_dirs(rng, 4000)
    wi = _random_dirs(rng, 4000, lower=True)
    n = min(len(wo), len(wi))
    wo, wi = wo[:n], wi[:n]
    # Leave out pairs whose microfacet (the generalised half vector) one of them grazes within
    # 1 degree: seen from the other it sits at the critical angle, where float32 Fresnel's
    # sqrt(1 - sin^2) cancels (such pairs' f is tiny: below 1e-4 of the typical).
    m = wi * eta + wo
    m /= np.linalg.norm(m, axis=1, keepdims=True)
    keep = np.minimum(np.abs(np.sum(wo * m, axis=1)), np.abs(np.sum(wi * m, axis=1))) > 0.02
    wo, wi, n = wo[keep], wi[keep], np.count_nonzero(keep)
    ax, ay = alphas(r, s)
    f_oi, _ = pairs(DIELECTRIC, (eta, ax, ay, 0.0), wo, wi)
    f_io, _ = pairs(DIELECTRIC, (eta, ax, ay, 0.0), wi, wo)
    a, b = eta * eta * f_oi / np.abs(wi[:, 2]), f_io / np.abs(wo[:, 2])
    assert np.count_nonzero(a > 0) > n // 10        # pairs with a valid generalised half vector
    assert_close_float32(a, b, rtol=1e-3)
    # and a thin sheet passes light both ways alike
    t_oi, _ = pairs(THIN, (eta, ax, ay, 0.0), wo, wi)
    t_io, _ = pairs(THIN, (eta, ax, ay, 0.0), wi, wo)
    assert_close_float32(t_oi / np.abs(wi[:, 2]), t_io / np.abs(wo[:, 2]), rtol=1e-3)


def test_wo_below_mirrors_the_frame():
    """The documented convention for wo.z < 0: the conductor is two-sided, a dielectric (and its
    sampler) sees eta inverted: f(wo, wi; eta) = f(-wo, -wi; 1/eta)."""
    rng = np.random.default_rng(13)
    wo = _random_dirs(rng, 2000)
    wi = np.concatenate([_random_dirs(rng, 1000), _random_dirs(rng, 1000, lower=True)])
    n = min(len(wo), len(wi))
    wo, wi = wo[:n], wi[:n]
    ax, ay = alphas(0.5, 0.6)
    for kind, up, down in ((CONDUCTOR, (0.7, ax, ay, 1.0), (0.7, ax, ay, 1.0)),
                           (DIELECTRIC, (1.5, ax, ay, 0.0), (1 / 1.5, ax, ay, 0.0)),
                           (THIN, (1.5, ax, ay, 0.0), (1.5, ax, ay, 0.0))):
        f_up, p_up = pairs(kind, up, wo, wi)
        f_dn, p_dn = pairs(kind, down, -wo, -wi)
        assert np.count_nonzero(f_up) > n // 4
        np.testing.assert_allclose(f_dn, f_up, rtol=1e-5, atol=1e-7)
        np.testing.assert_allclose(p_dn, p_up, rtol=1e-5, atol=1e-7)
        s_up = sample(kind, direction(0.6), up, n=2000, seed=4)
        s_dn = sample(kind, -direction(0.6), down, n=2000, seed=4)
        np.testing.assert_array_equal(s_dn["ok"], s_up["ok"])
        ok = s_up["ok"] == 1
        np.testing.assert_allclose(s_dn["wi"][ok], -s_up["wi"][ok], atol=1e-6)
        np.testing.assert_allclose(s_dn["value"], s_up["value"], rtol=1e-5)
        np.testing.assert_allclose(s_dn["pdf"], s_up["pdf"], rtol=1e-5)


# ---------------------------------------------------------------- white furnace and tables


def albedo(kind, wo, params, n=40_000, seed=3):
    s = sample(kind, wo, params, n=n, seed=seed)
    ok = s["ok"] == 1
    w = np.where(ok, s["value"] / np.where(ok, s["pdf"], 1.0), 0.0)
    return w.mean(), w.std() / math.sqrt(n)


FURNACE_COS = (1.0, 0.8, 0.5, 0.3, 0.15, 0.05)     # down to 87 degrees


@pytest.mark.parametrize("r", [0.05, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0])
def test_white_furnace_with_compensation(r):
    """f0 = 1, compensated: the directional albedo is 1 within 1% at every angle up to 87 deg."""
    ax, ay = alphas(r, 0.0)
    for c in FURNACE_COS:
        mean, se = albedo(CONDUCTOR, direction(c), (1.0, ax, ay, 1.0))
        assert abs(mean - 1.0) < 0.01 + 4 * se, (r, c, mean, se)


@pytest.mark.parametrize("r", [0.3, 0.6, 1.0])
def test_white_furnace_without_compensation_loses_the_single_scattering_share(r):
    """Uncompensated, the albedo is the F = 1 single-scattering albedo integrated directly here;
    at roughness 1 that is well below 1 (0.31 at normal incidence)."""
    ax, ay = alphas(r, 0.0)
    for c in (1.0, 0.7, 0.4, 0.2):
        mean, se = albedo(CONDUCTOR, direction(c), (1.0, ax, ay, 0.0))
        want = ggx_albedo_direct(c, ax)
        assert abs(mean - want) < 4 * se + 2e-3, (r, c, mean, want)
        if r == 1.0:
            assert mean < 0.7


def _tables(mu, alpha, f0):
    n = len(mu)
    out = [wp.empty(n, dtype=float, device=DEVICE), wp.empty(n, dtype=float, device=DEVICE),
           wp.empty(n, dtype=wp.vec3, device=DEVICE), wp.empty(n, dtype=wp.vec3, device=DEVICE)]
    wp.launch(_table_kernel, n, inputs=[_arr(mu, float), _arr(alpha, float), _arr(f0, wp.vec3)] + out,
              device=DEVICE)
    return [o.numpy().astype(np.float64) for o in out]


def test_albedo_table_matches_a_direct_integral():
    """ggx_albedo (bilinear in the table) against the integral over wi, off the table's nodes,
    within 1% for mu >= 0.1 (the table's measured interpolation error is below 0.2% there)."""
    mus, rs = [0.93, 0.61, 0.33, 0.12], [0.27, 0.52, 0.77, 0.96]
    grid = [(m, r * r) for m in mus for r in rs]
    e, e_avg, _, _ = _tables(np.array([g[0] for g in grid]), np.array([g[1] for g in grid]),
                             np.ones((len(grid), 3)))
    want = np.array([ggx_albedo_direct(m, a) for m, a in grid])
    np.testing.assert_allclose(e, want, rtol=0.01)
    # the hemispherical average, by Gauss-Legendre over mu of the direct integral
    x, w = np.polynomial.legendre.leggauss(24)
    for r in (0.52, 0.96):
        avg = sum(0.5 * wk * 2 * (0.5 * (xk + 1)) * ggx_albedo_direct(0.5 * (xk + 1), r * r, n=200)
                  for xk, wk in zip(x, w))
        got = _tables(np.array([0.5]), np.array([r * r]), np.ones((1, 3)))[1][0]
        assert got == pytest.approx(avg, rel=5e-3)


def test_specular_albedo_is_the_compensated_lobes_albedo():
    """specular_albedo(mu, alpha, f0) against the compensated conductor's sampled albedo with that
    Schlick f0 (within 1% + 4 standard errors), and its average against Gauss-Legendre over mu
    of specular_albedo itself, per channel; with f0 = 1 the average is 1 (all energy kept)."""
    f0 = np.array([0.04, 0.5, 0.9])
    for r in (0.3, 0.8):
        ax, _ = alphas(r, 0.0)
        for c in (0.9, 0.4):
            _, _, spec, _ = _tables(np.array([c]), np.array([ax]), f0[None, :])
            for ch in range(3):
                mean, se = albedo(CONDUCTOR, direction(c), (f0[ch], ax, ax, 1.0), n=20_000)
                assert abs(spec[0][ch] - mean) < 0.01 * mean + 4 * se, (r, c, ch, spec[0][ch], mean)
        x, w = np.polynomial.legendre.leggauss(32)
        mu = 0.5 * (x + 1)
        _, _, spec, spec_avg = _tables(mu, np.full(len(mu), ax), np.repeat(f0[None, :], len(mu), 0))
        avg = (0.5 * w * 2 * mu) @ spec
        np.testing.assert_allclose(spec_avg[0], avg, rtol=5e-3)
        _, _, _, ones = _tables(np.array([0.5]), np.array([ax]), np.ones((1, 3)))
        np.testing.assert_allclose(ones[0], 1.0, atol=2e-3)


# ---------------------------------------------------------------- Fresnel and parameters


def test_fresnel_matches_the_angle_form():
    cases = [(c, eta) for c in (1.0, 0.9, 0.6, 0.3, 0.05, -0.2, -0.7, -1.0) for eta in (1.5, 1 / 1.5, 2.4, 1.0001)]
    c = np.array([x[0] for x in cases])
    eta = np.array([x[1] for x in cases])
    out = wp.empty(len(c), dtype=float, device=DEVICE)
    wp.launch(_fresnel_kernel, len(c), inputs=[_arr(c, float), _arr(eta, float), out], device=DEVICE)
    want = np.array([fresnel_angles(a, b) for a, b in cases])
    np.testing.assert_allclose(out.numpy(), want, rtol=1e-4, atol=1e-6)
    assert fresnel_angles(-0.2, 1.5) == 1.0          # the table includes total internal reflection


def test_alphas_follow_gltf():
    r = np.array([0.0, 0.5, 1.0, 0.3])
    s = np.array([0.0, 0.0, 0.5, 0.8])
    al = wp.empty(4, dtype=wp.vec2, device=DEVICE)
    wp.launch(_alphas_kernel, 4, inputs=[_arr(r, float), _arr(s, float), al], device=DEVICE)
    want = np.array([alphas(a, b) for a, b in zip(r, s)])
    np.testing.assert_allclose(al.numpy(), want, rtol=1e-6, atol=1e-7)


# ---------------------------------------------------------------- the smooth limits


def degrees_between(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle between unit vectors, from the chord (arccos loses float32's last digits near 1)."""
    return np.degrees(2 * np.arcsin(np.clip(np.linalg.norm(a - b, axis=-1) / 2, 0, 1)))


def _fresnel_schlick(f0, c):
    return f0 + (1 - f0) * (1 - c) ** 5


SPEC_REFL = int(mf.LOBE_SPECULAR) | int(mf.LOBE_REFLECTION)
SPEC_TRANS = int(mf.LOBE_SPECULAR) | int(mf.LOBE_TRANSMISSION)


@pytest.mark.parametrize("c", [0.95, 0.5, 0.2])
def test_smooth_conductor_is_the_mirror(c):
    wo = direction(c)
    s = sample(CONDUCTOR, wo, (0.3, 0.0, 0.0, 1.0), n=64)
    assert np.all(s["ok"] == 1) and np.all(s["flags"] == SPEC_REFL)
    np.testing.assert_allclose(s["wi"], np.broadcast_to(mirror(wo), s["wi"].shape), atol=1e-6)
    np.testing.assert_allclose(s["value"] / s["pdf"], _fresnel_schlick(0.3, c), rtol=1e-5)
    assert np.all(s["ev"] == 0) and np.all(s["pv"] == 0)
    # roughness 0.045 (alpha 2e-3, a rough lobe): directions concentrate on the mirror's (GGX's
    # long tail puts 1% beyond 2 degrees), the weight is the mirror's
    a = 2e-3
    s = sample(CONDUCTOR, wo, (0.3, a, a, 1.0), n=20_000)
    ok = s["ok"] == 1
    assert ok.mean() > 0.999
    assert np.all(s["flags"][ok] == int(mf.LOBE_GLOSSY) | int(mf.LOBE_REFLECTION))
    ang = degrees_between(s["wi"][ok], mirror(wo))
    assert np.quantile(ang, 0.9) < 1.0
    w = s["value"][ok] / s["pdf"][ok]
    assert w.mean() == pytest.approx(_fresnel_schlick(0.3, c), rel=5e-3)


@pytest.mark.parametrize("eta,c", [(1.5, 0.9), (1.5, 0.3), (1 / 1.5, 0.9), (1 / 1.5, 0.3)])
def test_smooth_dielectric_is_snell_and_fresnel(eta, c):
    """Roughness 0: reflection with probability F (exact Fresnel), weight 1; refraction by Snell's
    law, radiance weight 1/eta^2; total internal reflection reflects all. Roughness 0.045: 90% of
    the directions within a degree, the weights within 1% (G2/G1 is within 0.5% of 1 there)."""
    wo = direction(c)
    t = snell(wo, eta)
    f = fresnel_angles(c, eta)
    for a in (0.0, 2e-3):
        s = sample(DIELECTRIC, wo, (eta, a, a, 0.0), n=40_000, seed=5)
        ok = s["ok"] == 1
        refl = ok & (s["wi"][:, 2] > 0)
        tran = ok & (s["wi"][:, 2] < 0)
        n = len(ok)
        assert abs(refl.mean() - f) <= 4 * math.sqrt(f * (1 - f) / n) + 2e-3 * (a > 0)
        spec = a == 0
        want_r = SPEC_REFL if spec else int(mf.LOBE_GLOSSY) | int(mf.LOBE_REFLECTION)
        want_t = SPEC_TRANS if spec else int(mf.LOBE_GLOSSY) | int(mf.LOBE_TRANSMISSION)
        assert np.all(s["flags"][refl] == want_r) and np.all(s["flags"][tran] == want_t)
        wr = s["value"][refl] / s["pdf"][refl]
        assert wr.mean() == pytest.approx(1.0, rel=1e-5 if spec else 1e-2)
        ang = degrees_between(s["wi"][refl], mirror(wo))
        assert np.quantile(ang, 0.9) < (1e-3 if spec else 1.0)
        if t is None:
            assert not tran.any()
            continue
        assert ok.mean() > 0.999
        wt = s["value"][tran] / s["pdf"][tran]
        assert wt.mean() == pytest.approx(1 / eta ** 2, rel=1e-5 if spec else 1e-2)
        ang = degrees_between(s["wi"][tran], t)
        assert np.quantile(ang, 0.9) < (1e-3 if spec else 1.0)
        if spec:
            assert np.all(s["ev"] == 0) and np.all(s["pv"] == 0)


def test_index_matched_boundary_and_smooth_thin_sheet():
    """eta = 1: straight through, weight 1, even when rough. A smooth thin sheet reflects
    2R / (1 + R) (R + T^2 R / (1 - R^2) summed here as a series) and passes the rest unbent."""
    wo = direction(0.6)
    s = sample(DIELECTRIC, wo, (1.0, 0.3, 0.3, 0.0), n=256)
    assert np.all(s["flags"] == SPEC_TRANS)
    np.testing.assert_allclose(s["wi"], np.broadcast_to(-wo, s["wi"].shape), atol=1e-6)
    np.testing.assert_allclose(s["value"] / s["pdf"], 1.0, rtol=1e-6)
    r1 = fresnel_angles(0.6, 1.5)
    t1 = 1 - r1
    series = r1 + sum(t1 * t1 * r1 ** (2 * k + 1) for k in range(200))
    s = sample(THIN, wo, (1.5, 0.0, 0.0, 0.0), n=40_000, seed=9)
    refl = s["wi"][:, 2] > 0
    n = len(refl)
    assert abs(refl.mean() - series) < 4 * math.sqrt(series * (1 - series) / n)
    np.testing.assert_allclose(s["wi"][~refl], np.broadcast_to(-wo, s["wi"][~refl].shape), atol=1e-6)
    np.testing.assert_allclose(s["value"] / s["pdf"], 1.0, rtol=1e-5)


# ---------------------------------------------------------------- derivatives (for the tape)


@wp.kernel
def _grad_kernel(p: wp.array(dtype=float), wo: wp.vec3, wi: wp.vec3, wt: wp.vec3,
                 out: wp.array(dtype=float)):
    """p = (roughness, anisotropy, f0, eta): a sum of the lobes' values that depends on each."""
    al = mf.ggx_alphas(p[0], p[1])
    c = mf.conductor_eval(wo, wi, wp.vec3(p[2]), al[0], al[1], 1)[0]
    d = mf.dielectric_eval(wo, wi, p[3], al[0], al[1])[0] + mf.dielectric_eval(wo, wt, p[3], al[0], al[1])[0]
    t = mf.thin_dielectric_eval(wo, wt, p[3], al[0], al[1])[0]
    e = mf.specular_albedo(wo[2], al[0] * al[1], wp.vec3(p[2]))[0]
    out[0] = c + d + t + e


def test_derivatives_match_finite_differences():
    """Warp's adjoint of the lobes (what path replay and the tape use) against central differences
    in roughness, anisotropy, f0 and eta, at a point off the table's nodes."""
    wo, wi = direction(0.7, 0.3), direction(0.55, 2.9)
    wt = -direction(0.8, 0.2)
    p0 = np.array([0.47, 0.35, 0.62, 1.45])

    def f(p):
        out = wp.zeros(1, dtype=float, device=DEVICE)
        wp.launch(_grad_kernel, 1, inputs=[_arr(p, float), wp.vec3(*wo), wp.vec3(*wi), wp.vec3(*wt), out],
                  device=DEVICE)
        return float(out.numpy()[0])

    p = wp.array(p0.astype(np.float32), dtype=float, device=DEVICE, requires_grad=True)
    out = wp.zeros(1, dtype=float, device=DEVICE, requires_grad=True)
    tape = wp.Tape()
    with tape:
        wp.launch(_grad_kernel, 1, inputs=[p, wp.vec3(*wo), wp.vec3(*wi), wp.vec3(*wt), out], device=DEVICE)
    tape.backward(grads={out: wp.ones(1, dtype=float, device=DEVICE)})
    grad = p.grad.numpy()
    h = 2e-3
    for k in range(4):
        e = np.zeros(4)
        e[k] = h
        fd = (f(p0 + e) - f(p0 - e)) / (2 * h)
        assert grad[k] == pytest.approx(fd, rel=5e-3), (k, grad[k], fd)
