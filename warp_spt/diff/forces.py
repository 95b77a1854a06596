"""Boundary terms as forces on points of the geometry, and the chain rule from them to parameters.

A boundary sample's contribution to the loss's derivative is ``F . dX/dtheta`` for a point X of the
geometry that moves with theta (a point of an edge, a sphere's tangency point, a receiver's surface
point) and a force ``F`` the sample computed (its weight times the curve's normal, over the way the
image or the sphere of directions maps X). Whatever made the force (``diff.boundary``'s primary
samples, ``diff.secondary``'s), the point's motion is the geometry's:

* a point of a mesh is a fixed blend of up to three of its vertices (``vids``, ``weights``) in its own
  space, placed by its placement (an instance's transform, or a world-space mesh's pose);
* a point of a sphere moves with its centre and, scaled about it, with its radius.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_spt.diff import geometry_params as geo_params
from warp_spt.diff.geometry_params import MESH, POSE, SPHERE


@dataclass
class Forces:
    """Forces (N, 3) on world points (N, 3); ``sphere`` (N,) whether the point is a sphere's (else a
    mesh's), ``index`` its mesh or sphere, ``placement`` its mesh's placement, ``vids`` (N, 3) and
    ``weights`` (N, 3) the vertices it blends (a mesh's)."""

    point: np.ndarray
    force: np.ndarray
    sphere: np.ndarray
    index: np.ndarray
    placement: np.ndarray
    vids: np.ndarray
    weights: np.ndarray

    @classmethod
    def empty(cls) -> "Forces":
        return cls(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0, bool), np.zeros(0, np.int64),
                   np.zeros(0, np.int64), np.zeros((0, 3), np.int64), np.zeros((0, 3)))

    @classmethod
    def join(cls, parts: list["Forces"]) -> "Forces":
        if not parts:
            return cls.empty()
        return cls(*(np.concatenate([getattr(p, f) for p in parts]) for f in
                     ("point", "force", "sphere", "index", "placement", "vids", "weights")))


def chain(p, f: Forces, scene, poses: list) -> np.ndarray:
    """The gradient of geometry parameter ``p`` (a mesh's positions, a pose, a sphere's centre or
    radius) from the forces on its points."""
    if p.kind == SPHERE:
        sel = f.sphere & (f.index == p.index)
        sph = np.asarray(scene.spheres, dtype=np.float64).reshape(-1, 4)[p.index]
        if p.field == "center":
            return f.force[sel].sum(axis=0) if sel.any() else np.zeros(3)
        return np.asarray(np.sum(f.force[sel] * (f.point[sel] - sph[:3])) / sph[3]).reshape(())
    k = p.index if p.kind == MESH else poses[p.index].mesh
    m = scene.meshes[k]
    sel = ~f.sphere & (f.index == k)
    if p.kind == MESH:
        rows = np.flatnonzero(sel)
        if m.transforms is None:         # world points of base positions moved by the mesh's pose
            lin = np.broadcast_to(geo_params.placement(next(q for q in poses if q.mesh == k))[:3, :3],
                                  (len(rows), 3, 3))
        else:
            lin = np.asarray(m.transforms, np.float64)[f.placement[rows], :3, :3]
        own = np.einsum("ni,nij->nj", f.force[rows], lin)        # the force on the own-space point
        g = np.zeros((len(m.positions), 3))
        for j in range(3):
            np.add.at(g, f.vids[rows, j], f.weights[rows, j, None] * own)
        return g
    pose = poses[p.index]
    rows = np.flatnonzero(sel & (f.placement == pose.placement))
    if not len(rows):
        return np.zeros(3)
    full = geo_params.placement(pose)
    obj = (f.point[rows] - full[:3, 3]) @ np.linalg.inv(full[:3, :3]).T      # own-space (or base) points
    # sum F . (A obj + c) = <A, sum F obj^T> + c . sum F: the points summed once, not per difference
    moment = f.force[rows].T @ obj
    total = f.force[rows].sum(axis=0)
    g9 = geo_params.pose_derivative(pose, lambda x: np.sum(moment * x[:3, :3]) + total @ x[:3, 3])
    return g9[geo_params.pose_slice(p.field)]


def chain_all(wanted: list, f: Forces, scene, poses: list) -> dict[str, np.ndarray]:
    """:func:`chain` for every geometry parameter among ``wanted`` (the camera's are the sources' own)."""
    return {p.name: chain(p, f, scene, poses) for p in wanted if p.kind in (MESH, POSE, SPHERE)}
