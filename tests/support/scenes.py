"""Small scenes written as OBJ/MTL text for engine tests (independent of the code under test)."""

from __future__ import annotations

from pathlib import Path

import numpy as np


def box_obj(lo=(-1.0, -1.0, -1.0), hi=(1.0, 1.0, 1.0), material="wall", subdivide: int = 1) -> str:
    """A closed axis-aligned box as OBJ text: 6 faces, each split into subdivide^2 quads (2 triangles)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    verts, faces = [], []
    for axis in range(3):
        for side in (0, 1):
            a, b = [k for k in range(3) if k != axis]
            n = subdivide
            base = len(verts)
            for i in range(n + 1):
                for j in range(n + 1):
                    p = np.empty(3)
                    p[axis] = hi[axis] if side else lo[axis]
                    p[a] = lo[a] + (hi[a] - lo[a]) * i / n
                    p[b] = lo[b] + (hi[b] - lo[b]) * j / n
                    verts.append(p)
            for i in range(n):
                for j in range(n):
                    v00 = base + i * (n + 1) + j + 1
                    v10, v01, v11 = v00 + n + 1, v00 + 1, v00 + n + 2
                    faces += [(v00, v10, v11), (v00, v11, v01)]
    lines = [f"v {p[0]:.9g} {p[1]:.9g} {p[2]:.9g}" for p in verts]
    lines.append(f"usemtl {material}")
    lines += [f"f {a} {b} {c}" for a, b, c in faces]
    return "\n".join(lines) + "\n"


def quad_obj(corners, uvs=((0, 0), (1, 0), (1, 1), (0, 1)), material="quad") -> str:
    """One quad (two triangles) with texture coordinates."""
    lines = [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in corners]
    lines += [f"vt {u:.9g} {v:.9g}" for u, v in uvs]
    lines += [f"usemtl {material}", "f 1/1 2/2 3/3", "f 1/1 3/3 4/4"]
    return "\n".join(lines) + "\n"


def material(name: str, **tags) -> str:
    """MTL text for one material; tags like Kd=(1, 1, 1), Roughness=1, Refractable=True."""
    out = [f"newmtl {name}"]
    for k, v in tags.items():
        if v is True:
            out.append(k)
        elif isinstance(v, (tuple, list)):
            out.append(f"{k} " + " ".join(f"{x:.9g}" for x in v))
        else:
            out.append(f"{k} {v}")
    return "\n".join(out) + "\n"


def write_scene_files(folder: Path, name: str, obj: str, mtl: str | None = None) -> tuple[list[str], list[str]]:
    """Write ``name.obj`` (and ``name.mtl``) into ``folder``; returns ([obj], [mtl]) paths for load_scene."""
    folder.mkdir(parents=True, exist_ok=True)
    o = folder / f"{name}.obj"
    o.write_text(obj)
    mtls = []
    if mtl is not None:
        m = folder / f"{name}.mtl"
        m.write_text(mtl)
        mtls.append(str(m))
    return [str(o)], mtls


def write_ball_sequence(folder: Path, frames) -> tuple[list[str], list[str]]:
    """A static room (``room.obj``) and one sphere file per frame (``ball_NN.obj``, moving along x).

    Returns the OBJ list for an animation (static file, template) and the MTL list.
    """
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "room.obj").write_text(box_obj((-1, -1, -1), (1, 1, 1), "wall"))
    for k in frames:
        (folder / f"ball_{k:02d}.obj").write_text(f"usemtl lamp\nb {-0.5 + 0.1 * k:.3f} 0.2 -0.3 0.25\n")
    (folder / "seq.mtl").write_text(material("wall", Kd=(0.7, 0.6, 0.5), Roughness=0.9)
                                    + material("lamp", Kl=(6, 5, 4)))
    return [str(folder / "room.obj"), str(folder / "ball_{frame:02d}.obj")], [str(folder / "seq.mtl")]
