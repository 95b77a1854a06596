"""Write ``warp_spt/bsdfs/ggx_tables.py``: the directional albedo of the GGX reflection lobe, split sum.

For an isotropic GGX lobe (height-correlated Smith G2) with Schlick's Fresnel
``F = f0 + (1 - f0) (1 - c)^5`` (``c = wo . m``), the directional albedo is linear in ``f0``::

    E_F(mu, alpha) = f0 * A(mu, alpha) + B(mu, alpha)
    A = integral of D G2 (1 - (1 - c)^5) / (4 mu) over the hemisphere of wi
    B = integral of D G2 (1 - c)^5 / (4 mu)
    E = A + B            the F = 1 albedo (Turquin 2019's E_ss)

**Grid.** 32 x 32 nodes, row ``i`` at ``mu = (i / 31)^2`` (``mu`` the cosine of the outgoing
direction: the square crowds nodes towards grazing, where E changes fastest), column ``j`` at
roughness ``r = j / 31``, i.e. ``alpha = r^2``. Lookups are bilinear in (sqrt(mu), sqrt(alpha)).
Row 0 (mu = 0) holds the limit, evaluated at mu = 1e-6.

**Averages** per column (cosine-weighted over the hemisphere, 2 * integral of g(mu) mu dmu, by
48-point Gauss-Legendre in mu on fresh integrals, not on the table): ``E_AVG`` (of E), ``A_AVG``,
``B_AVG``, and the two moments the compensated albedo's average needs,
``C_AVG`` = avg of A (1 - E) / E and ``D_AVG`` = avg of B (1 - E) / E, so that the average of
``(f0 A + B)(1 + f0 (1 - E) / E)`` is ``f0 (A_AVG + D_AVG) + B_AVG + f0^2 C_AVG`` exactly.

**Method.** Each integral is taken over the visible-normal sample space, u in [0, 1]^2 mapped to a
microfacet normal by the spherical-cap method (Dupuy & Benyoub 2023), where the integrand is
``G2 / G1(wo) * F(c) * [wi.z > 0]`` (bounded, and smooth except at the horizon). Stratified
jittered sampling, 4 independent replicates of 256 x 256 strata with a fixed seed (1,048,576
samples per node); the standard error is estimated from the replicates' spread and printed.

**Measured error** (``python scripts/make_ggx_tables.py --check``):

* integration: largest estimated standard error of a node's E, 7.9e-05;
* interpolation: the bilinear look-up against fresh integrals at the centres of all 31 x 31 cells
  (the worst place for a bilinear look-up), largest relative error of E: 0.15% where
  theta_o < 84.3 deg (mu >= 0.1), 0.78% where theta_o < 89 deg, 9.1% over all cells (the most
  grazing row, theta_o > 89.9 deg, at the smallest roughnesses, where E changes steeply).

Deterministic (numpy only, fixed seed): the same file on every run; about a minute of CPU time
(two with ``--check``).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

N = 32                  # nodes per axis
STRATA = 256            # strata per axis of u, per replicate
REPLICATES = 4
SEED = 20260529
MU_MIN = 1e-6           # where the grazing row (mu = 0) is evaluated
OUT = Path(__file__).resolve().parents[1] / "warp_spt" / "bsdfs" / "ggx_tables.py"


def mu_node(i: np.ndarray | float) -> np.ndarray:
    return np.maximum((np.asarray(i, dtype=np.float64) / (N - 1)) ** 2, MU_MIN)


def alpha_node(j: np.ndarray | float) -> np.ndarray:
    return (np.asarray(j, dtype=np.float64) / (N - 1)) ** 2


def smith_lambda(cos2: np.ndarray, sin2: np.ndarray, alpha: float) -> np.ndarray:
    return 0.5 * (np.sqrt(1.0 + alpha * alpha * sin2 / np.maximum(cos2, 1e-300)) - 1.0)


def integrals(mu: float, alpha: float, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of each replicate, for one (mu, alpha): arrays of REPLICATES values."""
    mu = max(float(mu), MU_MIN)
    wo = np.array([np.sqrt(1.0 - mu * mu), 0.0, mu])
    lam_o = smith_lambda(mu * mu, 1.0 - mu * mu, alpha)
    # The view direction in the stretched (alpha = 1) configuration.
    ws = np.array([alpha * wo[0], 0.0, wo[2]])
    ws /= np.linalg.norm(ws)
    grid = (np.arange(STRATA) + 0.0) / STRATA
    g1, g2 = np.meshgrid(grid, grid, indexing="ij")
    out_a, out_b = np.empty(REPLICATES), np.empty(REPLICATES)
    for k in range(REPLICATES):
        u1 = (g1 + rng.random(g1.shape) / STRATA).ravel()
        u2 = (g2 + rng.random(g2.shape) / STRATA).ravel()
        phi = 2.0 * np.pi * u1
        z = (1.0 - u2) * (1.0 + ws[2]) - ws[2]
        s = np.sqrt(np.clip(1.0 - z * z, 0.0, 1.0))
        hx, hy, hz = s * np.cos(phi) + ws[0], s * np.sin(phi), z + ws[2]
        mx, my, mz = alpha * hx, alpha * hy, hz
        norm = np.sqrt(mx * mx + my * my + mz * mz)
        mx, my, mz = mx / norm, my / norm, mz / norm
        c = wo[0] * mx + wo[2] * mz
        wix, wiy, wiz = 2.0 * c * mx - wo[0], 2.0 * c * my, 2.0 * c * mz - wo[2]
        lam_i = smith_lambda(wiz * wiz, wix * wix + wiy * wiy, alpha)
        weight = np.where(wiz > 0.0, (1.0 + lam_o) / (1.0 + lam_o + lam_i), 0.0)
        f5 = (1.0 - np.clip(c, 0.0, 1.0)) ** 5
        out_a[k] = np.mean(weight * (1.0 - f5))
        out_b[k] = np.mean(weight * f5)
    return out_a, out_b


