"""Instances in the renderer: a mesh placed by several transforms (MeshData.transforms) is uploaded once
and renders as the same scene flattened into world-space copies (Scene.flattened), within the
statistical error of both images; glTF files whose nodes share a mesh, or move it rigidly, come in
as instances."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from warp_spt.upload.device_scene import DeviceScene
from warp_spt.io.gltf import quaternion_matrix
from warp_spt.rendering.settings import RenderSettings
from warp_spt.rendering.tiles import render_scene
from warp_spt.scene.camera import Camera
from warp_spt.scene.lights import SunLight
from warp_spt.scene.model import CHECKER_NAME, Material, MaterialTable, MeshData, Scene
from warp_spt.scene.sky import Sky

from tests.support import format_files
from tests.support.stability_scenes import assert_same_image, sky
from tests.accel.test_instances import bumpy_sphere


def _uv_sphere() -> MeshData:
    """The lumpy sphere with smooth corner normals and a spherical uv (tangent frames for anisotropy)."""
    m = bumpy_sphere(12)
    p = m.positions.astype(np.float64)[m.indices]                    # (F, 3, 3)
    n = p / np.linalg.norm(p, axis=2, keepdims=True)
    uv = np.stack([np.arctan2(p[..., 1], p[..., 0]) / (2 * np.pi) + 0.5, np.arccos(np.clip(n[..., 2], -1, 1)) / np.pi],
                  -1)
    return replace(m, corner_uv=uv.astype(np.float32), corner_normal=n.astype(np.float32))


def _quad(size: float, z: float, material: int) -> MeshData:
    p = np.array([[-size, -size, z], [size, -size, z], [size, size, z], [-size, size, z]], np.float64)
    tri = np.array([[0, 1, 2], [0, 2, 3]], np.int32)
    return MeshData("quad", p, tri, np.zeros((2, 3, 2), np.float32), None, np.full(2, material, np.int32))


def _placement(q, scale, offset) -> np.ndarray:
    x = np.eye(4)
    x[:3, :3] = quaternion_matrix(np.asarray(q, np.float64) / np.linalg.norm(q)) @ np.diag(scale)
    x[:3, 3] = offset
    return x


def instanced_scene() -> Scene:
    """Three placements of one sphere (a rotation with non-uniform scale, a mirror, a plain move) on a
    ground, lit by a low sun and a small emitting quad placed twice (emitters are flattened at upload)."""
    table = MaterialTable.from_rows([
        Material(CHECKER_NAME),
        Material.pbr("brushed", base_color=(0.9, 0.6, 0.3), metallic=1.0, roughness=0.35, anisotropy=0.8),
        Material.pbr("clay", base_color=(0.6, 0.6, 0.6), roughness=1.0),
        Material.pbr("lamp", base_color=(0.0, 0.0, 0.0), emission=(20.0, 20.0, 16.0)),
    ])
    sphere = _uv_sphere()
    sphere = replace(sphere, face_material=np.where(np.arange(len(sphere.indices)) % 2 == 0, 1, 2).astype(np.int32),
                     transforms=np.stack([_placement([0.3, 0.2, 0.9, 0.4], [1.4, 0.7, 1.0], [-2.2, 0.3, 1.0]),
                                          _placement([1, 0, 0, 0], [-1.0, 1.0, 1.2], [0.0, 0.0, 1.2]),
                                          _placement([0.1, 0.9, 0.1, 0.3], [0.8, 0.8, 0.8], [2.1, -0.4, 0.8])]))
    lamp = replace(_quad(0.6, 0.0, 3), transforms=np.stack([_placement([0, 1, 0, 0], [1, 1, 1], [-1.5, 0, 4.5]),
                                                            _placement([0, 1, 0, 0], [2, 1, 1], [1.5, 0, 4.5])]))
    scene = Scene(meshes=[_quad(6.0, 0.0, 2), sphere, lamp], spheres=np.zeros((0, 4)),
                  sphere_material=np.zeros(0, np.int32), materials=table, textures=[], seed_dialect=False)
    # a low sun from the side: shading that a wrong normal or point would change
    return scene.add_light(SunLight(direction=(-0.7, -0.4, 0.6), color=(3.0, 3.0, 3.0)))


CAMERA = Camera.look_at((0.0, -9.0, 4.0), (0.0, 0.0, 1.0), up="z", fov=40.0)


def _batches(dev: DeviceScene, k: int, **kw) -> np.ndarray:
    rs = RenderSettings(width=32, height=24, spp=4, max_depth=3, sky=sky(0.0), integrator="nee", **kw)
    return np.stack([render_scene(dev, CAMERA, replace(rs, seed=1000 + s)).image for s in range(k)])


def test_instances_render_as_the_flattened_scene():
    scene = instanced_scene()
    inst, flat = DeviceScene(scene), DeviceScene(scene.flattened())
    # the sphere is uploaded once: the ground, the sphere, and the lamp's two copies joined in world space
    assert inst.features.instances and not flat.features.instances
    assert len(inst._meshes) == 3 and len(flat._meshes) == 6
    assert inst.geometry.num_instances == 5 and inst.geometry.num_meshes == 3
    assert inst.scene.meshes[2].transforms is None and len(inst.scene.meshes[2].indices) == 4
    assert inst.features.needs("frame.uv")              # the anisotropic metal reads the tangents
    a, b = _batches(inst, 10), _batches(flat, 10)
    assert a.mean() > 0.05
    assert_same_image(a, b, "instanced against flattened")


def test_a_gltf_with_a_shared_mesh_renders_through_instances(tmp_path, capsys):
    from warp_spt.cli.main import main
    from warp_spt.io.loader import load_scene

    path = tmp_path / "two.glb"
    path.write_bytes(format_files.gltf_two_instances().glb())
    scene = load_scene([path])
    assert scene.instanced and len(scene.meshes) == 1 and scene.meshes[0].transforms.shape == (2, 4, 4)
    dev = DeviceScene(scene)
    assert dev.features.instances and len(dev._meshes) == 1 and dev.geometry.num_instances == 2
    flat = scene.flattened()
    assert np.allclose(scene.bounds, flat.bounds, rtol=1e-6, atol=1e-6)
    cam = Camera.look_at((5.5, -8.0, 0.5), (5.5, 0.0, -2.2), up="z", fov=80.0)        # both cubes in view
    # a sky bright above and dark below: the cubes' faces differ (under a constant sky a white
    # furnace-like cube would look the same whatever its normals)
    rs = RenderSettings(width=36, height=24, spp=2, max_depth=2, integrator="nee",
                        sky=Sky.gradient((1.0, 1.0, 1.0), (0.05, 0.05, 0.05), up=(0, 0, 1)))
    ks = range(6)
    a = np.stack([render_scene(dev, cam, replace(rs, seed=s)).image for s in ks])
    b = np.stack([render_scene(DeviceScene(flat), cam, replace(rs, seed=s)).image for s in ks])
    assert_same_image(a, b, "glTF instanced against flattened", block=4)
    out = tmp_path / "two.npy"
    assert main(["-obj", str(path), "-res", "8", "6", "-sr", "1", "-out", str(out)]) == 0
    assert np.load(out).shape[:2] == (6, 8)
    said = capsys.readouterr()
    assert "12 triangles, 24 placed by instances" in said.out + said.err


def test_bad_transforms_are_refused():
    from warp_spt.scene.errors import SceneError

    scene = instanced_scene()
    sphere = scene.meshes[1]
    far = np.eye(4)[None].copy()
    far[0, 0, 3] = 1e16
    huge = np.diag([1e11, 1.0, 1.0, 1.0])[None]
    for bad, match in ((np.zeros((1, 4, 4)), "invertible"), (np.full((1, 4, 4), np.nan), "non-finite"),
                       (np.eye(4), "shape"), (far, "beyond the supported range"), (huge, "edge of")):
        with pytest.raises(SceneError, match=match):
            DeviceScene(replace(scene, meshes=[scene.meshes[0], replace(sphere, transforms=bad)]))


def test_a_rigidly_moving_gltf_mesh_keeps_its_bvh_from_frame_to_frame(tmp_path):
    from warp_spt.animation import ObjSequence

    (tmp_path / "a.glb").write_bytes(format_files.gltf_animated().glb())      # a cube turned and moved by its node
    seq = ObjSequence([str(tmp_path / "a.glb")], fps=4)
    cache: dict = {}
    first = DeviceScene(seq.scene(0), meshes=cache)
    later = DeviceScene(seq.scene(2), meshes=cache)
    assert seq.scene(0).meshes[0].transforms is not None
    assert not np.array_equal(seq.scene(0).meshes[0].transforms, seq.scene(2).meshes[0].transforms)
    # the same wp.Mesh and wide BVH: only the instance's transform changed
    assert later._meshes[0] is first._meshes[0] and len(cache) == 1
    assert list(cache.values())[0].wide is not None
    assert not np.array_equal(first.geometry.inst_linear.numpy(), later.geometry.inst_linear.numpy())
    # what a cluster ships is keyed with the placements (a moved mesh is sent again); the BVH cache without
    from warp_spt.upload.device_scene import mesh_key

    m0, m2 = seq.scene(0).meshes[0], seq.scene(2).meshes[0]
    assert mesh_key(m0) != mesh_key(m2) and mesh_key(m0, placements=False) == mesh_key(m2, placements=False)


def test_a_shared_mesh_under_a_node_scaled_to_nothing_is_not_drawn_there():
    from warp_spt.io.gltf import parse_gltf_bytes, world_triangles

    g = format_files.gltf_two_instances()
    g.doc["nodes"][2]["matrix"] = [0.0] * 16           # the second placement: a zero matrix hides it
    g.doc["nodes"][2]["matrix"][15] = 1.0
    d = parse_gltf_bytes(g.gltf()[0], "hidden.gltf")
    (sub, transforms), = d.extras.placed
    assert len(transforms) == 1
    assert np.allclose(world_triangles(d)[0], format_files.two_instances_expected()[:8], atol=1e-12)


@pytest.mark.parametrize("mirror", [False, True])
def test_framing_cues_of_instances_equal_those_of_the_flattened_scene(mirror):
    from warp_spt.scene.camera import base_share, exact_bounds, flat_normal, subject_bounds

    rng = np.random.default_rng(3)
    # a flat model: quads placed in the plane z = 0.3 x (rotations about that plane's normal, scales within it)
    n = np.array([-0.3, 0.0, 1.0]) / np.linalg.norm([-0.3, 0.0, 1.0])
    e1 = np.array([1.0, 0.0, 0.3]) / np.linalg.norm([1.0, 0.0, 0.3])
    e2 = np.cross(n, e1)
    xs = []
    for k in range(5):
        x = np.eye(4)
        a, s = rng.uniform(0, 2 * np.pi), rng.uniform(0.5, 2.0, 2) * ([-1, 1] if mirror and k == 2 else [1, 1])
        rot = np.stack([e1, e2, n], 1) @ np.array([[np.cos(a), -np.sin(a), 0], [np.sin(a), np.cos(a), 0], [0, 0, 1]])
        x[:3, :3] = rot @ np.diag([s[0], s[1], 1.0])
        x[:3, 3] = e1 * rng.uniform(-5, 5) + e2 * rng.uniform(-5, 5)
        xs.append(x)
    flat_quad = replace(_quad(1.0, 0.0, 0), transforms=np.stack(xs))
    solid = instanced_scene()
    for scene in (replace(solid, meshes=[flat_quad], lights=[]), solid):
        flat = scene.flattened()
        towards = np.array([0.2, -1.0, 0.5])
        a, b = flat_normal(scene, towards), flat_normal(flat, towards)
        assert (a is None) == (b is None)
        if a is not None:
            assert np.allclose(a, b, atol=1e-9)
        assert np.allclose(exact_bounds(scene), exact_bounds(flat), rtol=1e-12, atol=1e-12)
        for up in ("y", "z"):
            assert base_share(scene, up) == pytest.approx(base_share(flat, up), rel=1e-9)
            sa, sb = subject_bounds(scene, up), subject_bounds(flat, up)
            assert (sa is None) == (sb is None) and (sa is None or np.allclose(sa, sb, rtol=1e-6, atol=1e-6))
    assert flat_normal(replace(solid, meshes=[flat_quad], lights=[]), towards) is not None     # the cue is exercised
