"""Geometry parameters (warp_spt.diff.geometry_params) and the boundary term's host geometry
(warp_spt.diff.boundary), checked without rendering: names, values, validation, what setting one
uploads, and each chain rule and projection against central differences of its own definition or
against a construction made another way (the pinhole rays of device.camera_rays, tangency)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from warp_spt.device.camera_rays import pinhole_directions
from warp_spt.diff import boundary as B
from warp_spt.diff import geometry_params as G
from warp_spt.diff.params import parameters

from tests.support import geometry_scenes as gs


def _params(meshes, spheres=None, sphere_materials=None):
    return parameters(gs.scene(meshes, spheres, sphere_materials), gs.CAMERA, gs.SKY)


def test_names_shapes_and_values():
    inst = replace(gs.cube("box"), transforms=np.stack([gs.placement(offset=(1, 0, 0)), gs.placement(offset=(-1, 0, 0))]))
    p = _params([gs.square(), inst], [[0, 0, 0.5, 0.25]], [gs.WHITE])
    names = p.names()
    for n in ("square.positions", "square.translation", "square.rotation", "square.scale", "box.positions",
              "box[0].translation", "box[1].rotation", "sphere0.center", "sphere0.radius"):
        assert n in names and n in p.differentiable(), n
    assert "box.translation" not in names          # placed twice: one pose per placement
    assert names[-2:] == ["camera.position", "camera.direction"]
    assert p["square.positions"].shape == (4, 3) and p.info("box.positions").shape == (8, 3)
    assert np.array_equal(p["box.positions"], gs.CUBE_P.astype(np.float32))      # own space: not moved
    assert np.array_equal(p["square.translation"], [0, 0, 0]) and np.array_equal(p["box[1].scale"], [1, 1, 1])
    assert p["sphere0.center"] == pytest.approx([0, 0, 0.5]) and float(p["sphere0.radius"]) == 0.25


def test_a_world_mesh_pose_moves_its_vertices_about_its_centre():
    p = _params([gs.cube(transform=gs.placement(offset=(0.5, 0, 0)))])
    p["cube.scale"] = (2.0, 1.0, 1.0)
    p["cube.translation"] = (0.0, 0.25, 0.0)
    pos = np.asarray(p.scene.scene.meshes[0].positions, np.float64)
    expect = (gs.CUBE_P + [0.5, 0, 0]) * [2, 1, 1] - [0.5, 0, 0] + [0, 0.25, 0]   # centre (0.5, 0, 0)
    assert np.allclose(pos, expect, atol=1e-6)
    assert np.array_equal(p["cube.positions"], (gs.CUBE_P + [0.5, 0, 0]).astype(np.float32))  # base positions
    p["cube.rotation"] = (0.0, 0.0, np.pi / 2)
    pos = np.asarray(p.scene.scene.meshes[0].positions, np.float64)
    # R(90 deg about z) diag(2, 1, 1) about the centre, then the translation
    local = (gs.CUBE_P) * [2, 1, 1]
    expect = np.stack([-local[:, 1], local[:, 0], local[:, 2]], 1) + [0.5, 0.25, 0]
    assert np.allclose(pos, expect, atol=1e-6)


def test_an_instance_pose_keeps_its_mesh_and_bvh():
    """A placed mesh's pose rebuilds the top-level BVH only; its positions rebuild its own."""
    inst = replace(gs.cube("box"), transforms=gs.placement()[None])
    p = _params([inst])
    mesh_before = p.scene._meshes[0]
    p["box.translation"] = (0.1, 0.2, 0.3)
    assert p.scene._meshes[0] is mesh_before
    assert np.allclose(p.scene.scene.meshes[0].transforms[0][:3, 3], [0.1, 0.2, 0.3])
    assert np.allclose(p.scene.geometry.inst_offset.numpy()[0], [0.1, 0.2, 0.3])
    lo = p.scene.geometry.node_lower.numpy()[0]
    assert lo[2] < -0.2 and lo[2] > -0.3                # the root box moved with it (the kit is elsewhere)
    p["box.positions"] = gs.CUBE_P * 1.5
    assert p.scene._meshes[0] is not mesh_before


