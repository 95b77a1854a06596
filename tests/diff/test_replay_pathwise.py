"""Path replay's pathwise kernel (warp_spt.diff.replay_pathwise) against the tape: the same estimator
with the same samples (hit points, normals, light samples and directions moving with the geometry and
the camera), so the two must agree to float32 rounding, for a mesh's positions, an object's pose and
the camera, under both integrators. The tape is checked against finite differences in
test_geometry_gradients.py; this pins the replay to it."""

from __future__ import annotations

import numpy as np
import pytest

from warp_spt.diff.gradients import render_gradients
from warp_spt.diff.params import parameters
from warp_spt.rendering.settings import RenderSettings

from tests.support import geometry_scenes as gs

ADJ = np.random.default_rng(7).uniform(0.2, 1.0, (16, 16, 3)).astype(np.float32)


@pytest.mark.parametrize("integrator", ["seed", "nee"])
def test_the_pathwise_replay_gives_the_tapes_geometry_and_camera_gradients(integrator):
    from warp_spt.scene.sky import Sky
    sky = Sky.gradient(zenith=(0.2, 0.3, 0.7), nadir=(0.7, 0.5, 0.3), up=(0.0, 1.0, 0.0))
    rs = RenderSettings(width=16, height=16, spp=4, max_depth=3, seed=3, integrator=integrator, sampler="sobol")
    tf = np.eye(4)
    tf[:3, :3] = [[1, 0, 0], [0, 0.8, -0.6], [0, 0.6, 0.8]]
    p = parameters(gs.scene([gs.square(0.6, material=gs.WHITE, transform=tf),
                             gs.cube("cube", material=gs.RED, transform=np.diag([0.3, 0.3, 0.3, 1.0]))]), gs.CAMERA, sky)
    names = ["square.positions", "square.rotation", "cube.positions", "cube.rotation", "camera.direction"]
    tape = render_gradients(p, rs, adjoint=ADJ, wrt=names, mode="tape", boundary=False)
    pw = render_gradients(p, rs, adjoint=ADJ, wrt=names, mode="prb", boundary=False)
    assert (tape.mode, pw.mode) == ("tape", "prb")
    np.testing.assert_array_equal(pw.image, tape.image)
    for n in names:
        scale = np.abs(tape.grads[n]).max()
        assert scale > 1e-2, n
        np.testing.assert_allclose(pw.grads[n], tape.grads[n], rtol=0, atol=1e-5 * scale, err_msg=n)
    # the default takes path replay (its pathwise kernel) for these parameters too
    assert render_gradients(p, rs, adjoint=ADJ, wrt=["cube.rotation"], boundary=False).mode == "prb"
