"""Write ``warp_spt/bsdfs/sheen_table.py``: the directional albedo of the sheen lobe (KHR_materials_sheen).

The lobe is Khronos' glTF sample viewer's: the "Charlie" distribution and the fitted visibility of
Estevez & Kulla (2017), with alpha = roughness^2::

    D(h)  = (2 + 1/alpha) sin(theta_h)^(1/alpha) / (2 pi)
    V     = clamp(1 / ((1 + L(mu_o) + L(mu_i)) 4 mu_o mu_i), 0, 1)      (L the fitted Lambda)
    f cos = colour D V mu_i

Its albedo E_RAW(mu) = integral of D V mu_i over the hemisphere exceeds 1 at grazing angles for
roughness below about 0.19 (1.8 at roughness 0.05: the fit is not a masking function there), so the
renderer divides the lobe by max(1, E_RAW(mu_o), E_RAW(mu_i)), with E_RAW read from this table as the
kernel reads it (bilinear): symmetric in the two directions, and no direction reflects more than it
receives. ``E`` is the albedo of that lobe, the one the layering (the base scaled by
1 - max(colour) E(mu_o)) and the lobe choice read.

**Grid.** 32 x 32 nodes, row ``i`` at mu = (i / 31)^2 (row 0 at mu = 1e-4), column ``j`` at
roughness MIN_ROUGHNESS + (1 - MIN_ROUGHNESS) j / 31; look-ups are bilinear in (sqrt(mu), roughness).
Roughness is held at or above MIN_ROUGHNESS (Filament holds it at 0.045): below it the lobe is a
spike at the horizon that no table of this size resolves.

**Method.** Midpoint quadrature over (t, phi) with mu_i = t^3 (the lobe's mass crowds towards mu_i =
0 at low roughness), 768 x 384 points over a half-hemisphere (the lobe is symmetric in phi).
``--check`` prints the largest difference to a quadrature of twice the resolution at the nodes
(5.1e-06) and the bilinear look-up's error at the cell centres: 8.7e-03 where mu >= 0.1 (theta_o <
84 deg), 3.9e-02 at the worst cell, between 84 and 89 deg at the lowest roughnesses, where E climbs
from 0.8 to 1 within a cell.

Deterministic (numpy only); about a minute of CPU time.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

N = 32
MIN_ROUGHNESS = 0.07
MU_MIN = 1e-4
OUT = Path(__file__).resolve().parents[1] / "warp_spt" / "bsdfs" / "sheen_table.py"


def mu_nodes() -> np.ndarray:
    return np.maximum((np.arange(N) / (N - 1)) ** 2, MU_MIN)


def rough_nodes() -> np.ndarray:
    return MIN_ROUGHNESS + (1.0 - MIN_ROUGHNESS) * np.arange(N) / (N - 1)


def charlie(cos_h: np.ndarray, rough: float) -> np.ndarray:
    alpha = rough * rough
    return (2.0 + 1.0 / alpha) * np.maximum(1.0 - cos_h * cos_h, 0.0) ** (0.5 / alpha) / (2.0 * np.pi)


def _fit(x: np.ndarray, alpha: float) -> np.ndarray:
    t = (1.0 - alpha) ** 2
    a, b, c = 21.5473 + 3.7772 * t, 3.82987 - 0.50552 * t, 0.19823 - 0.03022 * t
    d, e = -1.97760 + 0.70367 * t, -4.32054 - 0.53913 * t
    return a / (1.0 + b * x ** c) + d * x + e


def sheen_lambda(mu: np.ndarray, alpha: float) -> np.ndarray:
    return np.where(mu < 0.5, np.exp(_fit(mu, alpha)), np.exp(2.0 * _fit(0.5, alpha) - _fit(1.0 - mu, alpha)))


def visibility(mu_o, mu_i, rough: float) -> np.ndarray:
    alpha = rough * rough
    v = 1.0 / ((1.0 + sheen_lambda(mu_o, alpha) + sheen_lambda(mu_i, alpha)) * 4.0 * mu_o * mu_i)
    return np.clip(v, 0.0, 1.0)


def lookup(table: np.ndarray, mu: np.ndarray, rough: float) -> np.ndarray:
    """The kernel's bilinear look-up (warp_spt/bsdfs/sheen.py), in numpy."""
    x = np.sqrt(np.clip(mu, 0.0, 1.0)) * (N - 1)
    y = np.clip((rough - MIN_ROUGHNESS) / (1.0 - MIN_ROUGHNESS), 0.0, 1.0) * (N - 1)
    i = np.minimum(x.astype(int), N - 2)
    j = min(int(y), N - 2)
    fx, fy = x - i, y - j
    return ((table[i, j] * (1 - fy) + table[i, j + 1] * fy) * (1 - fx)
            + (table[i + 1, j] * (1 - fy) + table[i + 1, j + 1] * fy) * fx)


