"""Instanced intersection (the renderer's traversal over MeshData.transforms) against the same
instances flattened into world-space meshes, traced by the same closest hit and shadow test."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from warp_spt.upload.device_scene import DeviceScene, Features, Geometry
from warp_spt.accel.ray_queries import make_closest_hit, make_occluded
from warp_spt.upload.instances import upload_instances
from warp_spt.io.gltf import quaternion_matrix
from warp_spt.scene.model import CHECKER_NAME, Material, MaterialTable, MeshData, Scene

# the renderer's own traversal, through the top-level BVH (small_scene=0), for both scenes
_closest = make_closest_hit(Features.general(), small_scene=0)
_occluded = make_occluded(Features.general(), small_scene=0)


@wp.kernel(enable_backward=False)
def _occ(s: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), t_max: wp.array(dtype=float),
         out: wp.array(dtype=int)):
    i = wp.tid()
    out[i] = wp.where(_occluded(s, o[i], d[i], t_max[i]), 1, 0)


@wp.kernel(enable_backward=False)
def _cast_flat(s: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), t: wp.array(dtype=float),
               index: wp.array(dtype=int), face: wp.array(dtype=int), n: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    h = _closest(s, o[i], d[i], 3.0e38)
    t[i] = h.t
    index[i] = wp.where(h.kind == 0, h.index, -1)
    face[i] = h.face
    n[i] = h.normal


@wp.kernel(enable_backward=False)
def _cast_inst(s: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), t: wp.array(dtype=float),
               index: wp.array(dtype=int), face: wp.array(dtype=int), n: wp.array(dtype=wp.vec3)):
    i = wp.tid()
    h = _closest(s, o[i], d[i], 3.0e38)
    t[i] = h.t
    index[i] = wp.where(h.kind == 0, h.placed - 1, -1)        # the top-level item: which instance
    face[i] = h.face
    n[i] = h.normal


def bumpy_sphere(n: int = 24) -> MeshData:
    """A closed, lumpy UV sphere: faces of many orientations and sizes."""
    th, ph = np.meshgrid(np.linspace(0, np.pi, n + 1), np.linspace(0, 2 * np.pi, 2 * n + 1), indexing="ij")
    r = 1 + 0.2 * np.sin(3 * th) * np.cos(5 * ph)
    p = np.stack([r * np.sin(th) * np.cos(ph), r * np.sin(th) * np.sin(ph), r * np.cos(th)], -1).reshape(-1, 3)
    k = np.arange((n + 1) * (2 * n + 1)).reshape(n + 1, 2 * n + 1)[:-1, :-1].reshape(-1)
    w = 2 * n + 1
    tri = np.concatenate([np.stack([k, k + w, k + w + 1], 1), np.stack([k, k + w + 1, k + 1], 1)])
    p0, p1, p2 = p[tri[:, 0]], p[tri[:, 1]], p[tri[:, 2]]
    tri = tri[np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1) > 1e-9]
    return _mesh(p, tri.astype(np.int32))


def _mesh(p: np.ndarray, tri: np.ndarray, name: str = "m") -> MeshData:
    return MeshData(name=name, positions=p.astype(np.float32), indices=tri, corner_uv=np.zeros((len(tri), 3, 2),
                    np.float32), corner_normal=None, face_material=np.zeros(len(tri), np.int32))


def transforms(rng: np.random.Generator, k: int) -> np.ndarray:
    """Rotations, non-uniform scales (one mirrored), translations."""
    out = []
    for i in range(k):
        q = rng.normal(size=4)
        m = np.eye(4)
        scale = rng.uniform(0.5, 2.0, 3) * (-1 if i == 1 else 1) ** np.array([1, 0, 0])
        m[:3, :3] = quaternion_matrix(q / np.linalg.norm(q)) * scale
        m[:3, 3] = rng.uniform(-6, 6, 3)
        out.append(m)
    return np.stack(out)


def flattened(meshes: list[MeshData], mesh_of: np.ndarray, xf: np.ndarray) -> DeviceScene:
    """Each instance copied into world space (a mirroring transform reverses the winding, as glTF's
    flattening does, so the geometric normal is A^-T n in both)."""
    copies = []
    for i, (m, x) in enumerate(zip(mesh_of, xf)):
        src = meshes[m]
        p = np.asarray(src.positions, np.float64) @ x[:3, :3].T + x[:3, 3]
        tri = src.indices[:, ::-1].copy() if np.linalg.det(x[:3, :3]) < 0 else src.indices
        copies.append(_mesh(p, tri, f"copy{i}"))
    table = MaterialTable.from_rows([Material(CHECKER_NAME)])
    return DeviceScene(Scene(meshes=copies, spheres=np.zeros((0, 4)), sphere_material=np.zeros(0, np.int32),
                             materials=table, textures=[]))


def _rays(rng, n, centres):
    """Rays from a box around the scene towards points near the instances' origins."""
    o = rng.uniform(-12, 12, (n, 3))
    target = centres[rng.integers(0, len(centres), n)] + rng.normal(0, 1.2, (n, 3))
    d = target - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return o.astype(np.float32), d.astype(np.float32)


def _cast(kernel, inputs, o, d):
    n = len(o)
    outs = [wp.zeros(n, dtype=float), wp.zeros(n, dtype=int), wp.zeros(n, dtype=int), wp.zeros(n, dtype=wp.vec3)]
    wp.launch(kernel, dim=n, inputs=[*inputs, wp.array(o, dtype=wp.vec3), wp.array(d, dtype=wp.vec3), *outs])
    return [a.numpy() for a in outs]