@pytest.mark.parametrize("name, value, match", [
    ("square.positions", np.full((4, 3), np.nan), "finite"),
    ("square.positions", [[0, 0, 0], [0, 0, 0], [1, 1, 0], [0, 1, 0]], "degenerate"),
    ("square.positions", [[0, 0, 0], [2e15, 0, 0], [1, 1, 0], [0, 1, 0]], "within"),
    ("square.positions", np.zeros((3, 3)), "shape"),
    ("square.scale", (0.0, 1.0, 1.0), "scale component"),
    ("square.translation", (1e16, 0.0, 0.0), "within"),
    ("square.rotation", (np.inf, 0.0, 0.0), "finite"),
    ("sphere0.radius", 0.0, "radius must be > 0"),
    ("sphere0.radius", -1.0, "radius must be > 0"),
    ("sphere0.center", (0, 0, 1e16), "within"),
])
def test_bad_values_are_refused_and_change_nothing(name, value, match):
    p = _params([gs.square()], [[0, 0, 0.5, 0.25]], [gs.WHITE])
    before = (p.scene.scene.meshes[0].positions.copy(), p.scene.scene.spheres.copy(), p[name].copy())
    with pytest.raises(ValueError, match=match):
        p[name] = value
    assert np.array_equal(p.scene.scene.meshes[0].positions, before[0])
    assert np.array_equal(p.scene.scene.spheres, before[1]) and np.array_equal(p[name], before[2])


def test_a_sphere_moves_on_the_device():
    p = _params([], [[0, 0, 0.5, 0.25]], [gs.WHITE])
    p["sphere0.center"] = (0.1, 0.2, 0.3)
    p["sphere0.radius"] = 0.5
    assert np.allclose(p.scene.geometry.spheres.numpy()[0], [0.1, 0.2, 0.3, 0.5])
    assert np.allclose(p.scene.scene.spheres[0], [0.1, 0.2, 0.3, 0.5])


