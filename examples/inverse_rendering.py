"""Inverse rendering with warp_spt: recover a Cornell wall's colour, and a 16x16 texture, from images.

    python examples/inverse_rendering.py        (PYTHONPATH=. python ... from a checkout not installed)

The two problems and the optimisation (Adam on an L2 loss, a fresh seed per iteration, the mean of
the last iterates) are :mod:`warp_spt.diff.inverse_demo`; notebooks/inverse_rendering.ipynb runs
them at smaller sizes and plots the loss curves; the converged errors are in docs/gradients.md.
"""

from __future__ import annotations

import numpy as np

from warp_spt.diff.inverse_demo import recover_texture, recover_wall_colour


def main() -> None:
    for run in (recover_wall_colour(), recover_texture()):
        print(f"{run.name}: target {np.round(run.target.reshape(-1)[:3], 4)} recovered "
              f"{np.round(run.value.reshape(-1)[:3], 4)}; max abs error {run.max_abs_error:.4f}, relative "
              f"{run.max_relative_error:.4f}; "
              f"RMSE / range {run.rmse_of_range:.4f}; loss {run.losses[0]:.3e} -> {run.losses[-1]:.3e}; "
              f"{run.seconds_per_iteration * 1e3:.0f} ms per iteration")


if __name__ == "__main__":
    main()
