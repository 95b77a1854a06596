"""Fuzzing the PLY and glTF readers: mutated headers, counts, offsets, strides and JSON types give
either valid data or a SceneError, and never allocate far beyond the input's size (tracemalloc peak)."""

from __future__ import annotations

import json
import tracemalloc

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from tests.support.format_files import (
    gltf_animated,
    gltf_camera_and_light,
    gltf_morph,
    gltf_skinned_bar,
    gltf_sparse,
    gltf_textured_box,
    gltf_two_instances,
    ply_bytes,
)
from warp_spt.io.gltf import parse_gltf_bytes
from warp_spt.io.ply import parse_ply_bytes
from warp_spt.scene.errors import SceneError

SETTINGS = settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.too_slow])
# The readers may copy the input a few times and make per-triangle arrays; a forged count must not
# make them allocate for it. 16 MiB covers numpy's and the texture baker's fixed costs.
MEMORY_BOUND = 16 << 20
BIG = [0, 1, 2, 3, 4, 5, 7, 8, 12, 255, 256, 65535, 2**31 - 1, 2**31, 2**32 - 1, 2**32, 2**53, 10**18, -1, -2**31]


def _bounded(parse, data: bytes, path: str):
    tracemalloc.start()
    try:
        try:
            d = parse(data, path)
        except SceneError as err:
            assert str(err).startswith(path)
            d = None
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert peak < MEMORY_BOUND + 50 * len(data), peak
    if d is not None:
        assert d.faces.dtype == np.int32 and (d.faces < len(d.positions)).all() and (d.faces >= 0).all()
        assert np.isfinite(d.positions).all()
    return d


PLY_SEEDS = [ply_bytes(f, colours=c) for f in ("ascii", "binary_little_endian", "binary_big_endian")
             for c in (True, False)]
PLY_PIECES = [b" ", b"\n", b"-1", b"0", b"9", b"255", b"4294967295", b"nan", b"1e40", b"element ", b"property ",
              b"list ", b"uchar ", b"int ", b"float ", b"double ", b"face ", b"vertex ", b"tristrips ", b"\xff",
              b"\x00", b"\x7f\xff\xff\xff", b"end_header\n"]


@st.composite
def mutated_bytes(draw, seeds: list[bytes], pieces: list[bytes]) -> bytes:
    data = bytearray(draw(st.sampled_from(seeds)))
    body = bytes(data).find(b"end_header") + 11
    for _ in range(draw(st.integers(1, 5))):
        # most edits in the data after the header (binary counts, indices, values), some anywhere
        at = draw(st.integers(body if draw(st.integers(0, 3)) and 0 < body < len(data) else 0, len(data)))
        kind = draw(st.sampled_from(["insert", "delete", "replace", "count"]))
        piece = draw(st.sampled_from(pieces) | st.binary(min_size=1, max_size=4))
        if kind == "insert":
            data[at:at] = piece
        elif kind == "delete":
            data[at:at + draw(st.integers(1, 8))] = b""
        elif kind == "replace":
            data[at:at + len(piece)] = piece
        else:       # a header count forged: the number after "element NAME "
            text = bytes(data)
            k = text.find(b"element ", at % max(1, text.find(b"end_header") + 1))
            if k >= 0:
                end = text.find(b"\n", k)
                words = text[k:end].split(b" ")
                if len(words) == 3:
                    words[2] = str(draw(st.sampled_from(BIG))).encode()
                    data[k:end] = b" ".join(words)
    return bytes(data)


@SETTINGS
@given(mutated_bytes(PLY_SEEDS, PLY_PIECES))
def test_mutated_ply_is_data_or_a_scene_error_in_bounded_memory(data):
    _bounded(parse_ply_bytes, data, "fuzz.ply")


def _docs():
    out = []
    for make in (gltf_two_instances, gltf_sparse, gltf_textured_box, gltf_camera_and_light, gltf_animated,
                 lambda: gltf_animated("CUBICSPLINE"), gltf_skinned_bar, gltf_morph):
        g = make()
        out.append((g.gltf()[0], g.glb()))
    return out


GLTF_SEEDS = _docs()
JSON_VALUES = st.one_of(st.sampled_from(BIG), st.none(), st.booleans(), st.text(max_size=5),
                        st.floats(allow_nan=True), st.lists(st.integers(-3, 300), max_size=4),
                        st.dictionaries(st.sampled_from(["bufferView", "count", "byteOffset"]), st.integers(-1, 99)))


def _paths(doc, prefix=()):
    """Every (container, key) in a JSON document, depth first."""
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else []
    for k, v in items:
        yield doc, k
        yield from _paths(v, prefix + (k,))


@st.composite
def mutated_gltf(draw) -> tuple[bytes, bool]:
    text, glb = draw(st.sampled_from(GLTF_SEEDS))
    as_glb = draw(st.booleans())
    doc = json.loads(text)
    places = list(_paths(doc))
    for _ in range(draw(st.integers(1, 4))):
        container, key = draw(st.sampled_from(places))
        action = draw(st.sampled_from(["value", "delete", "number"]))
        if action == "delete" and isinstance(container, dict):
            container.pop(key, None)
        elif action == "number":
            container[key] = draw(st.sampled_from(BIG))
        else:
            container[key] = draw(JSON_VALUES)
        places = list(_paths(doc))
        if not places:
            break
    data = json.dumps(doc).encode()
    if as_glb:
        # the same document with the original binary chunk (a fresh GLB, so the header stays consistent)
        bin_start = glb.index(b"BIN\x00") - 4
        body = data + b" " * (-len(data) % 4)
        chunk = len(body).to_bytes(4, "little") + b"JSON" + body + glb[bin_start:]
        data = b"glTF" + (2).to_bytes(4, "little") + (12 + len(chunk)).to_bytes(4, "little") + chunk
    return data, as_glb


@SETTINGS
@given(mutated_gltf())
def test_mutated_gltf_is_data_or_a_scene_error_in_bounded_memory(case):
    data, glb = case
    # posed at a time inside the animated seeds' range (the others ignore it)
    _bounded(lambda b, p: parse_gltf_bytes(b, p, time=0.7), data, "fuzz.glb" if glb else "fuzz.gltf")


@SETTINGS
@given(mutated_bytes([g for _, g in GLTF_SEEDS], [b"\x00", b"\xff\xff\xff\xff", b"glTF", b"JSON", b"BIN\x00"]))
def test_mutated_glb_bytes_are_data_or_a_scene_error(data):
    _bounded(parse_gltf_bytes, data, "fuzz.glb")
