"""Large Steps (Nicolet, Jacobson and Jakob 2021): mesh positions optimised through a smooth latent.

    opt = LargeSteps(params, "blob.obj.positions", lr=0.01, lam=20.0)
    for it in range(100):
        r = render_gradients(params, settings, loss=l2(target), wrt=opt.names)
        opt.step(r.grads)

Plain gradient descent on vertex positions moves each vertex by its own gradient, and an image's
gradient is concentrated on the few vertices at silhouettes and edges: the mesh crumples long before
it takes the target's shape. Large Steps optimises instead the latent ``u = M v`` with
``M = I + lam L`` (``L`` the combinatorial Laplacian, ``laplacian``): ``v = M^-1 u`` is a smoothed
``u``. ``M`` is symmetric, so ``dLoss/du = M^-T dLoss/dv = M^-1 g``, and the step in ``v`` is the
gradient filtered twice by ``M^-1``, a low-pass filter of width about sqrt(lam) edges: a gradient at
one vertex moves its neighbourhood with it. The step in ``u`` is "uniform Adam": Adam whose second
moment is one number, the running mean of the largest squared entry of the gradient, so that every
vertex's step has the same scale (a per-entry second moment would undo the filter, blowing up the
vertices whose filtered gradient is small).

Both solves with ``M`` are by conjugate gradients (``cg_solve``) on a CSR matrix built here
(``SparseMatrix``), warm-started from the previous step's solution: ``M`` is fixed, and from one step
to the next ``u`` and the gradient change little. No sparse library is needed: the solve costs
milliseconds for a few thousand vertices (benchmarks/large_steps_solve.py), where one rendered
gradient costs seconds.

Vertices at the same place (the copies an OBJ or glTF reader makes at uv seams and split normals)
are fused (``fuse``) before anything else: the optimiser moves unique points, and each copy takes
its point's position, so a seam cannot open; the gradient of a point is the sum of its copies'.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_spt.diff.params import SceneParameters

FUSE_TOLERANCE = 1e-6      # of the mesh's bounding-box diagonal: copies written from one float agree exactly
CG_TOLERANCE = 1e-7        # relative residual; float32 positions need ~1e-7 relative


@dataclass(frozen=True)
class SparseMatrix:
    """A square matrix in compressed sparse rows: row ``i``'s columns ``indices[indptr[i]:indptr[i+1]]``
    with values ``data[...]``; every row has at least one entry (its diagonal)."""

    indptr: np.ndarray
    indices: np.ndarray
    data: np.ndarray

    @property
    def n(self) -> int:
        return len(self.indptr) - 1

    def __matmul__(self, x: np.ndarray) -> np.ndarray:
        prod = self.data.reshape((-1,) + (1,) * (x.ndim - 1)) * x[self.indices]
        return np.add.reduceat(prod, self.indptr[:-1], axis=0)

    def diagonal(self) -> np.ndarray:
        rows = np.repeat(np.arange(self.n), np.diff(self.indptr))
        out = np.zeros(self.n)
        on = rows == self.indices
        out[rows[on]] = self.data[on]
        return out

    def dense(self) -> np.ndarray:
        rows = np.repeat(np.arange(self.n), np.diff(self.indptr))
        out = np.zeros((self.n, self.n))
        np.add.at(out, (rows, self.indices), self.data)
        return out


def edges(faces: np.ndarray) -> np.ndarray:
    """(E, 2) the unique undirected edges of triangles ``faces`` (F, 3), each as (low, high)."""
    f = np.asarray(faces, dtype=np.int64)
    if f.ndim != 2 or f.shape[1] != 3:
        raise ValueError(f"faces must be an (F, 3) array of vertex indices, got shape {f.shape}")
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    e = np.sort(e, axis=1)
    e = e[e[:, 0] != e[:, 1]]                 # a triangle whose corners were fused has no such edge
    return np.unique(e, axis=0)


def laplacian(faces: np.ndarray, n: int, lam: float = 1.0, identity: float = 0.0) -> SparseMatrix:
    """``identity * I + lam * L`` over ``n`` vertices, ``L = D - A`` the combinatorial (uniform)
    Laplacian of the mesh ``faces``: ``A`` its adjacency, ``D`` the vertices' degrees. ``L`` is
    symmetric and its rows sum to 0; ``I + lam L`` (lam >= 0) is symmetric positive definite."""
    e = edges(faces)
    if len(e) and (e.min() < 0 or e.max() >= n):
        raise ValueError(f"faces index vertices 0..{n - 1}, got {e.min()}..{e.max()}")
    rows = np.concatenate([e[:, 0], e[:, 1], np.arange(n)])
    cols = np.concatenate([e[:, 1], e[:, 0], np.arange(n)])
    degree = np.bincount(e.reshape(-1), minlength=n).astype(np.float64)
    vals = np.concatenate([np.full(2 * len(e), -lam), identity + lam * degree])
    order = np.lexsort((cols, rows))
    indptr = np.concatenate([[0], np.cumsum(np.bincount(rows, minlength=n))])
    return SparseMatrix(indptr, cols[order], vals[order])


def cg_solve(a: SparseMatrix, b: np.ndarray, x0: np.ndarray | None = None, tol: float = CG_TOLERANCE,
             max_iter: int = 1000) -> tuple[np.ndarray, int]:
    """Solve ``a x = b`` (``a`` symmetric positive definite; ``b`` (n,) or (n, k), each column its own
    system) by conjugate gradients with the diagonal as preconditioner, from ``x0`` (default 0), until
    every column's residual is at most ``tol`` times its ``b``'s norm. Returns (x, iterations)."""
    b = np.asarray(b, dtype=np.float64)
    if b.shape[0] != a.n:
        raise ValueError(f"b must have {a.n} rows (the matrix's), got shape {b.shape}")
    col = b.reshape(a.n, -1)
    x = np.zeros_like(col) if x0 is None else np.array(x0, dtype=np.float64).reshape(col.shape)
    inv_diag = (1.0 / a.diagonal())[:, None]
    r = col - a @ x
    goal = tol * np.linalg.norm(col, axis=0)
    z = inv_diag * r
    p = z.copy()
    rz = np.sum(r * z, axis=0)
    it = 0
    while it < max_iter and np.any(np.linalg.norm(r, axis=0) > goal):
        ap = a @ p
        pap = np.sum(p * ap, axis=0)
        alpha = np.divide(rz, pap, out=np.zeros_like(rz), where=pap > 0)   # a converged column stops
        x += alpha * p
        r -= alpha * ap
        z = inv_diag * r
        rz_new = np.sum(r * z, axis=0)
        beta = np.divide(rz_new, rz, out=np.zeros_like(rz), where=rz > 0)
        p = z + beta * p
        rz = rz_new
        it += 1
    return x.reshape(b.shape), it


def fuse(positions: np.ndarray, tol: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Group vertices closer than ``tol`` in every coordinate (default FUSE_TOLERANCE of the bounding
    box's diagonal). Returns (``point`` (V,), each vertex's unique point, and ``first`` (U,), a vertex
    of each point): ``positions[first][point]`` moves every copy with its point.

    Vertices are binned in cells of side ``tol``; copies in one cell are one point, and points in
    neighbouring cells (two copies either side of a cell's wall) are joined where they are within ``tol``."""
    p = np.asarray(positions, dtype=np.float64)
    if p.ndim != 2 or p.shape[1] != 3 or not np.all(np.isfinite(p)):
        raise ValueError(f"positions must be a finite (V, 3) array, got shape {p.shape}")
    if tol is None:
        diag = float(np.linalg.norm(p.max(0) - p.min(0))) if len(p) else 0.0
        tol = FUSE_TOLERANCE * max(diag, 1e-30)
    if not tol > 0:
        raise ValueError(f"the fusing tolerance must be > 0, got {tol!r}")
    cell = np.floor((p - p.min(0)) / tol).astype(np.int64)
    _, first, cell_of = np.unique(cell, axis=0, return_index=True, return_inverse=True)
    cell_of = cell_of.reshape(-1)
    cells = cell[first]                                   # (C, 3), sorted lexicographically
    label = np.arange(len(cells))
    # the 13 neighbour offsets that come after (0, 0, 0) in lexicographic order: each pair once
    offsets = [(i, j, k) for i in (-1, 0, 1) for j in (-1, 0, 1) for k in (-1, 0, 1) if (i, j, k) > (0, 0, 0)]
    pairs = []
    for o in offsets:
        hit = _find_rows(cells, cells + np.array(o))
        ok = hit >= 0
        a, b = np.flatnonzero(ok), hit[ok]
        near = np.all(np.abs(p[first[a]] - p[first[b]]) < tol, axis=1)
        pairs.append(np.stack([a[near], b[near]], axis=1))
    pairs = np.concatenate(pairs) if pairs else np.zeros((0, 2), np.int64)
    while len(pairs):                                     # connected components by label propagation
        low = np.minimum(label[pairs[:, 0]], label[pairs[:, 1]])
        new = label.copy()
        np.minimum.at(new, pairs[:, 0], low)
        np.minimum.at(new, pairs[:, 1], low)
        new = new[new]
        if np.array_equal(new, label):
            break
        label = new
    _, point_of_cell = np.unique(label, return_inverse=True)
    point = point_of_cell.reshape(-1)[cell_of]
    first_vertex = np.full(point.max() + 1 if len(point) else 0, len(p), dtype=np.int64)
    np.minimum.at(first_vertex, point, np.arange(len(p)))
    order = np.argsort(first_vertex)                      # points numbered in the order of their first vertex
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    return rank[point], first_vertex[order]


