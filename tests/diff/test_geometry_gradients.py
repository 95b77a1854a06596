"""Geometry gradients (positions, poses, spheres, the camera) with the primary-visibility boundary
term, against analytic derivatives and central finite differences of the primal render.

References are independent of the code under test: closed forms (an emitting square's image under
scaling and translation, a sphere's projected disc under its radius), and central differences of the
fast renderer (which knows nothing of gradients) with common random numbers. Tolerances come from
the estimated standard errors of both sides: the gradient's over ``SEEDS`` gradient seeds, the
difference's over as many render seeds; the difference's truncation error is bounded by comparing
steps h and 2h (|D(2h) - D(h)| bounds D(h)'s error whether it is O(h^2), a third of that, or O(h),
where a curve crosses a pixel's side under a random adjoint). Each
comparison must also resolve its reference (the tolerance below 10% of it), and the same comparison
with the boundary term switched off must fail: the silhouettes carry these derivatives.

All scenes share one feature set (tests/support/geometry_scenes.py): one set of kernels.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from warp_spt.diff.gradients import render_gradients
from warp_spt.diff.params import parameters
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene
from warp_spt.scene.sky import Sky

from tests.support import geometry_scenes as gs

W = H = 16
RS = RenderSettings(width=W, height=H, spp=16, max_depth=2, seed=3, integrator="seed")
FD_SPP = 2048
SEEDS = 4
ADJ = np.random.default_rng(7).uniform(0.2, 1.0, (H, W, 3)).astype(np.float32)
# A ramp across the image: where every vertex of the subject moves (the camera's translation), a
# random adjoint makes the objective kink each time a vertex crosses a pixel's side, and central
# differences over the step then err by O(h), not O(h^2)
RAMP = np.broadcast_to((0.5 + np.arange(W) / W)[None, :, None] * [1.0, 0.8, 0.6], (H, W, 3)).astype(np.float32)
# a gradient sky about the view's up axis: a surface's shading changes as it turns (the interior term)
LIT = Sky.gradient(zenith=(0.2, 0.3, 0.7), nadir=(0.7, 0.5, 0.3), up=(0.0, 1.0, 0.0))
PPU = H / (2.0 * 3.0 * math.tan(math.radians(20.0)))     # pixels per unit at the origin's depth (fov 40, distance 3)


def _params(meshes, spheres=None, sphere_materials=None, camera=gs.CAMERA, sky=gs.SKY):
    return parameters(gs.scene(meshes, spheres, sphere_materials), camera, sky)


def gradient(p, name: str, direction, adjoint=ADJ, rs=RS, **kw) -> tuple[float, float]:
    """(mean, standard error) of ``grad . direction`` over SEEDS gradient seeds."""
    u = np.asarray(direction, np.float64)
    vals = [float(np.sum(render_gradients(p, rs, adjoint=adjoint, wrt=[name], gradient_seed=100 + k, **kw)
                         .grads[name] * u)) for k in range(SEEDS)]
    return float(np.mean(vals)), float(np.std(vals, ddof=1) / math.sqrt(SEEDS))


def difference(p, name: str, direction, h: float, adjoint=ADJ, spp: int = FD_SPP,
               seeds: int = SEEDS, rs=RS) -> tuple[float, float, float]:
    """(D(h), its standard error, the truncation bound |D(2h) - D(h)|): central differences of
    sum(adjoint x image) along ``direction``, common random numbers per seed. (A smooth objective's
    central difference errs by O(h^2), a third of that bound; one with kinks, a curve crossing a
    pixel's side under a random adjoint, by O(h), about the bound itself.)"""
    v0 = p[name].astype(np.float64).copy()
    u = np.asarray(direction, np.float64).reshape(v0.shape)

    def objective(v, seed):
        p[name] = v
        img = render_scene(p.scene, p.camera, replace(rs, spp=spp, seed=seed, sky=p.sky)).film.image()
        return float(np.sum(img.astype(np.float64) * adjoint))

    try:
        d = {step: [(objective(v0 + step * u, s) - objective(v0 - step * u, s)) / (2 * step)
                    for s in range(seeds)] for step in (h, 2 * h)}
    finally:
        p[name] = v0
    return float(np.mean(d[h])), float(np.std(d[h], ddof=1) / math.sqrt(seeds)), abs(np.mean(d[2 * h]) - np.mean(d[h]))


def assert_matches(g, se_g, ref, se_ref, trunc=0.0, what="", resolve=0.1):
    tol = 4.0 * math.hypot(se_g, se_ref) + trunc + 1e-6 * abs(ref)
    print(f"{what}: gradient {g:.5f} +- {se_g:.5f}, reference {ref:.5f} +- {se_ref:.5f} (truncation {trunc:.5f})")
    assert tol < resolve * abs(ref), (what, "the reference is not resolved", tol, ref)
    assert abs(g - ref) <= tol, (what, g, ref, tol)
    return tol


def check_against_fd(p, name, direction, h, control=True, adjoint=ADJ, without=None, fd_spp=FD_SPP,
                     resolve=0.1, fd_seeds=SEEDS, rs=RS, **kw) -> float:
    """The gradient (with the boundary terms) matches the differences; without them (``without``:
    the keywords that leave a term out, default ``boundary=False``), it does not. Returns the
    gradient without them. ``resolve``: the largest tolerance accepted, relative to the reference."""
    ref, se_ref, trunc = difference(p, name, direction, h, adjoint, fd_spp, fd_seeds, rs)
    g, se = gradient(p, name, direction, adjoint, rs, **kw)
    tol = assert_matches(g, se, ref, se_ref, trunc, name, resolve)
    g0, _ = gradient(p, name, direction, adjoint, rs, **{**kw, **(without or {"boundary": False})})
    print(f"  without the boundary term: {g0:.5f}")
    if control:
        assert abs(g0 - ref) > 2 * tol, (name, "the boundary term made no difference", g0, ref)
    return g0


# --- analytic ---------------------------------------------------------------------------------

def test_an_emitting_square_scaled_and_translated():
    """A square of radiance 1 on the sky (0.25), face-on, fully in view: its image covers
    side^2 pixels, side = PPU x its size; d sum/d scale_x = 3 x 0.75 x side^2 (coverage grows as
    s_x s_y about the centre); translating it moves the left and right edges, each of side pixels,
    by PPU pixels per unit: the image's left half loses 3 x 0.75 x side x PPU per unit, its right half
    gains as much, and the whole image's derivative is 0."""
    p = _params([gs.square(0.5)])
    side = PPU
    ones = np.ones((H, W, 3), np.float32)
    g = render_gradients(p, RS, adjoint=ones, wrt=["square.scale"]).grads["square.scale"]
    assert g[:2] == pytest.approx([3 * 0.75 * side ** 2] * 2, rel=1e-4)
    left = ones.copy()
    left[:, W // 2:] = 0
    for adj, sign in ((left, -1.0), (1 - left, 1.0), (ones, 0.0)):
        g = render_gradients(p, RS, adjoint=adj, wrt=["square.translation"]).grads["square.translation"]
        assert g[0] == pytest.approx(sign * 3 * 0.75 * side * PPU, abs=1e-4 * side * PPU)
        assert g[2] == pytest.approx(3 * 0.75 * side ** 2 * 2 / 3.0 * (0.5 if sign else 1.0), rel=1e-4)
    g = render_gradients(p, RS, adjoint=ones, wrt=["square.scale"], boundary=False).grads["square.scale"]
    assert np.all(g == 0)           # its radiance is the same everywhere: all of it is the boundary's


def test_a_sphere_radius_under_a_constant_sky():
    """A red diffuse sphere under the constant sky reflects (0.8, 0.3, 0.2) x 0.25 at every point (it
    is convex): its image is a disc of that colour whose area is pi (PPT tan(asin(r / D)))^2 pixels."""
    r, dist = 0.5, 3.0
    p = _params([], [[0, 0, 0, r]], [gs.RED])
    ppt = H / (2 * math.tan(math.radians(20.0)))

    def area(x):
        return math.pi * (ppt * math.tan(math.asin(x / dist))) ** 2

    d_area = (area(r + 1e-6) - area(r - 1e-6)) / 2e-6
    contrast = sum(np.array([0.8, 0.3, 0.2]) * 0.25 - 0.25)
    g = render_gradients(p, RS, adjoint=np.ones((H, W, 3), np.float32), wrt=["sphere0.radius"]).grads["sphere0.radius"]
    assert float(g) == pytest.approx(contrast * d_area, rel=1e-3)


# --- finite differences of the primal ----------------------------------------------------------

def test_a_diffuse_square_rotated_under_the_sky():
    p = _params([gs.square(0.5, material=gs.RED, transform=gs.placement((0.5, 0.4, 0.2)))])
    check_against_fd(p, "square.rotation", (0.2, 1.0, 0.3), 0.02)


def test_an_emitter_translated():
    p = _params([gs.square(0.4)])
    check_against_fd(p, "square.translation", (1.0, 0.4, 0.5), 0.01)


def test_a_sphere_moved_and_scaled():
    p = _params([], [[0.1, -0.1, 0, 0.4]], [gs.RED])
    check_against_fd(p, "sphere0.center", (0.5, 1.0, -0.8), 0.01, fd_spp=4096)
    check_against_fd(p, "sphere0.radius", 1.0, 0.01, control=False, fd_spp=512)


def test_the_camera_translated_past_a_silhouette():
    p = _params([gs.cube(transform=gs.placement((0.4, 0.6, 0.1)))])
    check_against_fd(p, "camera.position", (1.0, 0.3, 0.0), 0.02, adjoint=RAMP)


def test_an_instance_rotated():
    """Under the gradient sky its faces' shading turns with them (the interior term: 0.64 of -19.1
    here) as its outline does (the boundary term, the rest)."""
    inst = replace(gs.cube(), transforms=np.stack([gs.placement((0.4, 0.6, 0.1)), gs.placement(offset=(0, 0, -500))]))
    p = _params([inst], sky=LIT)
    g0 = check_against_fd(p, "cube[0].rotation", (0.3, -1.0, 0.5), 0.02)
    assert abs(g0) > 0.3


def test_a_plane_filling_the_view_turned_under_the_gradient_sky():
    """No curve in view (the plane's edges are outside the image): the interior term is the whole
    derivative, and the primary boundary term adds exactly nothing (the secondary one a trace: the
    kit's tiny objects seen from the plane)."""
    p = _params([gs.square(6.0, material=gs.RED, transform=gs.placement((0.3, -0.2, 0.0)))], sky=LIT)
    g0 = check_against_fd(p, "square.rotation", (1.0, 0.5, 0.2), 0.01, control=False)
    g, _ = gradient(p, "square.rotation", (1.0, 0.5, 0.2), secondary_spp=0)
    assert g == g0 and abs(g0) > 1.0


def test_a_ball_inflated_along_its_normals():
    """The ball's vertices move along their normals (its interior and its silhouette alike)."""
    b = gs.ball(2, 0.6)
    p = _params([b])
    n = np.asarray(b.positions, np.float64)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    check_against_fd(p, "ball.positions", n, 0.01)


def test_a_gltf_node_translated(tmp_path):
    """A glTF file's node, read as an instance of its mesh (materials replaced by the kit's)."""
    from warp_spt.io.loader import load_scene

    from tests.support.format_files import CUBE_POSITIONS, CUBE_TRIANGLES, GltfBuilder

    g = GltfBuilder()
    g.mesh(CUBE_POSITIONS, CUBE_TRIANGLES)
    g.node(mesh=0, translation=[0.2, -0.1, 0.0], rotation=[0.2, 0.3, 0.1, float(np.sqrt(1 - 0.14))])
    g.node(mesh=0, translation=[0.0, 0.0, -400.0])
    (tmp_path / "two.gltf").write_bytes(g.gltf()[0])
    m = load_scene([str(tmp_path / "two.gltf")], []).meshes[0]
    assert m.transforms is not None and len(m.transforms) == 2
    m = replace(m, name="node", face_material=np.where(np.arange(12) // 2 % 2 == 0, gs.WHITE, gs.RED).astype(np.int32))
    p = _params([m])
    check_against_fd(p, "node[0].translation", (1.0, -0.5, 0.7), 0.01)


def test_a_cube_as_a_mesh_and_as_an_instance_has_one_gradient():
    """The same cube placed in world space and as an instance: the pose gradients agree, and the
    world mesh's translation is the sum of its vertices' gradients."""
    x = gs.placement((0.4, 0.6, 0.1), (0.1, 0.0, 0.0))
    world = _params([gs.cube(transform=x)])
    placed = _params([replace(gs.cube(), transforms=x[None])])
    for f in ("translation", "rotation", "scale"):
        a = [render_gradients(world, RS, adjoint=ADJ, wrt=[f"cube.{f}"], gradient_seed=k).grads[f"cube.{f}"]
             for k in range(SEEDS)]
        b = [render_gradients(placed, RS, adjoint=ADJ, wrt=[f"cube.{f}"], gradient_seed=k).grads[f"cube.{f}"]
             for k in range(SEEDS)]
        se = np.hypot(np.std(a, 0, ddof=1), np.std(b, 0, ddof=1)) / math.sqrt(SEEDS)
        print(f, np.mean(a, 0), np.mean(b, 0), se)
        assert np.all(np.abs(np.mean(a, 0) - np.mean(b, 0)) <= 4 * se + 1e-3 * np.abs(np.mean(a, 0)).max())
    r = render_gradients(world, RS, adjoint=ADJ, wrt=["cube.translation", "cube.positions"], gradient_seed=1)
    assert r.grads["cube.translation"] == pytest.approx(r.grads["cube.positions"].sum(0), rel=1e-5, abs=1e-6)


def test_geometry_gradients_are_identical_on_one_and_two_threads():
    """The tape's tiles reduce in tile order and the boundary term is one launch with numbers drawn
    from the seed: the same bits whatever the thread count."""
    p = _params([gs.cube(transform=gs.placement((0.4, 0.6, 0.1)))], [[0.6, 0.3, -0.2, 0.3]], [gs.RED])
    names = ["cube.translation", "cube.rotation", "cube.positions", "sphere0.center", "camera.position"]
    rs = replace(RS, tile_pixels=64)
    a, b = (render_gradients(p, replace(rs, threads=t), adjoint=ADJ, wrt=names).grads for t in (1, 2))
    for n in names:
        assert np.array_equal(a[n], b[n]), n
        assert np.any(a[n] != 0), n


# --- secondary visibility: what the camera rays' hits see ------------------------------------

def _lit_floor(*extra):
    """A white floor filling the view, lit by a lamp (emission 6, out of view, facing down) and the sky."""
    floor = gs.square(3.0, 0.0, gs.WHITE, "floor")
    lamp = gs.square(0.8, 0.0, gs.LAMP, "lamp", transform=gs.placement((np.pi, 0, 0), offset=(1.5, 0.0, 2.2)))
    return _params([floor, lamp, *extra])


def test_an_area_light_moved_over_a_floor():
    """The lamp is out of view: its motion reaches the image only through its outline as the floor
    sees it (the secondary term), which the control without it (secondary_spp=0) lacks entirely."""
    p = _lit_floor()
    check_against_fd(p, "lamp.translation", (1.0, 0.0, 0.0), 0.02, adjoint=RAMP, without={"secondary_spp": 0},
                     fd_spp=4096, resolve=0.2, secondary_spp=64)


def test_an_area_light_moved_over_a_floor_under_nee():
    """The same under next-event estimation (path replay's pathwise kernel): the lamp's light samples
    stay where they were in world space (the light table is the host's), the split that matches a
    boundary term taken at fixed directions (Reynolds' theorem on the sphere); the light-sample and
    BSDF-sample MIS weights' derivatives, both held, cancel in expectation."""
    p = _lit_floor()
    check_against_fd(p, "lamp.translation", (1.0, 0.0, 0.0), 0.02, adjoint=RAMP, without={"secondary_spp": 0},
                     fd_spp=4096, resolve=0.2, secondary_spp=64, rs=replace(RS, integrator="nee"), mode="prb")


def test_an_occluder_moved_between_a_light_and_a_floor():
    """The occluder hangs out of view between the lamp and the floor: its motion reaches the image
    only through its shadow's edge (and the patch of sky it hides), the secondary term; without it
    the gradient is 0. Where the shadow's edge is, a sample must find the lamp behind the occluder's
    edge: the estimate is noisier than the others (512 hits per pixel: a standard error of 5% of the
    derivative; the reference is resolved to a third)."""
    occ = gs.square(0.3, 0.0, gs.RED, "occluder", transform=gs.placement(offset=(1.0, 0.0, 1.4)))
    p = _lit_floor(occ)
    check_against_fd(p, "occluder.translation", (1.0, 0.5, 0.0), 0.02, without={"secondary_spp": 0},
                     fd_spp=8192, fd_seeds=8, resolve=0.35, secondary_spp=512)


def test_a_shadow_seen_in_a_mirror():
    """The camera sees a ceiling only in a mirror (a perfect one: no lobe with a density there); a
    lamp lights the ceiling past an occluder, both out of view directly and in the mirror. The
    occluder moves the image only through its shadow's edge on the ceiling, a curve the ceiling (the
    paths' second vertex) sees: the secondary term's deeper receivers. With the camera rays' hits
    alone (``secondary_depth=1``: the mirror, whose f cos is 0 off its reflection) the gradient is 0."""
    mirror = gs.square(3.0, 0.0, gs.MIRROR, "mirror")
    ceiling = gs.square(3.0, 0.0, gs.WHITE, "ceiling", transform=gs.placement((np.pi, 0, 0), offset=(0.0, 0.0, 4.4)))
    lamp = gs.square(0.4, 0.0, gs.LAMP, "lamp", transform=gs.placement(offset=(3.0, 0.0, 2.2)))
    occ = gs.square(0.3, 0.0, gs.RED, "occluder", transform=gs.placement(offset=(3.0, 0.0, 3.3)))
    p = _params([mirror, ceiling, lamp, occ])
    check_against_fd(p, "occluder.translation", (1.0, 0.5, 0.0), 0.02, rs=replace(RS, max_depth=3),
                     without={"secondary_depth": 1}, fd_spp=8192, fd_seeds=8, resolve=0.35,
                     secondary_spp=512, mode="prb")


def _shadowed_floor(light):
    """A white floor and a square hanging out of view between it and ``light`` (a sun or a bright
    point light: light selection under nee picks it in most samples), the square's hard shadow in view."""
    floor = gs.square(3.0, 0.0, gs.WHITE, "floor")
    occ = gs.square(0.2, 0.0, gs.RED, "occluder", transform=gs.placement(offset=(1.1, 0.1, 1.6)))
    return parameters(replace(gs.scene([floor, occ]), lights=[light]), gs.CAMERA, gs.SKY)


@pytest.mark.parametrize("light", ["point", "sun"])
def test_a_punctual_light_and_an_occluder_moved_over_a_floor(light):
    """Moving the light or the square moves the hard shadow's edge across the image: a jump no
    sampled direction crosses (a delta light), the shadow term's (diff.shadows); without the
    boundary terms the gradient keeps only the smooth change of the irradiance (the light) or
    nothing (the square)."""
    from warp_spt.scene.lights import PointLight, SunLight

    if light == "point":
        p = _shadowed_floor(PointLight(position=(1.4, 0.2, 2.2), intensity=(20.0, 20.0, 20.0), name="bulb"))
        own = "bulb.position"
    else:
        # turned about the vertical (the direction below, orthogonal to it and to its elevation's
        # gradient): the floor's irradiance holds to first order, the shadow moves. (The kit's own
        # shadows fall out of view at this elevation; from overhead they would fall in it.)
        p = _shadowed_floor(SunLight(direction=(0.3, 0.1, 1.0), color=(3.0, 3.0, 3.0), name="sun"))
        own = "sun.direction"
    rs = replace(RS, integrator="nee")
    turn = (-1.0, 3.0, 0.0) if light == "sun" else (1.0, 0.5, 0.0)
    # (a shadow's edge crossing pixel sides under the random adjoint makes the differences O(h): the
    # sun's check takes a small step and resolves its reference to a third; a point light's shadow
    # magnifies the square's motion 3.7 times: a ramp, not a random adjoint, and a smaller step)
    # (the square's forces are checked under the point light, whose shadow magnifies its motion; under
    # the sun its shadow's translation changes this image's sum too little to resolve)
    sun = light == "sun"
    checks = ((own, turn, ADJ, 0.003, 0.35, 4096, 2048),) if sun else \
        ((own, turn, ADJ, 0.01, 0.2, 4096, 2048), ("occluder.translation", (1.0, 0.5, 0.0), RAMP, 0.005, 0.2, 1024, 2048))
    for name, direction, adjoint, h, resolve, fd_spp, boundary_spp in checks:
        check_against_fd(p, name, direction, h, rs=rs, adjoint=adjoint, fd_spp=fd_spp, resolve=resolve,
                         boundary_spp=boundary_spp)
