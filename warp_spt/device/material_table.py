"""The material table on the device: the ``Materials`` struct, built from the material schema.

One array field per column of ``warp_spt.scene.material_schema.COLUMNS``, in its order and with its
name, so a column added to the schema reaches every kernel (and the gradient kernels' aliases,
:func:`with_gradients`) without an edit here. The struct keeps the name and field order the
hand-written struct had: its generated code, and so the kernels and their images, are unchanged.
"""

from __future__ import annotations

from typing import Callable

import numpy as np
import warp as wp

from warp_spt.scene.material_schema import (
    COLOR,
    COLUMNS,
    FLAG,
    INDEX,
    NUM_SLOTS,
    SCALAR,
    SLOTS,
    Column,
)

_SLOTS_TYPE = wp.vec4i if NUM_SLOTS == 4 else wp.types.vector(length=NUM_SLOTS, dtype=wp.int32)


def device_dtype(c: Column):
    """The Warp dtype of a column's device array (a flag is an int32 0/1: Warp arrays hold no bool)."""
    return {COLOR: wp.vec3, SCALAR: wp.float32, FLAG: wp.int32, INDEX: wp.int32, SLOTS: _SLOTS_TYPE}[c.type]


def _materials_struct():
    """``@wp.struct class Materials`` with one ``wp.array`` per schema column."""
    cls = type("Materials", (), {
        "__module__": __name__,
        "__doc__": "The material table (structure of arrays, one row per material; see scene.MaterialTable).",
        "__annotations__": {c.name: wp.array(dtype=device_dtype(c)) for c in COLUMNS},
    })
    return wp.struct(cls)


Materials = _materials_struct()


def upload_materials(table, device: str) -> Materials:
    """The host ``MaterialTable`` as a :data:`Materials` struct on ``device``."""
    m = Materials()
    for c in COLUMNS:
        dtype = device_dtype(c)
        np_dtype = np.float32 if dtype in (wp.vec3, wp.float32) else np.int32
        data = np.ascontiguousarray(np.asarray(getattr(table, c.name), dtype=np_dtype))
        setattr(m, c.name, wp.array(data, dtype=dtype, device=device))
    return m


def with_gradients(m: Materials, alias: Callable[[wp.array], wp.array]) -> Materials:
    """A copy of ``m`` whose differentiable columns are ``alias(array)`` (arrays carrying a gradient
    buffer, ``warp_spt.diff.gradients``); the other columns are shared."""
    out = Materials()
    for c in COLUMNS:
        a = getattr(m, c.name)
        setattr(out, c.name, alias(a) if c.differentiable else a)
    return out