def _find_rows(sorted_rows: np.ndarray, queries: np.ndarray) -> np.ndarray:
    """The index of each of ``queries`` (Q, 3) among ``sorted_rows`` (C, 3, unique, lexicographic), -1 if absent."""
    lo = sorted_rows.min(0) - 1
    span = sorted_rows.max(0) - lo + 2
    def key(r):
        return ((r[:, 0] - lo[0]) * span[1] + (r[:, 1] - lo[1])) * span[2] + (r[:, 2] - lo[2])
    k = key(sorted_rows)
    q = key(np.clip(queries, lo, lo + span - 1))
    at = np.clip(np.searchsorted(k, q), 0, len(k) - 1)
    return np.where(k[at] == q, at, -1)


class LargeSteps:
    """Large Steps on ``params[name]`` (a ``"<mesh>.positions"`` parameter): uniform Adam on the latent
    ``u = (I + lam L) v`` of the mesh's unique points. ``lr`` is the step in scene units per
    iteration before the filter (the first step moves every point by about ``lr`` in ``u``);
    ``betas`` and ``eps`` Adam's; ``tol`` and ``max_iter`` the solves'. ``fuse_seams`` False treats
    every vertex as its own point (the control of the seam test). ``cg_iterations`` holds each
    solve's iteration count."""

    def __init__(self, params: SceneParameters, name: str, lr: float = 0.01, lam: float = 10.0,
                 betas=(0.9, 0.999), eps: float = 1e-8, tol: float = CG_TOLERANCE, max_iter: int = 1000,
                 fuse_seams: bool = True, fuse_tol: float | None = None):
        info = params.info(name)
        if info.kind != "mesh":
            raise ValueError(f"LargeSteps optimises a mesh's positions (\"<mesh>.positions\"), not {name!r}")
        if not lam >= 0:
            raise ValueError(f"lam must be >= 0, got {lam!r}")
        self.params, self.name, self.names = params, name, [name]
        self.lr, self.betas, self.eps, self.tol, self.max_iter = lr, betas, eps, tol, max_iter
        v = params[name].astype(np.float64)
        faces = params.scene.scene.meshes[info.index].indices
        if fuse_seams:
            self.point, first = fuse(v, fuse_tol)
        else:
            self.point, first = np.arange(len(v)), np.arange(len(v))
        self.matrix = laplacian(self.point[np.asarray(faces)], len(first), lam, identity=1.0)
        self.v = v[first]
        self.u = self.matrix @ self.v
        self.m = np.zeros_like(self.u)
        self.s = 0.0                           # the uniform second moment
        self.t = 0
        self._g = np.zeros_like(self.u)        # the last solve's filtered gradient: the next one's start
        self.cg_iterations: list[int] = []

    def unique_gradient(self, g: np.ndarray) -> np.ndarray:
        """(U, 3): the gradient of the unique points, each the sum of its copies' (V, 3) ``g``."""
        out = np.zeros_like(self.u)
        np.add.at(out, self.point, np.asarray(g, dtype=np.float64).reshape(-1, 3))
        return out

    def step(self, grads: dict[str, np.ndarray]) -> None:
        g = np.asarray(grads[self.name], dtype=np.float64)
        if g.shape != (len(self.point), 3):
            raise ValueError(f"{self.name}: the gradient must have shape ({len(self.point)}, 3), got {g.shape}")
        b1, b2 = self.betas
        self.t += 1
        gu, it = cg_solve(self.matrix, self.unique_gradient(g), self._g, self.tol, self.max_iter)
        self.cg_iterations.append(it)
        self._g = gu
        self.m = b1 * self.m + (1 - b1) * gu
        self.s = b2 * self.s + (1 - b2) * float(np.max(gu * gu))
        m_hat = self.m / (1 - b1 ** self.t)
        s_hat = self.s / (1 - b2 ** self.t)
        self.u = self.u - self.lr * m_hat / (np.sqrt(s_hat) + self.eps)
        self.v, it = cg_solve(self.matrix, self.u, self.v, self.tol, self.max_iter)
        self.cg_iterations.append(it)
        self.params[self.name] = self.v[self.point]
