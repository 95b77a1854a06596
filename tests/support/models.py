"""Procedural stand-ins for the public models a new user tries (bunny, teapot, cow), written as OBJ.

Each shape is built Z-up with its front towards -Y (the seed's axes), then optionally turned
Y-up (x, y, z) -> (x, z, -y), the usual export convention, scaled and moved. The blob is one closed,
welded mesh (for the "camera inside a closed mesh" case). ``marker=True`` writes the upper half
(along the model's own up axis) with material ``top`` and the rest with ``bottom``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def _sphere_grid(n_u: int = 48, n_v: int = 24):
    """A welded UV sphere: (V, 3) unit points, (F, 3) faces; poles are single vertices."""
    th = np.linspace(0, np.pi, n_v + 1)[1:-1]
    ph = np.linspace(0, 2 * np.pi, n_u, endpoint=False)
    t, p = np.meshgrid(th, ph, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    pts = np.concatenate([[[0, 0, 1]], ring, [[0, 0, -1]]])
    faces = []
    idx = lambda i, j: 1 + i * n_u + (j % n_u)
    for j in range(n_u):
        faces.append((0, idx(0, j), idx(0, j + 1)))
        faces.append((len(pts) - 1, idx(n_v - 2, j + 1), idx(n_v - 2, j)))
    for i in range(n_v - 2):
        for j in range(n_u):
            a, b, c, d = idx(i, j), idx(i, j + 1), idx(i + 1, j), idx(i + 1, j + 1)
            faces += [(a, c, b), (b, c, d)]
    return pts.astype(np.float64), np.array(faces)


def _deform(pts, fn):
    return pts * fn(pts)[:, None]


def bunny():
    """A lumpy closed blob with two ear bumps on top: about 1.1 x 0.9 x 1.6 (Z up)."""
    p, f = _sphere_grid()
    r = 1.0 + 0.12 * np.sin(3 * p[:, 0]) * np.cos(2 * p[:, 1]) + 0.5 * np.exp(-((p[:, 0] - 0.3) ** 2 + p[:, 1] ** 2
                                                                               + (p[:, 2] - 0.9) ** 2) * 20)
    r += 0.5 * np.exp(-((p[:, 0] + 0.3) ** 2 + p[:, 1] ** 2 + (p[:, 2] - 0.9) ** 2) * 20)
    q = p * r[:, None] * np.array([0.55, 0.45, 0.6])
    return [(q - [0, 0, q[:, 2].min()], f)]


def teapot():
    """A body of revolution with a spout and a handle (open parts, like the original teapot)."""
    body, f = _sphere_grid(40, 20)
    body = body * np.array([1.0, 1.0, 0.7])
    spout, fs = _sphere_grid(12, 8)
    spout = spout * np.array([0.6, 0.12, 0.12]) + np.array([1.2, 0, 0.25])
    handle, fh = _sphere_grid(12, 8)
    handle = handle * np.array([0.15, 0.08, 0.45]) + np.array([-1.05, 0, 0.1])
    parts = [(body, f), (spout, fs), (handle, fh)]
    low = min(p[:, 2].min() for p, _ in parts)
    return [(p - [0, 0, low], q) for p, q in parts]


def cow():
    """A long body, four legs and a head: about 2.6 x 0.8 x 1.6 (Z up)."""
    s, f = _sphere_grid(24, 12)
    parts = [(s * [1.0, 0.4, 0.4] + [0, 0, 1.0], f), (s * [0.35, 0.25, 0.3] + [1.2, 0, 1.3], f)]
    for x in (-0.6, 0.6):
        for y in (-0.22, 0.22):
            parts.append((s * [0.1, 0.1, 0.4] + [x, y, 0.4], f))
    low = min(p[:, 2].min() for p, _ in parts)
    return [(p - [0, 0, low], q) for p, q in parts]


def bust():
    """A scanned bust as scans come (issue 31): a head on a neck on a round plinth whose bottom is
    cut flat (a disc of faces in the lowest plane); about 1.2 x 1.2 x 2.2 (Z up)."""
    head, f = _sphere_grid(32, 16)
    parts = [(head * [0.45, 0.5, 0.6] + [0, 0, 1.55], f), (head * [0.2, 0.2, 0.35] + [0, 0, 0.95], f),
             (head * [0.6, 0.45, 0.35] + [0, 0, 0.75], f)]
    n = 40
    a = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = np.stack([0.6 * np.cos(a), 0.6 * np.sin(a), np.zeros(n)], -1)
    top = ring + [0, 0, 0.5]
    pts = np.concatenate([[[0, 0, 0]], ring, top])
    faces = [(0, 1 + (k + 1) % n, 1 + k) for k in range(n)]                     # the flat bottom, facing down
    faces += [(1 + k, 1 + (k + 1) % n, 1 + n + k) for k in range(n)]
    faces += [(1 + (k + 1) % n, 1 + n + (k + 1) % n, 1 + n + k) for k in range(n)]
    parts.append((pts, np.array(faces)))
    return parts


def bust_open():
    """:func:`bust` as many scans come: its cut base left open (no faces across it, only its rim)."""
    parts = bust()
    pts, faces = parts[-1]
    return parts[:-1] + [(pts[1:], faces[40:] - 1)]


def plaque():
    """A relief plaque standing upright, its flat back towards +Y: thin (2 x 0.15 x 1.4, Z up)."""
    n_u, n_v = 24, 16
    u, v = np.meshgrid(np.linspace(-1, 1, n_u), np.linspace(0, 1.4, n_v), indexing="ij")
    bump = 0.12 * np.exp(-(u ** 2 + (v - 0.7) ** 2) * 3)
    front = np.stack([u, -bump - 0.03, v], -1).reshape(-1, 3)
    back = np.stack([u, np.zeros_like(u), v], -1).reshape(-1, 3)
    idx = lambda i, j: i * n_v + j
    faces = []
    for i in range(n_u - 1):
        for j in range(n_v - 1):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i, j + 1), idx(i + 1, j + 1)
            faces += [(a, b, d), (a, d, c)]
    f = np.array(faces)
    return [(front, f), (back, f[:, ::-1])]


def spheres_on_floor():
    """Eight balls in a ring of radius 1.5 on a 24 x 24 floor (issue 31: a ground that framing took
    for the subject), Z up; egg-shaped (0.35 wide, 1.6 tall) so that upright means something."""
    s, f = _sphere_grid(24, 12)
    parts = [(np.array([[-12.0, -12, 0], [12, -12, 0], [12, 12, 0], [-12, 12, 0]]), np.array([[0, 1, 2], [0, 2, 3]]))]
    for k in range(8):
        a = 2 * np.pi * k / 8
        parts.append((s * [0.35, 0.35, 0.8] + [1.5 * np.cos(a), 1.5 * np.sin(a), 0.8], f))
    return parts


SHAPES = {"bunny": bunny, "teapot": teapot, "cow": cow, "bust": bust, "bust_open": bust_open, "plaque": plaque,
          "spheres_on_floor": spheres_on_floor}


def write_model(path: Path, shape: str, *, up: str = "z", scale: float = 1.0, offset=(0.0, 0.0, 0.0),
                marker: bool = False, tilt: float = 0.0, ply_comments: tuple[str, ...] | None = None) -> Path:
    """Write one generated model as an OBJ file and return its path. ``tilt``: degrees the model is
    turned about X first (a scan whose cut base is not quite a plane of the file's axes);
    ``ply_comments``: write an ascii PLY instead, with these header comments."""
    parts = SHAPES[shape]()
    if tilt:
        c, s_ = np.cos(np.radians(tilt)), np.sin(np.radians(tilt))
        turn = np.array([[1, 0, 0], [0, c, -s_], [0, s_, c]])
        parts = [(p @ turn.T, f) for p, f in parts]
    if ply_comments is not None:
        return _write_ply(path, parts, up, ply_comments)
    top = max(p[:, 2].max() for p, _ in parts)
    lines, base = [], 1
    for pts, faces in parts:
        q = pts * scale
        if up == "y":
            q = np.stack([q[:, 0], q[:, 2], -q[:, 1]], -1)
        q = q + np.asarray(offset, dtype=np.float64)
        digits = 17 if float(np.max(np.abs(offset))) > 1e5 else 9     # far off: every digit of the model
        lines += [f"v {x:.{digits}g} {y:.{digits}g} {z:.{digits}g}" for x, y, z in q]
        height = pts[faces].mean(1)[:, 2]
        groups = [("top", height > top / 2), ("bottom", height <= top / 2)] if marker else [(None, np.ones(len(faces), bool))]
        for name, sel in groups:
            if name:
                lines.append(f"usemtl {name}")
            lines += [f"f {a + base} {b + base} {c + base}" for a, b, c in faces[sel]]
        base += len(pts)
    path.write_text("\n".join(lines) + "\n")
    return path


MARKER_MTL = """newmtl top
Kd 0 0 0
Ke 1 0 0
newmtl bottom
Kd 0 0 0
Ke 0 1 0
"""


def _write_ply(path: Path, parts, up: str, comments: tuple[str, ...]) -> Path:
    """The parts as one ascii PLY (vertices and triangles), Y-up turned as write_model does."""
    pts, faces, base = [], [], 0
    for p, f in parts:
        pts.append(np.stack([p[:, 0], p[:, 2], -p[:, 1]], -1) if up == "y" else p)
        faces.append(f + base)
        base += len(p)
    v, f = np.concatenate(pts), np.concatenate(faces)
    head = ["ply", "format ascii 1.0", *(f"comment {c}" for c in comments), f"element vertex {len(v)}",
            "property float x", "property float y", "property float z", f"element face {len(f)}",
            "property list uchar int vertex_indices", "end_header"]
    body = [f"{x:.7g} {y:.7g} {z:.7g}" for x, y, z in v] + [f"3 {a} {b} {c}" for a, b, c in f]
    path.write_text("\n".join(head + body) + "\n")
    return path
