"""The viewer's camera math, ray cast and command line (issue 23): pure numpy, no rendering."""

from __future__ import annotations

import math
import shlex

import numpy as np
import pytest

import warp_spt
from warp_spt.viewer import navigation as nav
from warp_spt.viewer.command import CommandSpec, command_args, command_line
from warp_spt.viewer.raycast import first_hit, spheres_hit, triangles_hit

from tests.support.scenes import box_obj, material, write_scene_files

RIGS = [nav.make_rig((4, -55, 16), (4, 5, 16), (0, 0, 1), fov=38),
        nav.make_rig((3, 2, 10), (-1, 0.5, 0), (0, 1, 0), fov=60),
        nav.make_rig((0.1, 0.2, 5), (0, 0, 0), (0, 0, 1), fov=20)]     # nearly overhead


def angle_to_up(rig: nav.Rig) -> float:
    return math.degrees(math.acos(float(np.dot(-rig.direction, rig.up))))


@pytest.mark.parametrize("rig", RIGS)
@pytest.mark.parametrize("dx, dy", [(0.1, 0.0), (0.0, 0.2), (-0.37, 0.11), (2.5, -3.0)])
def test_orbit_keeps_the_target_and_the_distance(rig, dx, dy):
    out = nav.orbit(rig, dx, dy)
    assert np.array_equal(out.target, rig.target)
    assert out.distance == pytest.approx(rig.distance, rel=1e-12)
    assert not np.allclose(out.position, rig.position)


@pytest.mark.parametrize("rig", RIGS)
def test_a_full_turn_in_steps_returns_to_the_start(rig):
    out = rig
    steps = 36
    for _ in range(steps):                     # 2 view widths = 360 degrees
        out = nav.orbit(out, 2.0 * math.pi / nav.ORBIT_PER_VIEW / steps, 0.0)
    assert np.allclose(out.position, rig.position, atol=1e-9 * rig.distance)


@pytest.mark.parametrize("rig", RIGS)
def test_orbit_never_goes_over_the_pole(rig):
    for dy in (10.0, -10.0):
        out = nav.orbit(rig, 0.0, dy)
        elevation = 90.0 - angle_to_up(out)
        assert abs(elevation) == pytest.approx(math.degrees(nav.MAX_ELEVATION), abs=1e-9)
        assert abs(float(np.dot(out.direction, out.up))) < 0.99999    # Camera.axes's special case


def test_orbit_directions_follow_the_drag():
    rig = RIGS[0]
    right, image_up = nav.screen_axes(rig)
    moved = nav.orbit(rig, 0.01, 0.0).position - rig.position   # drag right: camera swings left
    assert float(np.dot(moved, right)) < 0
    lifted = nav.orbit(rig, 0.0, 0.01).position - rig.position  # drag down: camera rises
    assert float(np.dot(lifted, rig.up)) > 0


@pytest.mark.parametrize("rig", RIGS[:2])      # the third starts within 13 degrees of the clamp
def test_there_and_back_returns(rig):
    out = nav.orbit(nav.orbit(rig, 0.13, 0.07), -0.13, -0.07)
    assert np.allclose(out.position, rig.position, atol=1e-9 * rig.distance)


@pytest.mark.parametrize("rig", RIGS)
@pytest.mark.parametrize("dx, dy", [(0.1, 0.0), (0.0, -0.3), (0.25, 0.4)])
def test_pan_keeps_the_view_direction_and_distance(rig, dx, dy):
    out = nav.pan(rig, dx, dy, aspect=4 / 3)
    assert np.allclose(out.direction, rig.direction, atol=1e-12)
    assert out.distance == pytest.approx(rig.distance, rel=1e-12)
    assert np.allclose(out.position - rig.position, out.target - rig.target, atol=1e-12)
    back = nav.pan(out, -dx, -dy, aspect=4 / 3)
    assert np.allclose(back.position, rig.position, atol=1e-9 * rig.distance)


