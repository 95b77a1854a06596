"""The sky's light-selection weight is sized by the subject, not by the studio's ground: a ground
30 times the model's size (``scene.studio.add_studio``) made a user's point light about one pick in
a hundred beside the sky (a fog lit by it rendered black at 2 spp)."""

from __future__ import annotations

import numpy as np

from warp_spt.emitters.sky import weigh
from warp_spt.scene.model import Scene
from warp_spt.scene.sky import Sky
from warp_spt.scene.studio import add_studio

from tests.support import geometry_scenes as gs


def test_the_sky_is_weighed_by_the_subject_not_the_ground():
    scene = Scene(meshes=[gs.cube()], spheres=np.zeros((0, 4)), sphere_material=np.zeros(0, np.int32),
                  materials=gs.materials(), textures=[], seed_dialect=False)
    dressed = add_studio(scene, up="y", key=False)
    ground = [m for m in dressed.meshes if m.prop]
    assert len(ground) == 1 and np.ptp(dressed.bounds, axis=0).max() > 20 * np.ptp(dressed.subject_bounds, axis=0).max()
    np.testing.assert_array_equal(dressed.subject_bounds, scene.bounds)
    sky = Sky.constant(0.1, 0.1, 0.1)
    np.testing.assert_array_equal(weigh(dressed, sky).weights, weigh(scene, sky).weights)
