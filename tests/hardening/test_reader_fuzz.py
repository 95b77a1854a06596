"""Per-reader fuzzers (issue 42): valid files of each reader mutated byte by byte (and, for glTF, value
by value) give a clean error naming the file (SceneError, or the image readers' ValueError; for
line-based files the line, for glTF the JSON pointer) or data that loads, in bounded memory. Here
through the loader and the readers' public entry points, not their parsers alone
(tests/hardening/test_format_fuzz.py fuzzes the PLY and glTF parsers).

Each reader has a short run in the default tier and a long one in the slow tier (tests/conftest.py)."""

from __future__ import annotations

import json
import sys
import tracemalloc

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from warp_spt.scene.errors import SceneError

from tests.hardening.test_format_fuzz import mutated_bytes
from tests.support.format_files import (FakeBlosc, blosc_grid, gltf_animated, gltf_camera_and_light, gltf_textured_box,
                                        ply_bytes)

SHORT, LONG = 25, 1500
MEMORY_BOUND = 16 << 20                 # numpy's and the readers' fixed costs, as test_format_fuzz's


def _settings(n: int):
    return settings(max_examples=n, deadline=None, derandomize=n == SHORT,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


def _outcome(read, path, data: bytes, errors=(SceneError,), per_result=lambda out, path: 0):
    """Write ``data`` to ``path``, read it: the result, or None for an error that names the file; the
    peak of Python's allocations bounded by the input's size (and ``per_result(out, path)`` bytes for
    what it read or declared: an image compressed to a few bytes may hold its whole texel budget)."""
    path.write_bytes(data)
    tracemalloc.start()
    try:
        try:
            out = read(str(path))
        except errors as err:
            assert str(path) in str(err) and "\n" not in str(err), err
            out = None
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < MEMORY_BOUND + 50 * len(data) + per_result(out, path), peak
    return out


# ---------------------------------------------------------------------------- environment images

def _image_seeds() -> dict[str, list[bytes]]:
    import io

    from PIL import Image

    from warp_spt.images.hdr import encode_rgbe

    rng = np.random.default_rng(3)
    img = (rng.random((8, 16, 3)) * 3).astype(np.float32)
    rgbe = encode_rgbe(img)
    flat = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 8 +X 16\n" + rgbe.tobytes()
    rle = bytearray(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n+Y 8 +X 16\n")
    for row in rgbe:
        rle += bytes((2, 2, 0, 16))
        for ch in range(4):
            rle += bytes((16,)) + row[:, ch].tobytes()           # one literal run per channel
    pf = b"PF\n16 8\n-1.0\n" + img[::-1].astype("<f4").tobytes()
    grey = b"Pf\n16 8\n1.0\n" + img[::-1, :, 0].astype(">f4").tobytes()
    npy = io.BytesIO()
    np.save(npy, img.astype(np.float64))
    png = io.BytesIO()
    Image.fromarray((img / 3 * 255).astype(np.uint8)).save(png, format="PNG")
    seeds = {".hdr": [flat, bytes(rle)], ".pfm": [pf, grey], ".npy": [npy.getvalue()], ".png": [png.getvalue()]}
    try:
        import OpenEXR

        exr = OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                           {"RGB": img})
        exr.write(str(_image_seeds.folder / "seed.exr"))
        seeds[".exr"] = [(_image_seeds.folder / "seed.exr").read_bytes()]
    except Exception:              # the optional extra absent, or another OpenEXR API: the rest still run
        pass
    return seeds


def _read_image(path: str):
    from warp_spt.images.environment import read_environment_image

    img = read_environment_image(path)
    assert img.dtype == np.float32 and img.ndim == 3 and img.shape[2] == 3 and img.size > 0
    return img


def _image_bytes(img, path) -> int:
    """What reading an image may take beyond its input: the readers' stated budget per texel, of what
    it read, or for an EXR that fails to decode, of the size its header declares (checked against the
    texel budget before decoding; OpenEXR allocates for it before it finds the data missing)."""
    from warp_spt.images.environment import READ_BYTES_PER_TEXEL

    texels = 0
    if img is not None:
        texels = img.shape[0] * img.shape[1]
    elif str(path).endswith(".exr"):
        import OpenEXR

        try:
            with OpenEXR.File(str(path), header_only=True) as head:
                (x0, y0), (x1, y1) = head.header()["dataWindow"]
            texels = (int(x1) - int(x0) + 1) * (int(y1) - int(y0) + 1)
        except Exception:          # a header OpenEXR cannot read: nothing was decoded
            pass
    return max(READ_BYTES_PER_TEXEL.values()) * texels


@pytest.fixture(scope="module")
def image_seeds(folder):
    _image_seeds.folder = folder
    return _image_seeds()


def _image_case(image_seeds, data):
    ext = data.draw(st.sampled_from(sorted(image_seeds)))
    blob = data.draw(mutated_bytes(image_seeds[ext], [b"\n", b" ", b"-Y", b"+X", b"99999", b"-1", b"\x00",
                                                      b"\xff\xff\xff\xff", b"\x80", b"\x02\x02"]))
    return ext, blob


@_settings(SHORT)
@given(data=st.data())
def test_mutated_environment_images_read_or_name_the_file(folder, image_seeds, data):
    ext, blob = _image_case(image_seeds, data)
    _outcome(_read_image, folder / f"env{ext}", blob, errors=(ValueError,), per_result=_image_bytes)


@_settings(LONG)
@given(data=st.data())
def test_mutated_environment_images_read_or_name_the_file_long(folder, image_seeds, data):
    ext, blob = _image_case(image_seeds, data)
    _outcome(_read_image, folder / f"env{ext}", blob, errors=(ValueError,), per_result=_image_bytes)


# ------------------------------------------------------------------------------------------- NanoVDB

@pytest.fixture(scope="module")
def grid_seeds(folder):
    import warp as wp

    a = np.zeros((8, 8, 8), np.float32)
    a[2:5, 2:5, 2:5] = 1.0
    out = []
    for codec in ("none", "zip"):
        wp.Volume.load_from_numpy(a, bg_value=0.0, device="cpu").save_to_nvdb(str(folder / f"{codec}.nvdb"),
                                                                               codec=codec)
        out.append((folder / f"{codec}.nvdb").read_bytes())
    return [*out, blosc_grid(out[0])]           # blosc: read through FakeBlosc (_read_grid)


def _read_grid(path: str):
    from unittest import mock

    from warp_spt.media.grid import load_grid
    from warp_spt.scene.media import Medium

    with mock.patch.dict(sys.modules, {"blosc": FakeBlosc()}):
        _, ijk, vals = load_grid(Medium(sigma_s=1.0, density=path), "cpu", "density")
    assert len(ijk) == len(vals) and np.isfinite(vals).all() and (vals >= 0).all()


@st.composite
def _grid_bytes(draw, seeds):
    data = bytearray(draw(st.sampled_from(seeds)))
    for _ in range(draw(st.integers(1, 4))):
        # most edits in the file header and the grid's metadata (sizes, codec, name), some anywhere
        at = draw(st.integers(0, 400) if draw(st.booleans()) else st.integers(0, len(data)))
        piece = draw(st.sampled_from([b"\x00" * 8, b"\xff" * 8, b"\x01\x00", b"\x02\x00"]) | st.binary(min_size=1,
                                                                                                   max_size=8))
        data[at:at + len(piece)] = piece
    return bytes(data)


@_settings(SHORT)
@given(data=st.data())
def test_mutated_nanovdb_grids_load_or_name_the_file(folder, grid_seeds, data):
    _outcome(_read_grid, folder / "grid.nvdb", data.draw(_grid_bytes(grid_seeds)))


@_settings(LONG)
@given(data=st.data())
def test_mutated_nanovdb_grids_load_or_name_the_file_long(folder, grid_seeds, data):
    _outcome(_read_grid, folder / "grid.nvdb", data.draw(_grid_bytes(grid_seeds)))


# ---------------------------------------------------------------------------------------- light files

LIGHTS = (b"# key and fill\nsun direction 0.4 -0.3 1 color 3 3 2.8 radius 0.27\n"
          b"point position 0 2 0 intensity 50\n"
          b"spot position 0 3 0 direction 0 -1 0 intensity 200 180 160 inner 15 outer 30 name key\n")
LIGHT_PIECES = [b" ", b"\n", b"-", b"1e40", b"-1e40", b"nan", b"inf", b"0", b"1e-320", b"90", b"91", b"sun ",
                b"point ", b"spot ", b"radius ", b"inner ", b"outer ", b"color ", b"direction ", b"\xff", b"\x00"]


def _read_lights(path: str):
    from warp_spt.io.light_file import load_lights

    return load_lights(path)


@st.composite
def _light_text(draw):
    return draw(mutated_bytes([LIGHTS], LIGHT_PIECES))


def _check_lights(folder, blob):
    lights = _outcome(_read_lights, folder / "key.lights", blob)
    for light in lights or ():
        assert all(np.isfinite(v).all() for v in vars(light).values() if isinstance(v, (float, tuple))
                   and all(isinstance(c, float) for c in np.ravel(v)))


@_settings(SHORT)
@given(blob=_light_text())
def test_mutated_light_files_load_or_name_file_and_line(folder, blob):
    _check_lights(folder, blob)


@_settings(LONG)
@given(blob=_light_text())
def test_mutated_light_files_load_or_name_file_and_line_long(folder, blob):
    _check_lights(folder, blob)


# ------------------------------------------------------------------------------- glTF and PLY scenes

EXTREMES = [0, -1, 1e-46, 1e-9, 0.5, 1, 2, 3.2, 90, 1e15, 1e20, 1e39, -1e39, "x", None, [], {}, [1, 2], True]


@st.composite
def _gltf_values(draw):
    """A glTF whose numbers (anywhere: lights, materials, cameras, nodes, accessors) are replaced by
    extremes, or by other types, a few at a time."""
    doc = json.loads(draw(st.sampled_from([gltf_camera_and_light, gltf_textured_box, gltf_animated]))().gltf()[0])
    leaves = []

    def walk(x, path):
        items = x.items() if isinstance(x, dict) else enumerate(x) if isinstance(x, list) else ()
        for k, v in items:
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                leaves.append(path + [k])
            elif k != "uri":
                walk(v, path + [k])

    walk(doc, [])
    for _ in range(draw(st.integers(1, 3))):
        where = draw(st.sampled_from(leaves))
        parent = doc
        for k in where[:-1]:
            parent = parent[k]
        parent[where[-1]] = draw(st.sampled_from(EXTREMES))
    return json.dumps(doc).encode()


def _load(path: str):
    from warp_spt.io.loader import load_scene

    return load_scene([path], warn=lambda message: None)


def _with(make, change) -> bytes:
    doc = json.loads(make().gltf()[0])
    change(doc)
    return json.dumps(doc).encode()


# what the long run found before the fixes: a light's intensity below 0 (a ValueError naming nothing)
# and a texture transform taking the coordinates past float32 ("<scene>: meshes[0] ... corner_uv")
NEGATIVE_LIGHT = _with(gltf_camera_and_light, lambda d: d["extensions"]["KHR_lights_punctual"]["lights"][0]
                       .update(intensity=-1))
FAR_UV = _with(gltf_textured_box, lambda d: d["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]
               ["extensions"]["KHR_texture_transform"].update(offset=[1e39, 0]))


@_settings(SHORT)
@given(blob=_gltf_values())
@example(blob=NEGATIVE_LIGHT)
@example(blob=FAR_UV)
def test_gltf_files_with_extreme_values_load_or_name_file_and_pointer(folder, blob):
    _outcome(_load, folder / "model.gltf", blob)


@_settings(LONG)
@given(blob=_gltf_values())
def test_gltf_files_with_extreme_values_load_or_name_file_and_pointer_long(folder, blob):
    _outcome(_load, folder / "model.gltf", blob)


PLY_SEEDS = [ply_bytes(f) for f in ("ascii", "binary_little_endian", "binary_big_endian")]
PLY_PIECES = [b" ", b"\n", b"-1", b"9", b"1e40", b"nan", b"\xff", b"\x00", b"element ", b"end_header\n"]


@_settings(SHORT)
@given(blob=mutated_bytes(PLY_SEEDS, PLY_PIECES))
def test_mutated_ply_scenes_load_or_name_the_file(folder, blob):
    _outcome(_load, folder / "model.ply", blob)


@_settings(LONG)
@given(blob=mutated_bytes(PLY_SEEDS, PLY_PIECES))
def test_mutated_ply_scenes_load_or_name_the_file_long(folder, blob):
    _outcome(_load, folder / "model.ply", blob)
