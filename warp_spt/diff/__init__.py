"""Differentiable rendering: parameters by name, their gradients, and optimisation.

``params`` (SceneParameters: what can be edited and differentiated, by name), ``gradients``
(render_gradients: path replay or the tape), ``check`` (check_gradients: against finite
differences), ``prb`` (path-replay backpropagation), ``optim`` (Adam
and bounds), ``inverse_demo`` (the inverse-rendering demos of examples/ and notebooks/). Losses are
in :mod:`warp_spt.losses`.
"""
