"""Adam on named scene parameters, with each step projected back into the parameter's valid range.

    opt = Adam(params, ["wall.diffuse"], lr=0.02)
    for it in range(50):
        r = render_gradients(params, settings, loss=l2(target), wrt=opt.names)
        opt.step(r.grads)
"""

from __future__ import annotations

import numpy as np

from warp_spt.diff.params import SceneParameters, value_range

FLOOR = 1e-4     # a path whose throughput is exactly 0 ends, so a colour of exactly 0 gets no gradient


class Adam:
    """Adam (Kingma & Ba 2015) over ``names`` of ``params``, the step size multiplied by ``decay`` after
    each step. Each value is clipped into its valid range (``params.value_range``: a material field's
    range in the material schema), raised by FLOOR at the bottom, so that it stays valid for
    ``params[name] = value`` and keeps a gradient: at exactly 0 a colour kills its paths."""

    def __init__(self, params: SceneParameters, names: list[str], lr: float = 0.01, betas=(0.9, 0.999),
                 eps: float = 1e-8, decay: float = 1.0):
        self.params, self.names, self.lr, self.betas, self.eps = params, list(names), lr, betas, eps
        self.decay = decay
        self.m = {n: np.zeros(params.info(n).shape) for n in self.names}
        self.v = {n: np.zeros(params.info(n).shape) for n in self.names}
        self.t = 0

    def step(self, grads: dict[str, np.ndarray]) -> None:
        b1, b2 = self.betas
        self.t += 1
        for n in self.names:
            g = np.asarray(grads[n], dtype=np.float64)
            self.m[n] = b1 * self.m[n] + (1 - b1) * g
            self.v[n] = b2 * self.v[n] + (1 - b2) * g * g
            m_hat = self.m[n] / (1 - b1 ** self.t)
            v_hat = self.v[n] / (1 - b2 ** self.t)
            value = self.params[n] - self.lr * m_hat / (np.sqrt(v_hat) + self.eps)
            low, high = value_range(self.params.info(n))
            if low is not None:          # camera vectors, a texture's numbers: any value
                value = np.clip(value, low + FLOOR, high)
            self.params[n] = value
        self.lr *= self.decay
