"""The material schema: one row per column of the material table, the one home of every material field.

A :class:`Column` says what a field is (an RGB colour, a scalar, a flag, an index), its seed default,
its valid range, its texture slot (colours that a ``map_*`` statement may replace), whether gradients
reach it and its meaning. Everything else is derived from :data:`COLUMNS`, in its order:

* ``warp_spt.scene.model``: the host :class:`Material` (fields and defaults) and :class:`MaterialTable`
  (one array per column), and the table's assembly from Materials (loader, studio);
* ``warp_spt.scene.validate``: dtype, shape and range checks of the table;
* ``warp_spt.device.material_table``: the device struct ``Materials``, its upload and its gradient aliases;
* ``warp_spt.diff.params`` and ``warp_spt.diff.optim``: parameter names, shapes, ranges and bounds.

So adding a material field is one line here (then a material kind reads it in its kernel functions,
``warp_spt.bsdfs``). The order is the device struct's field order, which is in the kernels'
generated code: append new columns at the end.

``MATERIAL_KINDS`` names the material models (``warp_spt.bsdfs.<name>``), in the order of
their index in the ``kind`` column. Nothing here imports Warp.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from warp_spt.scene.limits import MAX_IOR, MAX_RADIANCE, MIN_IOR

# Column types: what a row holds, on the host and on the device (warp_spt.device.material_table)
COLOR = "color"      # RGB: host (M, 3) float32, device vec3; Material: a tuple of 3 floats
SCALAR = "scalar"    # host (M,) float32, device float32; Material: a float
FLAG = "flag"        # host (M,) bool, device int32 (0/1); Material: a bool
INDEX = "index"      # host (M,) int32, device int32; Material: an int
SLOTS = "slots"      # host (M, NUM_SLOTS) int32, device vec4i: the texture of each slot (model.TEX_*)

# The material models, by index in the ``kind`` column: each is the module
# warp_spt.bsdfs.<name> (a new kind: that module and its name here). ``seed`` is the seed's
# model (its dialect, the built-in demo, the studio's clay); ``pbr`` the physically based one
# (glTF metallic-roughness and its extensions; standard MTL files).
MATERIAL_KINDS: tuple[str, ...] = ("seed", "pbr")
KIND_SEED, KIND_PBR = (MATERIAL_KINDS.index(n) for n in ("seed", "pbr"))


@dataclass(frozen=True)
class Column:
    """One field of the material table.

    ``low``/``high``: the valid range (None: unbounded on that side), checked by ``validate_scene``
    and by ``SceneParameters``, and the optimiser's bounds. ``slot``: for a colour, its column in the
    texture-slot table (``Material.<name>_map`` names the texture that replaces the colour);
    ``checker``: the built-in checker pattern fills that slot of a ``Material.checker`` material.
    ``differentiable``: a named parameter (``"<material>.<name>"``) that gradients reach;
    ``pathwise``: its derivative bends sampled directions, so only the tape takes it (not path replay).
    ``channel``: for a scalar with a texture slot, the texel channel its map is read from (glTF packs
    roughness in G and metallic in B of one texture; a grey map gives the same value in every channel);
    ``srgb``: a colour whose map is decoded from sRGB in standard files (data maps stay linear; the
    seed's dialect keeps its raw mapping, SEMANTICS Q18). ``kinds``: the material kinds that read the
    column (empty: every kind).
    """

    name: str
    type: str
    default: object = None
    low: float | None = None
    high: float | None = None
    doc: str = ""
    slot: int | None = None
    checker: bool = False
    differentiable: bool = False
    pathwise: bool = False
    channel: int | None = None
    srgb: bool = False
    kinds: tuple[str, ...] = ()


# The seed's defaults (SEMANTICS §6): its MTL colours are bytes / 256.
COLUMNS: tuple[Column, ...] = (
    Column("diffuse", COLOR, (0x9F / 256, 0x8F / 256, 0x7C / 256), 0.0, 1.0, "diffuse colour (Kd)",
           slot=0, checker=True, differentiable=True, srgb=True, kinds=("seed",)),
    Column("reflect", COLOR, (0xAF / 256, 0xBF / 256, 0xCF / 256), 0.0, 1.0, "mirror colour (Kr, Ks)",
           slot=1, checker=True, differentiable=True, srgb=True, kinds=("seed",)),
    Column("refract", COLOR, (0xBB / 256, 0xBC / 256, 0xB1 / 256), 0.0, 1.0, "transmission colour of glass (Kt, Tf)",
           slot=2, differentiable=True, srgb=True, kinds=("seed",)),
    Column("emission", COLOR, (0.0, 0.0, 0.0), 0.0, MAX_RADIANCE, "emitted radiance, both faces (Kl, Ke)",
           slot=3, differentiable=True, srgb=True),
    Column("tex", SLOTS, None, None, None, "texture of each slot: TEX_NONE, TEX_CHECKER, a texture or a "
           "procedural instance (from the colours' maps and Material.checker)"),
    Column("roughness", SCALAR, 0.85, 0.0, 1.0, "seed: probability of the diffuse lobe (the seed's "
           "diffuseWeight); pbr: perceptual roughness (alpha = roughness^2; glTF roughnessFactor, MTL Pr)",
           differentiable=True, slot=6, channel=1),
    Column("fuzz", SCALAR, 0.62, 0.0, None, "length of the mirror's random perturbation (1 - reflectClearness)",
           differentiable=True, pathwise=True, kinds=("seed",)),
    Column("ior", SCALAR, 1.0, MIN_IOR, MAX_IOR, "index of refraction (Kn, Ni)", differentiable=True,
           pathwise=True),
    Column("refractable", FLAG, False, None, None, "the specular lobe may refract: glass", kinds=("seed",)),
    Column("kind", INDEX, 0, 0, len(MATERIAL_KINDS) - 1, "the material model: an index into MATERIAL_KINDS"),
    # The pbr kind's own columns (glTF 2.0 metallic-roughness and KHR_materials_*; docs/materials.md).
    Column("base_color", COLOR, (0.8, 0.8, 0.8), 0.0, 1.0, "base colour (glTF baseColorFactor, MTL Kd)",
           slot=4, differentiable=True, srgb=True, kinds=("pbr",)),
    Column("metallic", SCALAR, 0.0, 0.0, 1.0, "metalness: 1 a conductor whose F0 is the base colour (Pm)",
           slot=5, channel=2, differentiable=True, kinds=("pbr",)),
    Column("anisotropy", SCALAR, 0.0, 0.0, 1.0, "KHR_materials_anisotropy strength: alpha along the "
           "tangent becomes mix(alpha, 1, anisotropy^2) (MTL aniso)", differentiable=True, kinds=("pbr",)),
    Column("anisotropy_rotation", SCALAR, 0.0, -1000.0, 1000.0, "rotation of the anisotropy direction from "
           "the tangent (the uv's u direction), radians (MTL anisor x 2 pi)", kinds=("pbr",)),
    Column("specular", SCALAR, 1.0, 0.0, 1.0, "KHR_materials_specular specularFactor: scales the dielectric "
           "reflection's F0", kinds=("pbr",)),
    Column("specular_color", COLOR, (1.0, 1.0, 1.0), 0.0, 1000.0, "KHR_materials_specular specularColorFactor "
           "(MTL Ks); F0 = min(((ior - 1) / (ior + 1))^2 x colour, 1) x specular", kinds=("pbr",)),
    Column("transmission", SCALAR, 0.0, 0.0, 1.0, "KHR_materials_transmission: share of the dielectric base "
           "that refracts instead of scattering diffusely (MTL Tr, 1 - d, illum 4/6/7)",
           differentiable=True, kinds=("pbr",)),
    Column("thin", FLAG, False, None, None, "thin-walled: transmitted light leaves on the other side "
           "unbent (a sheet, not a solid)", kinds=("pbr",)),
    Column("normal", SCALAR, 1.0, 0.0, 10.0, "normal-map strength (glTF normalTexture.scale; the map is "
           "normal_map, tangent space)", slot=7, kinds=("pbr",)),
    Column("bump", SCALAR, 1.0, -1000.0, 1000.0, "bump-map multiplier (MTL -bm; the height map is bump_map, "
           "in uv units)", slot=8, channel=0, kinds=("pbr",)),
    Column("opacity", SCALAR, 1.0, 0.0, 1.0, "coverage: below alpha_cutoff the surface is a hole (a cut-out, "
           "for every kind: glTF alpha, MTL map_d)", slot=9, channel=0),
    Column("alpha_cutoff", SCALAR, 0.5, 0.0, 1.0, "opacity below which the surface is a hole"),
    Column("multiscatter", FLAG, True, None, None, "compensate the GGX reflection lobes' single-scattering "
           "energy loss (Turquin 2019); off: the bare single-scattering lobes, as most real-time viewers draw "
           "them", kinds=("pbr",)),
    Column("clearcoat", SCALAR, 0.0, 0.0, 1.0, "KHR_materials_clearcoat clearcoatFactor: a GGX coat of ior 1.5 "
           "over the rest, mixed in by clearcoat x Schlick's Fresnel at the view angle", kinds=("pbr",)),
    Column("clearcoat_roughness", SCALAR, 0.0, 0.0, 1.0, "KHR_materials_clearcoat clearcoatRoughnessFactor: the "
           "coat's perceptual roughness", kinds=("pbr",)),
    Column("clearcoat_normal", SCALAR, 1.0, 0.0, 10.0, "KHR_materials_clearcoat clearcoatNormalTexture.scale: "
           "the coat's normal-map strength (the map is clearcoat_normal_map, tangent space, about the "
           "interpolated normal; without it the coat follows the interpolated normal, not the base's map)",
           slot=10, kinds=("pbr",)),
    Column("sheen_color", COLOR, (0.0, 0.0, 0.0), 0.0, 1.0, "KHR_materials_sheen sheenColorFactor: a Charlie "
           "sheen lobe over the base, which is scaled by 1 - max(colour) x the lobe's albedo at the view angle",
           kinds=("pbr",)),
    Column("sheen_roughness", SCALAR, 0.0, 0.0, 1.0, "KHR_materials_sheen sheenRoughnessFactor: the sheen's "
           "perceptual roughness (held at or above 0.07)", kinds=("pbr",)),
)

COLUMN = {c.name: c for c in COLUMNS}
NORMAL_MAPS = ("normal", "clearcoat_normal")      # the scalars whose maps are tangent-space normal maps
SLOT_COLUMNS: tuple[Column, ...] = tuple(sorted((c for c in COLUMNS if c.slot is not None), key=lambda c: c.slot))
NUM_SLOTS = len(SLOT_COLUMNS)
DIFFERENTIABLE: tuple[Column, ...] = tuple(c for c in COLUMNS if c.differentiable)


def host_dtype(c: Column) -> str:
    """The numpy dtype of the column's host array."""
    return {COLOR: "float32", SCALAR: "float32", FLAG: "bool", INDEX: "int32", SLOTS: "int32"}[c.type]


def row_shape(c: Column) -> tuple[int, ...]:
    """The shape of one row of the column: (3,) for colours, (NUM_SLOTS,) for slots, () otherwise."""
    return {COLOR: (3,), SLOTS: (NUM_SLOTS,)}.get(c.type, ())


def range_text(c: Column) -> str:
    """The valid range as the error messages spell it: "lie in [0, 1]" or "be >= 0"."""
    if c.high is None:
        return f"be >= {c.low:g}"
    return f"lie in [{c.low:g}, {c.high:g}]"


def read_by(c: Column, kind: str) -> bool:
    """Whether material kind ``kind`` reads column ``c`` (a column that names no kinds: every kind):
    what an MTL ``set`` line is checked against (``warp_spt.io.mtl``)."""
    return not c.kinds or kind in c.kinds


def settable(kind: str | None = None) -> dict[str, tuple[Column, bool]]:
    """The fields a scene file may set by name (MTL ``set``), in the schema's order: {field: (its
    column, whether it is the column's texture map)}: every colour, scalar and flag that material
    kind ``kind`` reads (None: any kind) and ``<name>_map`` for those with a texture slot."""
    out: dict[str, tuple[Column, bool]] = {}
    for c in COLUMNS:
        if c.type in (COLOR, SCALAR, FLAG) and (kind is None or read_by(c, kind)):
            out[c.name] = (c, False)
            if c.slot is not None:
                out[c.name + "_map"] = (c, True)
    return out


def _check_schema() -> None:
    """Slots number 0..NUM_SLOTS-1 once each and belong to colours; names are unique."""
    assert len(COLUMN) == len(COLUMNS), "duplicate column names"
    assert [c.slot for c in SLOT_COLUMNS] == list(range(NUM_SLOTS)), "slots must be 0..n-1"
    assert all(c.type == COLOR or (c.type == SCALAR and c.channel is not None) or c.name in NORMAL_MAPS
               for c in SLOT_COLUMNS), "texture slots belong to colours and to scalars that name their channel"
    assert all(set(c.kinds) <= set(MATERIAL_KINDS) for c in COLUMNS), "columns name registered kinds"
    assert sum(c.type == SLOTS for c in COLUMNS) == 1, "one slots column"


_check_schema()


def material_problem(m) -> str | None:
    """Why one Material's values lie outside the schema's ranges (the field and its range), or None:
    what a reader checks while it still knows the file and the place (the table check below names
    only the column)."""
    for c in COLUMNS:
        if c.type == SLOTS or (c.low is None and c.high is None):
            continue
        a = np.asarray(getattr(m, c.name), dtype=host_dtype(c))      # as the table holds it: float32
        if not ((c.low is None or (a >= c.low).all()) and (c.high is None or (a <= c.high).all())):
            return f"{c.name} must {range_text(c)}, got {' '.join(f'{v:g}' for v in np.ravel(a))}"
    return None
