"""docs/gltf_layers.png: the glTF material extensions the pbr kind reads, on spheres of one file.

Khronos' ClearCoatTest is not shipped with anything installable here, so the script writes its own
glTF: back row the bare materials, front row the same with a layer on top. Left to right: red
plastic (front: KHR_materials_clearcoat 1, coat roughness 0.05), a rough red plastic (front: a
coat of roughness 0.4), dark blue cloth (front: KHR_materials_sheen, colour 0.9 0.9 1, roughness
0.5), clear glass (front: KHR_materials_volume, attenuation colour 0.3 0.8 0.4 at 0.5 m: the
sphere darkens with the distance light travels in it). Rendered by one warp-spt command line, run
in-process (volpath, since the file has a medium); the command is printed.

    python scripts/make_gltf_layers_image.py [--width 640] [--spp 128]
"""

from __future__ import annotations

import argparse
import io
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # run from a checkout without installing

from tests.support.format_files import GltfBuilder  # noqa: E402
from warp_spt.cli.main import run  # noqa: E402
from warp_spt.cli.options import parse_args  # noqa: E402


def uv_sphere(n_lat: int = 32, n_lon: int = 64) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(positions, normals, triangles) of a closed unit sphere: poles shared, the seam welded."""
    lat = np.linspace(0.0, np.pi, n_lat + 1)[1:-1]
    lon = np.linspace(0.0, 2 * np.pi, n_lon, endpoint=False)
    t, p = np.meshgrid(lat, lon, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.cos(t), np.sin(t) * np.sin(p)], -1).reshape(-1, 3)
    pos = np.concatenate([[[0, 1, 0]], ring, [[0, -1, 0]]])
    tris = []
    idx = lambda i, j: 1 + i * n_lon + j % n_lon       # noqa: E731
    for j in range(n_lon):
        tris.append((0, idx(0, j + 1), idx(0, j)))
        tris.append((len(pos) - 1, idx(n_lat - 2, j), idx(n_lat - 2, j + 1)))
        for i in range(n_lat - 2):
            tris += [(idx(i, j), idx(i, j + 1), idx(i + 1, j + 1)), (idx(i, j), idx(i + 1, j + 1), idx(i + 1, j))]
    return pos, pos.astype(np.float32), np.array(tris, np.int32)


def materials() -> list[dict]:
    def pbr(name, colour, rough, metallic=0.0, **ext):
        return {"name": name, "pbrMetallicRoughness": {"baseColorFactor": [*colour, 1.0], "metallicFactor": metallic,
                                                       "roughnessFactor": rough}, "extensions": ext}
    red, blue = (0.6, 0.05, 0.04), (0.03, 0.05, 0.25)
    glass = {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": 1.5}}
    return [
        pbr("plastic", red, 0.6), pbr("plastic, coated", red, 0.6, KHR_materials_clearcoat={
            "clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 0.05}),
        pbr("rough plastic", red, 0.9), pbr("rough plastic, coat 0.4", red, 0.9, KHR_materials_clearcoat={
            "clearcoatFactor": 1.0, "clearcoatRoughnessFactor": 0.4}),
        pbr("cloth", blue, 0.9), pbr("cloth, sheen", blue, 0.9, KHR_materials_sheen={
            "sheenColorFactor": [0.9, 0.9, 1.0], "sheenRoughnessFactor": 0.5}),
        pbr("glass", (1, 1, 1), 0.0, **glass), pbr("glass, volume", (1, 1, 1), 0.0, **glass, KHR_materials_volume={
            "thicknessFactor": 1.0, "attenuationColor": [0.3, 0.8, 0.4], "attenuationDistance": 0.5}),
    ]


def scene() -> bytes:
    g = GltfBuilder()
    pos, nrm, tris = uv_sphere()
    mats = materials()
    g.doc["materials"] = mats
    for k in range(len(mats)):
        g.mesh(pos, tris, NORMAL=(nrm, "VEC3", 5126))
        g.doc["meshes"][k]["primitives"][0]["material"] = k
        column, front = divmod(k, 2)
        g.node(mesh=k, translation=[2.4 * (column - 1.5), 0.0, 1.2 if front else -1.2], scale=[0.9, 0.9, 0.9])
    g.doc["extensionsUsed"] = sorted({e for m in mats for e in m.get("extensions", {})})
    return g.gltf()[0]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--spp", type=int, default=128)
    args = ap.parse_args()
    out = ROOT / "docs" / "gltf_layers.png"
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "layers.gltf"
        path.write_bytes(scene())
        argv = ["-obj", str(path), "-res", str(args.width), str(args.width * 3 // 8), "-sr", str(args.spp),
                "--tonemap", "srgb", "--studio", "--view", "0,28", "-out", str(out)]
        print("warp-spt " + " ".join(argv).replace(tmp + "/", "").replace(str(ROOT) + "/", ""))
        run(parse_args(argv), stderr=io.StringIO())
    print(f"wrote {out.relative_to(ROOT)}")


if __name__ == "__main__":
    main()
