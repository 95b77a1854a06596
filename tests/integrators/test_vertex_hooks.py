"""nee's vertex with hooks (``nee.VertexHooks``) is nee's vertex: hooks that change nothing give nee's
image bit for bit, so an integrator built on the hooks (guided, ears) shares nee's miss, emission,
MIS, depth and roulette code rather than a copy of it.

Two integrators are registered for the test only (monkeypatch): one with no hook but its own data
argument (the template's frame: Aux, new_out, finish; nee's roulette as the continuation), one whose
direction hook draws the material's own sample with share 1 (the hooked direction branch). Their
images are compared with nee's on the Cornell box of the stability suite, with a sky (MIS on misses)
and with Russian roulette on (the continuation).
"""

from dataclasses import replace

import numpy as np
import pytest
import warp as wp

from warp_spt.bsdfs import make_materials
from warp_spt.device.structs import Geometry, Materials, Textures
from warp_spt.emitters import Lights
from warp_spt.accel.surface import Surface
from warp_spt.integrators.common import PathState, RenderParams
from warp_spt.integrators.nee import VertexHooks, make_path_step
from warp_spt.rendering.settings import RenderSettings

from tests.support.stability_scenes import R, cornell_camera, cornell_files, load, sky


@wp.struct
class NoData:
    unused: int


@wp.func
def no_out() -> int:
    return 0


@wp.func
def path_only(p: PathState, out: int) -> PathState:
    return p


@wp.func
def no_guide(aux: NoData, mats: Materials, tex: Textures, sf: Surface) -> int:
    return 0


@wp.func
def whole_share(g: int) -> float:
    return 1.0


def _make(directed: bool):
    def make(features, sampler, differentiable=False):
        kw = {}
        if directed:
            mat = make_materials(features)

            @wp.func
            def own_sample(aux: NoData, g: int, mats: Materials, tex: Textures, sf: Surface, u_lobe: float,
                           u_dir: wp.vec2, u_fresnel: float):
                bs = mat.sample(mats, tex, sf, u_lobe, u_dir, u_fresnel)
                return bs, bs.pdf

            kw = {"guide": no_guide, "share": whole_share, "sample": own_sample}
        hooked = make_path_step(features, sampler, True, hooks=VertexHooks(Aux=NoData, new_out=no_out,
                                                                           finish=path_only, **kw))

        @wp.func
        def step(geo: Geometry, mats: Materials, tex: Textures, lights: Lights, rp: RenderParams,
                 path: PathState) -> PathState:
            return hooked(geo, mats, tex, lights, rp, path, NoData())

        return step

    return make


@pytest.fixture(scope="module")
def cornell(scene_dir):
    return load(*cornell_files(scene_dir))


@pytest.mark.parametrize("directed", [False, True], ids=["frame-only", "direction-hook"])
def test_hooks_that_change_nothing_give_nee_bit_for_bit(cornell, monkeypatch, directed):
    from warp_spt.integrators import INTEGRATORS

    name = f"hooked-{'directed' if directed else 'plain'}"
    monkeypatch.setitem(INTEGRATORS, name, replace(INTEGRATORS["nee"], name=name, make_step=_make(directed),
                                                   make_vertex=None, tape=False))
    images = {}
    for integ in ("nee", name):
        rs = RenderSettings(width=16, height=16, spp=8, max_depth=6, roulette_depth=2, sky=sky(0.4),
                            integrator=integ, seed=3)
        images[integ] = R.render_scene(cornell, cornell_camera(), rs).film.sum
    assert np.array_equal(images["nee"], images[name])
    assert images["nee"].max() > 0