@pytest.mark.parametrize("wide_limit", [None, 0])        # our wide BVHs; Warp's BVH for every mesh
def test_instanced_hits_equal_the_flattened_scene(wide_limit):
    rng = np.random.default_rng(7)
    meshes = [bumpy_sphere(), _mesh(np.array([[0, 0, 0], [2, 0, 0], [0, 2, 0], [0, 0, 2]], np.float64),
                                    np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], np.int32), "tet")]
    mesh_of = np.array([0, 0, 1, 0, 1, 0, 0, 1])
    xf = transforms(rng, len(mesh_of))
    inst = upload_instances(meshes, mesh_of, xf)
    if wide_limit == 0:         # the instanced meshes through Warp's BVH: mesh_root -1
        inst.device.geometry.mesh_root = wp.array(np.full(len(meshes), -1, np.int32), dtype=wp.int32)
    assert inst.device.features.instances and len(inst.device._meshes) == len(meshes)    # each mesh uploaded once
    flat = flattened(meshes, mesh_of, xf)
    assert not flat.features.instances
    o, d = _rays(rng, 20000, xf[:, :3, 3])
    tf, idf, ff, nf = _cast(_cast_flat, [flat.geometry], o, d)
    ti, item, fi, ni = _cast(_cast_inst, [inst.device.geometry], o, d)
    instance_of = np.argsort(inst.item_of)
    idi = np.where(item >= 0, instance_of[np.maximum(item, 0)], -1)
    hit = idf >= 0
    assert 0.3 < hit.mean() < 0.95                       # the rays test both hits and misses
    same = (idf == idi) & (ff == fi)
    # rounding in the ray's transform may move a hit across a shared edge: a handful of rays at most
    assert (idf == idi).mean() > 0.999 and same[hit].mean() > 0.995
    both = same & hit
    assert np.allclose(ti[both], tf[both], rtol=1e-4, atol=0)     # measured: 2.8e-5 at most
    assert np.allclose(ni[both], nf[both], atol=2e-4)
    # shadow rays ending at a random fraction of the way to the closest hit, or beyond it: blocked
    # exactly when they reach it (rays ending within 1e-3 of the hit are left out: rounding)
    frac = rng.uniform(0.0, 2.0, len(o)).astype(np.float32)
    t_max = np.where(hit, np.where(hit, tf, 0.0) * frac, 50.0).astype(np.float32)   # misses: t = 3e38
    clear = ~hit | (np.abs(frac - 1) > 1e-3)
    args = [wp.array(o, dtype=wp.vec3), wp.array(d, dtype=wp.vec3), wp.array(t_max, dtype=float)]
    flat_out, inst_out = wp.zeros(len(o), dtype=int), wp.zeros(len(o), dtype=int)
    wp.launch(_occ, dim=len(o), inputs=[flat.geometry, *args, flat_out])
    wp.launch(_occ, dim=len(o), inputs=[inst.device.geometry, *args, inst_out])
    want = hit & (frac > 1)
    assert np.array_equal(flat_out.numpy()[clear], want[clear])
    assert np.array_equal(inst_out.numpy()[clear], want[clear])


def test_bad_instances_are_refused():
    m = bumpy_sphere(4)
    with pytest.raises(ValueError, match="invertible"):
        upload_instances([m], [0], np.zeros((1, 4, 4)))
    with pytest.raises(ValueError, match="mesh index out of range"):
        upload_instances([m], [1], np.eye(4)[None])


_closest_diff = make_closest_hit(Features.general(), small_scene=0, differentiable=True)


@wp.kernel
def _hit_distance(s: Geometry, o: wp.array(dtype=wp.vec3), d: wp.array(dtype=wp.vec3), t: wp.array(dtype=float)):
    i = wp.tid()
    h = _closest_diff(s, o[i], d[i], 3.0e38)
    t[i] = wp.where(h.kind == 0, h.t, 0.0)


def _distance_gradient(dev: DeviceScene, o: np.ndarray, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t, dt/do) per ray through the differentiable closest hit (its closed-form re-intersection)."""
    oa = wp.array(o, dtype=wp.vec3, requires_grad=True)
    da = wp.array(d, dtype=wp.vec3, requires_grad=True)
    t = wp.zeros(len(o), dtype=float, requires_grad=True)
    tape = wp.Tape()
    with tape:
        wp.launch(_hit_distance, dim=len(o), inputs=[dev.geometry, oa, da, t])
    tape.backward(grads={t: wp.ones(len(o), dtype=float)})
    return t.numpy(), oa.grad.numpy()


def test_the_differentiable_hit_distance_through_an_instance_moves_as_the_flattened_one():
    """dt/do is -n / (d . n) on a triangle's plane: the re-intersection must use the placed corners."""
    rng = np.random.default_rng(11)
    meshes = [bumpy_sphere(8)]
    mesh_of = np.zeros(3, np.int32)
    xf = transforms(rng, 3)
    inst = upload_instances(meshes, mesh_of, xf)
    flat = flattened(meshes, mesh_of, xf)
    o, d = _rays(rng, 400, xf[:, :3, 3])
    ti, gi = _distance_gradient(inst.device, o, d)
    tf, gf = _distance_gradient(flat, o, d)
    hit = (ti > 0) & (tf > 0) & np.isclose(ti, tf, rtol=1e-4)
    assert hit.mean() > 0.3 and np.abs(gf[hit]).max() > 0.1
    assert np.allclose(gi[hit], gf[hit], rtol=1e-3, atol=1e-3)