def test_pan_moves_the_target_point_with_the_cursor():
    """After a pan of dx view widths, the old target appears dx of the view further right."""
    rig, aspect = RIGS[1], 1.5
    out = nav.pan(rig, 0.2, -0.1, aspect)
    right, image_up = nav.screen_axes(out)
    v = rig.target - out.position
    depth = float(np.dot(v, out.direction))
    half = math.tan(math.radians(out.fov) / 2)
    x = 0.5 + float(np.dot(v, right)) / depth / half / 2
    y = 0.5 - float(np.dot(v, image_up)) / depth / (half / aspect) / 2
    assert (x, y) == pytest.approx((0.7, 0.4), abs=1e-9)


@pytest.mark.parametrize("rig", RIGS)
@pytest.mark.parametrize("steps", [1, -1, 3.5, -2])
def test_dolly_keeps_the_direction_and_target_and_scales_the_distance(rig, steps):
    out = nav.dolly(rig, steps)
    assert np.allclose(out.direction, rig.direction, atol=1e-12)
    assert np.array_equal(out.target, rig.target)
    assert out.distance == pytest.approx(rig.distance * nav.DOLLY_STEP ** steps, rel=1e-12)


def test_dolly_never_reaches_the_target():
    out = nav.dolly(RIGS[0], 10_000, min_distance=1e-3)
    assert out.distance == pytest.approx(1e-3)
    assert np.allclose(out.direction, RIGS[0].direction)


def test_zoom_changes_only_the_fov_within_bounds():
    rig = RIGS[0]
    assert nav.zoom(rig, 1).fov == pytest.approx(rig.fov / nav.FOV_STEP)
    assert nav.zoom(rig, 1).position is rig.position
    assert nav.zoom(rig, 100).fov == nav.MIN_FOV
    assert nav.zoom(rig, -100).fov == nav.MAX_FOV


def test_retarget_keeps_the_position_and_focuses_on_the_point():
    rig = RIGS[0]
    out = nav.retarget(rig, (10.0, 0.0, 5.0))
    assert np.array_equal(out.position, rig.position)
    assert out.focus_distance == pytest.approx(float(np.linalg.norm(np.array([10.0, 0, 5]) - rig.position)))


@pytest.mark.parametrize("rig", RIGS)
def test_pixel_rays_match_the_renderers_image_plane(rig):
    """The ray through a pixel's centre points where warp_spt.Camera's image plane puts that pixel."""
    w, h = 40, 30
    cam = warp_spt.Camera.look_at(rig.position, rig.target, up=rig.up, fov=rig.fov)
    plane = cam.image_plane(w, h)
    for px, py in [(0, 0), (39, 29), (17, 5), (20, 15)]:
        point = plane["upper_left"] + (px + 0.5) * plane["x_step"] - (py + 0.5) * plane["y_step"]
        expected = (point - plane["origin"]) / np.linalg.norm(point - plane["origin"])
        got = nav.pixel_ray(rig, (px + 0.5) / w, (py + 0.5) / h, w / h)
        assert np.allclose(got, expected, atol=1e-9)


# ------------------------------------------------------------------ ray cast

def test_triangle_and_sphere_hits():
    o, d = np.zeros(3), np.array([0.0, 0.0, 1.0])
    tri = [np.array([[-1.0, -1.0, 5.0]]), np.array([[1.0, -1.0, 5.0]]), np.array([[0.0, 1.0, 5.0]])]
    assert triangles_hit(o, d, *tri) == pytest.approx(5.0)
    assert triangles_hit(o, -d, *tri) == np.inf                       # behind the origin
    assert triangles_hit(o + [5.0, 0, 0], d, *tri) == np.inf         # beside it
    spheres = np.array([[0.0, 0.0, 10.0, 2.0], [0.0, 0.0, 4.0, 0.5]])
    assert spheres_hit(o, d, spheres) == pytest.approx(3.5)
    assert spheres_hit(np.array([0.0, 0.0, 10.0]), d, spheres) == pytest.approx(2.0)   # from inside


def test_first_hit_in_a_loaded_scene(tmp_path):
    objs, mtls = write_scene_files(tmp_path, "box", box_obj((-1, -1, -1), (1, 1, 1), "wall", subdivide=3),
                                   material("wall", Kd=(0.5, 0.5, 0.5)))
    scene = warp_spt.load_scene(objs, mtls)
    assert first_hit(scene, (0.2, -5.0, 0.3), (0.0, 1.0, 0.0)) == pytest.approx(4.0)
    assert first_hit(scene, (0.0, 0.0, 0.0), (0.0, 0.0, 1.0)) == pytest.approx(1.0)   # inside: the far wall
    assert first_hit(scene, (0.0, -5.0, 3.0), (0.0, 1.0, 0.0)) is None


