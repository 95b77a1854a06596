"""USD stages (``.usd``, ``.usda``, ``.usdc``, ``.usdz``) read through Pixar's ``usd-core`` (the optional
extra ``pip install ".[usd]"``: the only well-kept reader of the format) into an :class:`ObjData`,
as glTF files are: meshes (subsets, face-varying normals and texture coordinates, orientation,
holes, n-gons fanned), implicit shapes (spheres exact where they can be, cubes, capsules,
cylinders, cones as polygons), Xform hierarchies, native and PointInstancer instances kept as TLAS
instances, UsdPreviewSurface materials (displayColor where none is bound), UsdLux lights, cameras,
the up axis and metres per unit, purposes, and time samples (``time``: seconds since the stage's
start time code, at its timeCodesPerSecond). See ``stage.py`` for the walk, ``meshes.py``,
``materials.py``, ``lights_cameras.py``, ``shapes.py`` and ``assets.py`` for the rest;
docs/formats.md says what is read and what is not.

Errors are :class:`SceneError` naming the file (line 0) and the prim path."""

from __future__ import annotations

import os

from warp_spt.scene.errors import SceneError
from warp_spt.scene.model import ObjData

__all__ = ["load_usd", "USD_SUFFIXES"]

USD_SUFFIXES = (".usd", ".usda", ".usdc", ".usdz")


def load_usd(path: str | os.PathLike[str], time: float | None = None) -> ObjData:
    """Read a USD stage; ``time`` (seconds from its start) poses it (None: its start or its defaults)."""
    from warp_spt.io.tokens import file_problem

    path = str(path)
    try:
        from pxr import Tf, Usd
    except ImportError:
        raise SceneError(path, 0, 'reading USD needs Pixar\'s usd-core: pip install ".[usd]" (or pip install '
                         'usd-core)') from None
    problem = file_problem(path)
    if problem is not None:
        raise SceneError(path, 0, f"cannot read the stage: {problem}")
    try:
        stage = Usd.Stage.Open(path, Usd.Stage.LoadAll)
    except Tf.ErrorException as err:
        first = str(err).strip().splitlines()
        raise SceneError(path, 0, f"not a USD stage USD can open: {first[-1] if first else err}"[:400]) from None
    if stage is None:
        raise SceneError(path, 0, "not a USD stage USD can open")
    from warp_spt.usd.stage import Reader

    try:
        return Reader(stage, path, time).run()
    except Tf.ErrorException as err:
        raise SceneError(path, 0, f"USD: {str(err).strip()[:400]}") from None