def test_rodrigues_is_a_rotation_and_agrees_with_its_series():
    rng = np.random.default_rng(0)
    for r in rng.normal(size=(5, 3)):
        m = G.rodrigues(r)
        assert np.allclose(m @ m.T, np.eye(3), atol=1e-12) and np.linalg.det(m) == pytest.approx(1.0)
        assert np.allclose(m @ r, r, atol=1e-12)                   # the axis stays
    assert np.allclose(G.rodrigues([0, 0, np.pi / 2]), [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)
    small = np.array([3e-9, -2e-9, 1e-9])
    k = np.array([[0, -small[2], small[1]], [small[2], 0, -small[0]], [-small[1], small[0], 0]])
    assert np.allclose(G.rodrigues(small), np.eye(3) + k, atol=1e-16)      # series branch = first order


def _numeric(f, x, h=1e-6):
    g = np.zeros_like(x)
    for i in np.ndindex(x.shape):
        xp, xm = x.copy(), x.copy()
        xp[i] += h
        xm[i] -= h
        g[i] = (f(xp) - f(xm)) / (2 * h)
    return g


def test_flat_normal_chain_rule_against_differences():
    m = gs.cube(transform=gs.placement((0.2, 0.4, -0.3)))
    scene = gs.scene([m])
    gn = np.random.default_rng(1).normal(size=(12, 3, 3))

    def objective(pos):
        tri = pos[m.indices]
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        return np.sum(gn * n[:, None, :])

    got = G.flat_normal_gradient(scene, 0, gn)
    assert np.allclose(got, _numeric(objective, np.asarray(m.positions, np.float64)), atol=1e-7)


def test_placed_pose_chain_rule_against_differences():
    pose = G.Pose(0, 0, gs.placement((0.1, 0.2, 0.3), (1, 2, 3), 1.5), np.array([0.5, 0.0, -1.0]),
                  np.array([0.1, -0.2, 0.3]), np.array([0.3, 0.1, -0.2]), np.array([1.2, 0.8, 1.1]))
    rng = np.random.default_rng(2)
    ga, gc, gn = rng.normal(size=(3, 3)), rng.normal(size=3), rng.normal(size=(3, 3))

    def objective(v):
        x = G.placement(pose, v)
        return np.sum(ga * x[:3, :3]) + gc @ x[:3, 3] + np.sum(gn * np.linalg.inv(x[:3, :3]).T)

    got = G.pose_gradient_placed(pose, ga, gc, gn)
    assert np.allclose(got, _numeric(objective, pose.values(), 1e-5), rtol=1e-6, atol=1e-6)


def test_projection_inverts_the_pinhole_rays_and_its_jacobian_is_its_derivative():
    w, h = 12, 9
    cam = replace(gs.CAMERA, position=(0.3, -0.2, 2.5), direction=(0.1, 0.05, -1.0))
    proj = B.Projection.of(cam, w, h)
    origin, dirs = pinhole_directions(cam, w, h)
    pts = origin + dirs.reshape(-1, 3) * np.linspace(0.5, 4.0, w * h)[:, None]
    px, lam = proj.project(pts)
    centres = np.stack(np.meshgrid(np.arange(w) + 0.5, np.arange(h) + 0.5), -1).reshape(-1, 2)
    assert np.allclose(px, centres, atol=1e-9) and np.all(lam > 0)
    assert np.allclose(proj.direction(centres), dirs.reshape(-1, 3), atol=1e-12)
    jac = proj.jacobian(pts[:5])
    for k in range(5):
        num = np.stack([(proj.project(pts[k] + e)[0] - proj.project(pts[k] - e)[0]) / 2e-6
                        for e in np.eye(3) * 1e-6], axis=1)
        assert np.allclose(jac[k], num, rtol=1e-6, atol=1e-6)
    # a blend of two points projects to the blend image_to_edge says
    a, b = pts[3], pts[40]
    (pa, la), (pb, lb) = proj.project(a), proj.project(b)
    for t in (0.1, 0.5, 0.9):
        s = B.image_to_edge(t, la, lb)
        assert np.allclose(proj.project(a + s * (b - a))[0], pa + t * (pb - pa), atol=1e-9)


def test_sphere_silhouette_points_graze_the_sphere():
    c, r, eye = np.array([0.2, -0.1, 0.3]), 0.7, np.array([1.0, 2.0, 3.0])
    x, _ = B.sphere_circle(c, r, eye, np.linspace(0, 2 * np.pi, 17))
    assert np.allclose(np.linalg.norm(x - c, axis=1), r, atol=1e-12)
    assert np.allclose(np.sum((x - c) * (x - eye), axis=1), 0.0, atol=1e-12)   # the ray from the eye is tangent
    assert B.sphere_circle(c, r, c + [0.1, 0, 0], np.zeros(1))[0] is None        # the eye inside: no silhouette


def test_edges_and_the_curves_a_camera_sees():
    cube = gs.cube(material=gs.WHITE)
    e = B.mesh_edges(cube, reads_corner_normals=True)
    assert len(e.verts) == 18 and np.all(e.faces[:, 1] >= 0)              # 12 edges + 6 diagonals, closed
    assert e.crease.sum() == 12                                         # flat faces: every real edge
    sq = B.mesh_edges(gs.square(), reads_corner_normals=True)
    assert len(sq.verts) == 5 and (sq.faces[:, 1] < 0).sum() == 4 and sq.crease.sum() == 0
    # a cube seen along a diagonal: its 6 silhouette edges and 3 visible creases (and 3 hidden ones)
    cam = replace(gs.CAMERA, position=(2.0, 2.0, 2.0), direction=(-1.0, -1.0, -1.0))
    proj = B.Projection.of(cam, 32, 32)
    curves = B.candidate_curves(gs.scene([cube]), True, proj, 32, 32, 1.0, {})
    mine = [c for c in curves if c.kind == "mesh" and c.index == 0]
    assert len(mine) == 12
    total = sum(c.length for c in mine)
    # the hexagon's perimeter in pixels: 6 edges of a unit cube seen at the same foreshortening
    assert total > 0 and all(c.length > 0 for c in mine)