def test_first_hit_through_instances_equals_the_flattened_scene(tmp_path):
    """A double-click on an instanced mesh (glTF nodes sharing a mesh) finds the placed copy: the same
    distance as in the scene with every placement copied into world space (Scene.flattened)."""
    from dataclasses import replace

    objs, mtls = write_scene_files(tmp_path, "box", box_obj((-1, -1, -1), (1, 1, 1), "wall", subdivide=2),
                                   material("wall", Kd=(0.5, 0.5, 0.5)))
    scene = warp_spt.load_scene(objs, mtls)
    c, s_ = math.cos(0.6), math.sin(0.6)
    moved = np.array([[c, -s_, 0.0, 3.0], [s_, c, 0.0, 0.5], [0.0, 0.0, 1.0, 0.2], [0.0, 0.0, 0.0, 1.0]])
    squashed = np.diag([0.5, 2.0, 0.25, 1.0])
    squashed[:3, 3] = (-3.0, 1.0, 0.0)
    inst = replace(scene, meshes=[replace(scene.meshes[0], transforms=np.stack([moved, squashed]))])
    assert inst.instanced
    flat = inst.flattened()
    rng = np.random.default_rng(3)
    hits = 0
    for _ in range(200):
        o = np.array([rng.choice([-3.0, 3.0]) + rng.uniform(-1.5, 1.5), -8.0, rng.uniform(-1.0, 1.0)])
        d = np.array([rng.uniform(-0.3, 0.3), 1.0, rng.uniform(-0.1, 0.1)])
        d /= np.linalg.norm(d)
        a, b = first_hit(inst, o, d), first_hit(flat, o, d)
        assert (a is None) == (b is None)
        if a is not None:
            hits += 1
            assert a == pytest.approx(b, rel=1e-9)
    assert hits >= 50


# ------------------------------------------------------------------ command line

def test_the_command_names_the_view_in_the_readmes_order():
    cam = warp_spt.Camera(position=(1.5, -2.25, 3.0), direction=(0.0, 0.6, 0.8), fov=45.5, focus=7.25,
                          aperture=0.125, up=(0.0, 1.0, 0.0))
    spec = CommandSpec(objs=("my model.obj",), mtls=("m.mtl",), up="y", width=320, height=200, spp=99,
                       max_depth=5, sky=None, sky_color=(0.35, 0.35, 0.35), integrator="seed",
                       sampler="independent", out="x.npy")
    args = shlex.split(command_line(cam, spec))
    assert args == command_args(cam, spec)
    assert args[:5] == ["warp-spt", "-obj", "my model.obj", "-mtl", "m.mtl"]
    cam_at = args.index("-cam")
    assert [float(v) for v in args[cam_at + 1:cam_at + 10]] == [1.5, -2.25, 3.0, 0.0, 0.6, 0.8, 45.5, 7.25, 0.125]
    flags = " ".join(args[cam_at + 10:])
    assert flags == ("--up y -res 320 200 -sr 99 -depth 5 --sky-color 0.35 0.35 0.35 "
                     "--integrator seed --sampler independent -out x.npy")


@pytest.mark.parametrize("sky, flag", [("blue", "-sky 0"), ("gradient", "-sky 1"), ("pink", "-sky 2")])
def test_the_seeds_skies_are_named_by_index(sky, flag):
    args = command_args(warp_spt.Camera(), CommandSpec(sky=sky))
    assert flag in " ".join(args) and "--up" not in args and "--sky-color" not in args


def test_camera_numbers_round_trip_to_float32():
    cam = warp_spt.Camera.look_at((1 / 3, -2 / 7, 1e-3), (5 / 9, 1 / 11, 2.0), fov=33.333333)
    args = command_args(cam, CommandSpec())
    i = args.index("-cam")
    values = np.array([float(v) for v in args[i + 1:i + 10]])
    expected = np.array([*cam.position, *cam.direction, cam.fov, cam.focus, cam.aperture])
    assert np.array_equal(values.astype(np.float32), expected.astype(np.float32))