def build() -> dict:
    rng = np.random.default_rng(SEED)
    a = np.empty((N, N))
    b = np.empty((N, N))
    err = 0.0
    for i in range(N):
        for j in range(N):
            ra, rb = integrals(mu_node(i), alpha_node(j), rng)
            a[i, j], b[i, j] = ra.mean(), rb.mean()
            err = max(err, float(np.std(ra + rb, ddof=1) / np.sqrt(REPLICATES)))
    x, w = np.polynomial.legendre.leggauss(48)
    mus, wts = 0.5 * (x + 1.0), 0.5 * w
    avg = {name: np.empty(N) for name in ("E", "A", "B", "C", "D")}
    for j in range(N):
        vals = [tuple(r.mean() for r in integrals(m, alpha_node(j), rng)) for m in mus]
        ga = np.array([v[0] for v in vals])
        gb = np.array([v[1] for v in vals])
        ge = ga + gb
        for name, g in (("E", ge), ("A", ga), ("B", gb), ("C", ga * (1 - ge) / ge),
                        ("D", gb * (1 - ge) / ge)):
            avg[name][j] = 2.0 * np.sum(wts * g * mus)
    return {"A": a, "B": b, "avg": avg, "stderr": err, "rng": rng}


def bilinear(table: np.ndarray, mu: float, alpha: float) -> float:
    x = np.sqrt(mu) * (N - 1)
    y = np.sqrt(alpha) * (N - 1)
    i, j = min(int(x), N - 2), min(int(y), N - 2)
    fx, fy = x - i, y - j
    return float(table[i, j] * (1 - fx) * (1 - fy) + table[i + 1, j] * fx * (1 - fy)
                 + table[i, j + 1] * (1 - fx) * fy + table[i + 1, j + 1] * fx * fy)


def interpolation_error(t: dict) -> dict[float, float]:
    """Largest relative error of the bilinear E at the cell centres (the worst place for a
    bilinear look-up), against fresh integrals, over the cells with mu above each bound."""
    e = t["A"] + t["B"]
    bounds = (0.1, 0.0175, 0.0)           # 84.3 degrees, 89 degrees, everything
    worst = dict.fromkeys(bounds, 0.0)
    for i in range(N - 1):
        mu = ((i + 0.5) / (N - 1)) ** 2
        for j in range(N - 1):
            alpha = ((j + 0.5) / (N - 1)) ** 2
            ra, rb = integrals(mu, alpha, t["rng"])
            exact = float(ra.mean() + rb.mean())
            rel = abs(bilinear(e, mu, alpha) - exact) / exact
            for b in bounds:
                if mu >= b:
                    worst[b] = max(worst[b], rel)
    return worst


def _rows(name: str, values: np.ndarray) -> str:
    flat = [f"{float(v):.8g}" for v in np.asarray(values, dtype=np.float32).ravel()]
    lines = [", ".join(flat[k:k + 8]) for k in range(0, len(flat), 8)]
    return f"{name} = (\n    " + ",\n    ".join(lines) + ",\n)\n"


def write(t: dict, path: Path) -> None:
    text = ('"""Generated by scripts/make_ggx_tables.py (do not edit): the GGX directional albedo, split sum.\n\n'
            "A[i * N + j], B[i * N + j]: node at mu = (i / (N - 1))^2, alpha = (j / (N - 1))^2; the\n"
            "*_AVG: cosine-weighted hemispherical averages per alpha column (see the script's docstring).\n"
            '"""\n\n'
            f"N = {N}\n\n"
            + _rows("A", t["A"]) + "\n" + _rows("B", t["B"]) + "\n"
            + "".join(_rows(f"{k}_AVG", v) + "\n" for k, v in t["avg"].items()).rstrip("\n") + "\n")
    path.write_text(text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument("--check", action="store_true",
                        help="also measure the bilinear look-up's error at every cell centre")
    args = parser.parse_args()
    t = build()
    write(t, args.out)
    print(f"wrote {args.out}: largest standard error of a node's E: {t['stderr']:.2g}")
    if args.check:
        for bound, err in interpolation_error(t).items():
            print(f"bilinear E at cell centres with mu >= {bound} "
                  f"({np.degrees(np.arccos(bound)):.1f} deg): max relative error {err:.3%}")


if __name__ == "__main__":
    main()