def albedo(mu_o: float, rough: float, raw: np.ndarray | None, n_t: int = 768, n_phi: int = 384) -> float:
    """The lobe's albedo at mu_o: raw (``raw`` None) or divided by max(1, E_RAW(mu_o), E_RAW(mu_i))."""
    t = (np.arange(n_t) + 0.5) / n_t
    mu_i = t ** 3
    dmu = 3.0 * t ** 2 / n_t
    phi = (np.arange(n_phi) + 0.5) / n_phi * np.pi
    m, p = np.meshgrid(mu_i, phi, indexing="ij")
    s = np.sqrt(1.0 - m * m)
    wi = np.stack([s * np.cos(p), s * np.sin(p), m], -1)
    wo = np.array([np.sqrt(1.0 - mu_o * mu_o), 0.0, mu_o])
    h = wi + wo
    cos_h = h[..., 2] / np.linalg.norm(h, axis=-1)
    f = charlie(cos_h, rough) * visibility(mu_o, m, rough) * m
    if raw is not None:
        f = f / np.maximum(1.0, np.maximum(lookup(raw, np.array(mu_o), rough), lookup(raw, m, rough)))
    return float((f * dmu[:, None]).sum() * 2.0 * np.pi / n_phi)


def tables(**kw) -> tuple[np.ndarray, np.ndarray]:
    mus, roughs = mu_nodes(), rough_nodes()
    raw = np.array([[albedo(mu, r, None, **kw) for r in roughs] for mu in mus])
    e = np.array([[albedo(mu, r, raw, **kw) for r in roughs] for mu in mus])
    return raw, e


def _rows(values: np.ndarray) -> str:
    flat = [f"{v:.8g}" for v in values.ravel()]
    return "\n".join("    " + ", ".join(flat[k:k + 8]) + "," for k in range(0, len(flat), 8))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="print the quadrature's and the look-up's errors")
    args = ap.parse_args()
    raw, e = tables()
    OUT.write_text(f'''"""Generated by scripts/make_sheen_table.py (do not edit): the sheen lobe's directional albedo.

RAW[i * N + j]: the sample viewer's lobe (Charlie D, fitted V); E[i * N + j]: that lobe divided by
max(1, RAW(mu_o), RAW(mu_i)); node at mu = (i / (N - 1))^2, roughness = MIN_ROUGHNESS + (1 -
MIN_ROUGHNESS) j / (N - 1) (see the script's docstring).
"""

N = {N}
MIN_ROUGHNESS = {MIN_ROUGHNESS}

RAW = (
{_rows(raw)}
)

E = (
{_rows(e)}
)
''')
    print(f"wrote {OUT}: E_RAW max {raw.max():.4f}, E max {e.max():.4f}")
    if args.check:
        raw2, e2 = tables(n_t=1536, n_phi=768)
        print(f"quadrature: largest |E - E(2x)| {np.abs(e - e2).max():.2e}, "
              f"|RAW - RAW(2x)| {np.abs(raw - raw2).max():.2e}")
        worst = {0.1: 0.0, 0.02: 0.0, 0.0: 0.0}
        for j in range(N - 1):
            r = MIN_ROUGHNESS + (1.0 - MIN_ROUGHNESS) * (j + 0.5) / (N - 1)
            for i in range(N - 1):
                mu = ((i + 0.5) / (N - 1)) ** 2
                err = abs(float(lookup(e, np.array(mu), r)) - albedo(mu, r, raw))
                worst = {lo: max(w, err) if mu >= lo else w for lo, w in worst.items()}
        print("look-up: largest |E(bilinear) - E| at the cell centres: "
              + ", ".join(f"{w:.2e} where mu >= {lo}" for lo, w in worst.items()))


if __name__ == "__main__":
    main()
