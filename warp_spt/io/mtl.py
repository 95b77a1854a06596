"""MTL material libraries read into the seed's material model (:class:`Material`, SEMANTICS §6).

Seed tags (tag names are matched case-insensitively; colours take 3 numbers, or 1 for a grey):

========================  ==============================================================
``newmtl NAME``           a new material with the seed's MTL defaults; a later definition
                          of the same name replaces an earlier one
``Kd`` / ``map_Kd``       diffuse AND reflect colour / texture
``Kr`` / ``map_Kr``       reflect colour / texture only
``Kt`` / ``map_Kt``       refract (transmission) colour / texture (the seed ignored map_Kt)
``Kl`` / ``map_Kl``       emission colour / texture
``Roughness a``           probability of the diffuse bounce, in [0, 1]
``Fuzz a``                length of the reflection's random perturbation, >= 0
``Kn a``                  index of refraction, > 0
``Refractable``           the specular lobe may refract
========================  ==============================================================

A constant and a texture of the same slot replace each other: the later line wins (the seed
kept one texture object per slot).

A file that uses any of the seed's own tags (``Kr``, ``Kt``, ``Kl``, their maps, ``Roughness``,
``Fuzz``, ``Kn``, ``Refractable``) is in the seed's dialect: its materials are of the seed's kind and
keep the seed's defaults (a 15% fuzzy specular lobe) and its raw texture mapping (SEMANTICS Q18). The
standard tags it may also use map onto the seed's model as they always did:

* ``Ke`` / ``map_Ke``: emission (as ``Kl``); ``Ks`` / ``map_Ks``: reflect colour (as ``Kr``);
  ``Tf``: refract colour (as ``Kt``); ``Ni``: index of refraction (as ``Kn``).
* ``d a`` (opacity) and ``Tr t`` (= ``d 1-t``): when the opacity is below 1 the material becomes
  refractable and its diffuse probability is at most the opacity (``d 0`` is clear glass).
* ``illum 3`` or ``5``: a mirror, roughness 0 and fuzz 0; ``illum 4``, ``6`` or ``7``: glass.
* The values derived from ``d``/``Tr``/``illum`` never override an explicit ``Roughness``,
  ``Fuzz`` or ``Refractable`` of the same material, wherever the lines stand.
* ``Ks`` with ``Ns``: the specular probability max(Ks) / (max(Kd) + max(Ks)), the blur
  ``Fuzz = min(1, sqrt(5 / (Ns + 2)))``; ``Pm``/``Pr``: specular probability Pm + 0.04 (1 - Pm),
  ``Fuzz = Pr``.

Every other file is **standard**: its materials are of the physically based kind ``pbr``
(``warp_spt.bsdfs.pbr``; docs/materials.md), colour maps decoded from sRGB, data maps linear:

* ``Kd`` / ``map_Kd``: base colour; ``Ke`` / ``map_Ke``: emission.
* ``Pm`` / ``map_Pm``: metallic; ``Pr`` / ``map_Pr``: roughness (perceptual, alpha = Pr^2). Without
  ``Pr``, the Phong exponent gives it: alpha = sqrt(2 / (Ns + 2)) (Walter et al. 2007's Phong-Beckmann
  correspondence, which GGX shares near the peak), roughness = sqrt(alpha); without either, roughness 1.
* ``Ks``: Blender's "Specular" (0.5 is a 4% reflection at normal incidence): specular colour = 2 Ks,
  so F0 = ((Ni - 1)/(Ni + 1))^2 x 2 Ks. ``Ni``: the IOR (1.5 when absent).
* A pure Lambertian surface (no specular layer at all, not even Schlick's grazing reflection of an
  F0 of 0): ``illum 0`` or ``1`` (colour on, no highlight), or a material without ``Ks`` (MTL's
  default Ks is 0) or with ``Ks 0``, unless ``illum`` 3-7 or the PBR extension's ``Pr``/``Pm``
  ask for a reflection.
* ``illum 3`` or ``5`` (ray-traced reflection): a metal (metallic 1, base colour Ks if given, else Kd);
  with ``illum`` 3 to 7 the roughness is 0 unless ``Pr`` or ``Ns`` say otherwise.
* ``d a`` / ``Tr t`` (= ``d 1-t``): transmission 1 - d (glass, tinted by ``Tf`` where given);
  ``illum 4``, ``6`` or ``7``: transmission 1 unless ``d`` says otherwise.
* ``map_d``: cut-out (the map's alpha channel, else its grey value, is the opacity; below 0.5 a hole).
* ``norm``: a tangent-space normal map (``-bm`` its strength); ``bump`` / ``map_Bump``: a bump map
  (height, ``-bm`` its multiplier).
* ``aniso a`` / ``anisor r``: anisotropy strength and its rotation (a fraction of a turn).
* ``Ps``/``Pc``/``Pcr`` and ``map_Ks`` are not read (sheen and clearcoat are ``set`` lines): reported once per file.

* Texture statements may carry options (``-s 1 1 1``, ``-clamp on``...); ``-bm`` is read for bump
  and normal maps, the others are skipped. ``Ka`` (ambient: a path tracer computes the ambient light)
  is ignored silently; every other tag is ignored and reported, as are lines before the first
  ``newmtl``. :func:`load_mtl` reports once per file, through ``warn``, the tags and texture
  options it read but does not support.

``map_* proc:NAME key=value ...`` names a procedural texture instead of a file (syntax and
built-ins: :mod:`warp_spt.device.proctex`; read against the textures' Warp-free declarations,
:mod:`warp_spt.scene.proctex_registry`); an unknown name or key is a SceneError with file and line.

A material may name its kind and set any field of it by the material schema's names
(:mod:`warp_spt.scene.material_schema`; docs/materials.md, "Naming the kind in MTL"), so a new kind
needs no edit here:

* ``kind NAME`` (right after ``newmtl``): any name of ``MATERIAL_KINDS``. ``seed`` and ``pbr`` read
  the other tags as the seed's and the standard dialect do, whatever the file's dialect (tags the
  kind has no field for are reported); any other kind starts from the columns' defaults and reads
  ``set`` lines only (and ``medium_*``, ``index_matched``). Its tags leave the file's dialect alone.
* ``set FIELD VALUE...``: a colour (1 or 3 numbers), scalar (1 number) or flag (``on``/``off``)
  column that the material's kind reads, checked against the column's range, or ``FIELD_map`` (a
  texture statement, ``proc:`` included) for a column with a texture slot. It writes that one field,
  over what the tags derive, wherever it stands; without ``kind`` the file's dialect gives the kind.

Texture paths are recorded with their file and line (:class:`TextureRef`); they are resolved and
read later, by :func:`warp_spt.io.loader.load_scene`, and only for materials that geometry uses.
Bad values (a non-number, NaN, a reflectance colour outside [0, 1], an emission above 1e30, a
roughness outside [0, 1], an IOR outside [0.001, 1000], an opacity outside [0, 1], an anisotropy
outside [0, 1]) raise :class:`SceneError` with the file and line.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field, replace
from typing import Callable

import numpy as np

from warp_spt.io.paths import confine
from warp_spt.io.tokens import (
    decode_name,
    iter_lines,
    normalise_text,
    parse_floats,
    parse_int,
    read_file,
)
from warp_spt.scene import material_schema as schema
from warp_spt.scene.errors import SceneError
from warp_spt.scene.media import KEYS as MEDIUM_KEYS, MAX_G, MAX_MAJORANT, MAX_SIGMA, Medium
from warp_spt.scene.material_schema import COLOR, COLUMN, FLAG, Column
from warp_spt.scene.model import CHECKER_NAME, PBR_DEFAULTS, Material, TextureRef
from warp_spt.scene.proctex_registry import parse_proc_map

# Texture options and how many values follow them; (1, 3) means one to three numbers.
_TEX_OPTIONS = {
    "-blendu": 1, "-blendv": 1, "-bm": 1, "-boost": 1, "-cc": 1, "-clamp": 1, "-imfchan": 1,
    "-mm": 2, "-texres": 1, "-type": 1, "-o": (1, 3), "-s": (1, 3), "-t": (1, 3),
}
_COLOUR_SLOTS = {"kd": ("diffuse", "reflect"), "kr": ("reflect",), "ks": ("reflect",), "kt": ("refract",),
                 "tf": ("refract",), "kl": ("emission",), "ke": ("emission",)}
_MAP_SLOTS = {"map_kd": ("diffuse", "reflect"), "map_kr": ("reflect",), "map_ks": ("reflect",),
              "map_kt": ("refract",), "map_kl": ("emission",), "map_ke": ("emission",)}
# Tags only the seed's dialect has: a file using any of them keeps the seed's material defaults.
SEED_TAGS = frozenset({"kr", "map_kr", "kt", "map_kt", "kl", "map_kl", "roughness", "fuzz", "kn", "refractable"})
# Maps of standard files only (the pbr kind's data maps): tag -> the pbr column whose map it is.
_PBR_MAPS = {"map_pr": "roughness", "map_pm": "metallic", "map_d": "opacity", "norm": "normal",
             "bump": "bump", "map_bump": "bump"}
# Tags of standard files the pbr kind does not model (yet): reported once per file.
_UNMODELLED = {"ps": "sheen", "pc": "clearcoat", "pcr": "clearcoat roughness", "map_ps": "sheen",
               "map_pc": "clearcoat", "map_ks": "specular colour map"}
# The classic tags a kind's reading leaves out, in a material whose ``kind`` line names it (reported as
# ignored; a file's dialect reports its own once per file, in parse_mtl_bytes). Kinds not named here
# have no reading of the classic tags: they read ``set`` lines only (and what every kind reads, _kind_reads).
_UNREAD = {"seed": frozenset(_PBR_MAPS) | {"aniso", "anisor"}, "pbr": SEED_TAGS | {"map_ks"}}
_FLAG_WORDS = {"on": True, "off": False, "true": True, "false": False, "1": True, "0": False}


def builtin_checker() -> Material:
    """The built-in ``Inner_CheckerTexture``: checker diffuse and reflect, diffuse probability 0.75."""
    return Material(name=CHECKER_NAME, roughness=0.75, fuzz=0.62, ior=1.0, checker=True)


def builtin_clay() -> Material:
    """The default material of bare models: a neutral grey, purely diffuse clay (row 0's name kept)."""
    grey = (0.6, 0.6, 0.6)
    return Material(name=CHECKER_NAME, diffuse=grey, reflect=grey, roughness=1.0, fuzz=0.0, ior=1.0)


@dataclass
class _Draft:
    """A material being read, with what the standard tags ask for until it is finished."""

    mat: Material
    explicit: set[str] = field(default_factory=set)   # fields set by seed tags
    opacity: float = 1.0
    illum: int = -1
    phong: dict[str, float] = field(default_factory=dict)   # ks, ns, pr, pm as read
    ks: tuple[float, float, float] | None = None           # the Ks colour as read
    tf: tuple[float, float, float] | None = None           # the Tf colour as read
    pbr: dict[str, object] = field(default_factory=dict)   # pbr-only values and maps (standard files)
    medium: dict[str, object] = field(default_factory=dict)  # the interior medium's medium_* values
    index_matched: bool = False                             # ``index_matched``: a pass-through surface
    kind: str | None = None          # the kind its ``kind`` line names; None: the file's dialect decides
    statements: int = 0              # lines read since ``newmtl`` (a ``kind`` line must come first)
    sets: list[tuple[str, object, Column, int]] = field(default_factory=list)   # ``set``: field, value, line

    def finish(self, seed_dialect: bool) -> Material:
        """The material as read; ``seed_dialect``: its file uses the seed's own tags (module docs)."""
        kind = self.kind or ("seed" if seed_dialect else "pbr")
        if kind == "pbr":
            m = self._pbr_material()
        elif kind == "seed":
            m = self._seed_material()
        else:           # no reading of the classic tags: the columns' defaults, then its set lines
            m = replace(self.mat, kind=schema.MATERIAL_KINDS.index(kind))
        if self.kind is not None:       # the file's conventions (Scene.seed_dialect), whatever kind it names
            m = replace(m, seed_dialect=seed_dialect)
        return self._with_sets(m, kind)

    def _with_sets(self, m: Material, kind: str) -> Material:
        """``m`` with its ``set`` lines, which win over what the classic tags derive, wherever they
        stand; checked against the kind here, where it is known (a file's dialect: only at its end)."""
        for key, _, column, lineno in self.sets:
            if not schema.read_by(column, kind):
                raise SceneError(m.source, lineno, f"expected a field of material kind {kind!r} after 'set' "
                                 f"({', '.join(schema.settable(kind))}), got {key!r} (material {m.name!r})")
        return replace(m, **{key: value for key, value, _, _ in self.sets})

    def _seed_material(self) -> Material:
        """A material of the seed's kind from the classic tags (module docs: the mapping)."""
        derived = self._phong_and_pbr()
        derived["seed_dialect"] = True
        if self.illum in (3, 5, 4, 6, 7):
            derived.update(roughness=0.0, fuzz=0.0)
        if self.illum in (4, 6, 7) or self.opacity < 1.0:
            derived["refractable"] = True
        if self.opacity < 1.0:
            derived["roughness"] = min(float(derived.get("roughness", self.mat.roughness)), self.opacity)
        return replace(self.mat, **{k: v for k, v in derived.items() if k not in self.explicit})

    def _pbr_material(self) -> Material:
        """A standard file's material as the pbr kind (module docs: the mapping)."""
        m, p = self.mat, self.phong
        if "pr" in p:
            rough = p["pr"]
        elif "ns" in p:
            rough = (2.0 / (p["ns"] + 2.0)) ** 0.25          # sqrt(alpha), alpha = sqrt(2 / (Ns + 2))
        else:
            rough = 0.0 if self.illum in (3, 4, 5, 6, 7) else 1.0     # ray-traced reflection/refraction: smooth
        fields = dict(name=m.name, source=m.source, line=m.line, base_color=m.diffuse, base_color_map=m.diffuse_map,
                      emission=m.emission, emission_map=m.emission_map, roughness=rough,
                      metallic=p.get("pm", 0.0), ior=m.ior if self.pbr.get("ni") else PBR_DEFAULTS["ior"])
        if self.ks is not None:
            fields["specular_color"] = tuple(min(2.0 * c, 1000.0) for c in self.ks)
        if self._lambertian():
            fields["specular"] = 0.0
        if self.illum in (3, 5) and "pm" not in p:
            fields["metallic"] = 1.0
            if self.ks is not None:
                fields.update(base_color=self.ks, base_color_map=None)
        transmission = 1.0 - self.opacity
        if self.illum in (4, 6, 7) and "d" not in self.pbr:
            transmission = 1.0
        if transmission > 0:
            fields["transmission"] = transmission
            if self.tf is not None:
                fields.update(base_color=self.tf, base_color_map=None)
        for key in ("anisotropy", "anisotropy_rotation", "normal", "bump", "metallic_map", "roughness_map",
                    "opacity_map", "normal_map", "bump_map"):
            if key in self.pbr:
                fields[key] = self.pbr[key]
        return Material.pbr(**fields)

    def _lambertian(self) -> bool:
        """A standard material with no specular layer (module docs): ``illum 0`` or ``1`` (colour, no
        highlight), or no ``Ks`` (or ``Ks 0``) with neither ``illum`` 3-7 (ray-traced reflection or
        refraction) nor the PBR extension's ``Pr``/``Pm`` (whose dielectrics keep glTF's 4%)."""
        if self.illum in (0, 1):
            return True
        no_ks = self.ks is None or max(self.ks) == 0.0
        return no_ks and self.illum not in (3, 4, 5, 6, 7) and "pr" not in self.phong and "pm" not in self.phong

    def _phong_and_pbr(self) -> dict[str, object]:
        """Roughness (diffuse probability) and fuzz from Ks/Ns or Pm/Pr; see the module docs."""
        p, out = self.phong, {}
        if "pm" in p or "pr" in p:
            if "pm" in p:
                out["roughness"] = 1.0 - (p["pm"] + 0.04 * (1.0 - p["pm"]))
            if "pr" in p:
                out["fuzz"] = p["pr"]
            return out
        if "ks" in p:
            kd = max(self.mat.diffuse)
            out["roughness"] = kd / (kd + p["ks"]) if kd + p["ks"] > 0 else 1.0
        if "ns" in p:
            out["fuzz"] = min(1.0, (5.0 / (p["ns"] + 2.0)) ** 0.5)
        return out


def load_mtl(path: str | os.PathLike[str], warn: Callable[[str], None] | None = None) -> dict[str, Material]:
    """Read an MTL file into {name: Material}; the later of two definitions of a name wins.

    Raises :class:`SceneError` for a missing file or bad content, with the file and line. ``warn``,
    when given, receives at most one line per file about what was read but not supported.
    """
    path = str(path)
    return parse_mtl_bytes(read_file(path, "MTL"), path, warn)


def parse_mtl_bytes(data: bytes, path: str = "<input>", warn: Callable[[str], None] | None = None
                    ) -> dict[str, Material]:
    """Parse MTL text given as bytes; ``path`` names it in errors and in :class:`TextureRef`."""
    drafts: dict[str, _Draft] = {}
    draft: _Draft | None = None
    seed_dialect = False
    ignored: dict[str, None] = {}        # unsupported tags and texture options, in order of appearance
    standard_only: dict[str, None] = {}  # tags only the pbr kind reads, or it does not model
    data = normalise_text(data, path, "MTL")
    for lineno, toks in iter_lines(data):
        tag = toks[0].decode("latin-1").lower()
        if draft is None or draft.kind is None:     # a material naming its kind leaves the dialect alone
            seed_dialect = seed_dialect or tag in SEED_TAGS     # anywhere in the file, even before newmtl
        if tag == "newmtl":
            if len(toks) < 2:
                raise SceneError(path, lineno, "expected a material name after 'newmtl'")
            draft = _Draft(Material(name=decode_name(toks[1:]), source=path, line=lineno))
            drafts[draft.mat.name] = draft             # a later definition of a name replaces it
            continue
        if tag == "kind":
            _kind_statement(draft, toks, path, lineno)
        elif draft is None:
            continue
        elif tag == "set":
            _set_statement(draft, toks, path, lineno, ignored)
        elif draft.kind is not None and not _kind_reads(draft.kind, tag):
            ignored[toks[0].decode("latin-1")] = None
        else:
            if not _statement(draft, tag, toks, path, lineno):
                ignored[toks[0].decode("latin-1")] = None
            elif tag in _MAP_SLOTS:
                ignored.update((f"texture option {o}", None) for o in _texture_options(toks[1:]))
            if draft.kind is None and (tag in _PBR_MAPS or tag in ("aniso", "anisor", "map_ks")):
                standard_only[toks[0].decode("latin-1")] = None
        draft.statements += 1
    if seed_dialect:        # the seed's kind has no normal, bump or cut-out maps, no anisotropy
        ignored.update((t, None) for t in standard_only if t.lower() != "map_ks")
    elif "map_Ks" in standard_only or "map_ks" in standard_only:
        ignored["map_Ks"] = None
    if warn is not None:
        _report(path, list(ignored), warn)
    return {name: _with_medium(d, d.finish(seed_dialect)) for name, d in drafts.items()}


def _kind_reads(kind: str, tag: str) -> bool:
    """Whether a material that names ``kind`` reads classic tag ``tag``: the seed and pbr kinds read
    their dialects' tags but for what they have no field for (_UNREAD); every kind reads its interior
    medium and ``index_matched`` (docs/volumes.md), and ``Ka`` is ignored silently, as everywhere."""
    if kind in _UNREAD:
        return tag not in _UNREAD[kind]
    return tag.startswith("medium_") or tag in ("index_matched", "ka")


def _kind_statement(d: _Draft | None, toks: list[bytes], path: str, lineno: int) -> None:
    """``kind NAME``: the material's kind, any name of ``MATERIAL_KINDS`` (read when the line is, so
    that a kind registered there needs nothing here)."""
    kinds = schema.MATERIAL_KINDS
    if d is None:
        raise SceneError(path, lineno, "expected 'newmtl NAME' before 'kind'")
    if d.statements:        # so each line is read knowing the kind (the seed's and pbr's readings differ)
        raise SceneError(path, lineno, f"expected 'kind' right after 'newmtl {d.mat.name}' (line {d.mat.line}), "
                                       "before the material's other lines")
    name = b" ".join(toks[1:]).decode("latin-1").lower()
    if name not in kinds:
        raise SceneError(path, lineno, f"expected a material kind after 'kind' ({', '.join(kinds)}), got {name!r}")
    d.kind = name


def _set_statement(d: _Draft, toks: list[bytes], path: str, lineno: int, ignored: dict[str, None]) -> None:
    """``set FIELD VALUE...``: one field of the material by its schema name, read by its column's type
    and checked against its range (whether the kind reads it: at the end, _Draft._with_sets)."""
    fields = schema.settable(d.kind)
    key = toks[1].decode("latin-1").lower() if len(toks) > 1 else ""
    if key not in fields:
        raise SceneError(path, lineno, f"expected a material field after 'set' ({', '.join(fields)}), "
                                       f"got {key or 'nothing'!r}")
    (column, is_map), args, tag = fields[key], toks[2:], f"set {key}"
    words = b" ".join(args).decode("latin-1")
    if not args:
        raise SceneError(path, lineno, f"expected a value after '{tag}'")
    if is_map:
        value: object = _map_ref(args, path, lineno, tag, column.high)
        ignored.update((f"texture option {o}", None) for o in _texture_options(args))
    elif column.type == COLOR:
        value = _colour(args, path, lineno, tag, column.low, column.high)
    elif column.type == FLAG:
        value = _FLAG_WORDS.get(words.lower())
        if value is None:
            raise SceneError(path, lineno, f"expected on or off after '{tag}', got {words!r}")
    else:
        value = _column_value(args, path, lineno, tag, column.name)
    d.sets.append((key, value, column, lineno))


def _map_ref(args: list[bytes], path: str, lineno: int, tag: str, high: float | None, proc: bool = True) -> object:
    """A texture statement's map: a procedural texture (``proc:``, where ``proc``; its colours in
    [0, ``high``]), else a texture file after the statement's options."""
    ref = parse_proc_map(args, path, lineno, tag, np.inf if high is None else high) if proc else None
    return ref or TextureRef(path=_texture_path(args, path, lineno, tag), mtl_file=path, line=lineno)


def _colour(args: list[bytes], path: str, lineno: int, tag: str, low: float, high: float
            ) -> tuple[float, float, float]:
    """A colour: 3 numbers, or 1 for a grey, each in [low, high] (the schema's range)."""
    rgb = parse_floats(args, (1, 3), path, lineno, tag)
    if min(rgb) < low or max(rgb) > high:
        why = " (a surface cannot reflect more light than it receives)" if high == 1.0 else ""
        bad = min(rgb) if min(rgb) < low else max(rgb)
        raise SceneError(path, lineno, f"expected colour values in [{low:g}, {high:g}] after '{tag}', got {bad:g}{why}")
    return (rgb[0],) * 3 if len(rgb) == 1 else tuple(rgb)


def _with_medium(d: _Draft, m: Material) -> Material:
    """``m`` with its interior medium (``medium_*`` lines) and, for ``index_matched``, as the
    pass-through interface: a smooth pbr dielectric of IOR 1, white, no specular layer (every ray
    crosses it unbent and unweighted; docs/volumes.md)."""
    if d.index_matched:
        m = Material.pbr(m.name, source=m.source, line=m.line, base_color=(1.0, 1.0, 1.0), transmission=1.0,
                         ior=1.0, roughness=0.0, specular=0.0, metallic=0.0)
    if d.medium:
        m = replace(m, interior=Medium(**d.medium))
    return m


def _report(path: str, ignored: list[str], warn: Callable[[str], None]) -> None:
    """One line per file naming the tags and texture options it uses that are not supported.

    (A reflectance colour above 1, which would add energy, is an error: see :func:`_statement`.)
    """
    if ignored:
        warn(f"{path}: read but not supported (ignored): " + ", ".join(ignored))


def _statement(d: _Draft, tag: str, toks: list[bytes], path: str, lineno: int) -> bool:
    """Apply one line to the material being read; False for a tag that is not supported."""
    args, name = toks[1:], toks[0].decode("latin-1")
    m = d.mat
    if tag in _COLOUR_SLOTS:
        slots = [COLUMN[slot] for slot in _COLOUR_SLOTS[tag]]
        colour = _colour(args, path, lineno, name, max(c.low for c in slots), min(c.high for c in slots))
        for slot in _COLOUR_SLOTS[tag]:
            setattr(m, slot, colour)
            setattr(m, slot + "_map", None)
        if tag == "ks":
            d.phong["ks"] = max(colour)
            d.ks = colour
        elif tag == "tf":
            d.tf = colour
    elif tag in _MAP_SLOTS:
        high = min(COLUMN[slot].high for slot in _MAP_SLOTS[tag])     # the schema's, as for colours
        ref = _map_ref(args, path, lineno, name, high)
        for slot in _MAP_SLOTS[tag]:
            setattr(m, slot + "_map", ref)
    elif tag == "roughness":
        m.roughness = _column_value(args, path, lineno, name, "roughness")
        d.explicit.add("roughness")
    elif tag == "fuzz":
        m.fuzz = _column_value(args, path, lineno, name, "fuzz")
        d.explicit.add("fuzz")
    elif tag in ("kn", "ni"):
        m.ior = _column_value(args, path, lineno, name, "ior")
        d.pbr["ni"] = True
    elif tag in _PBR_MAPS:
        column = _PBR_MAPS[tag]
        d.pbr[column + "_map"] = _map_ref(args, path, lineno, name, COLUMN[column].high, tag in ("map_pr", "map_pm"))
        bm = _bump_multiplier(args, path, lineno, name)
        if bm is not None and column in ("normal", "bump"):
            d.pbr[column] = bm
    elif tag == "aniso":
        d.pbr["anisotropy"] = _column_value(args, path, lineno, name, "anisotropy")
    elif tag == "anisor":
        d.pbr["anisotropy_rotation"] = 2.0 * np.pi * _number(args, path, lineno, name, lo=-100.0, hi=100.0)
    elif tag == "refractable":
        m.refractable = True
        d.explicit.add("refractable")
    elif tag == "d":
        d.opacity = _number(args, path, lineno, name, lo=0.0, hi=1.0)
        d.pbr["d"] = True
    elif tag == "tr":
        d.opacity = 1.0 - _number(args, path, lineno, name, lo=0.0, hi=1.0)
        d.pbr["d"] = True
    elif tag == "medium_density":           # a density grid: a .nvdb file, relative to this file
        if len(args) != 1:
            raise SceneError(path, lineno, f"expected one .nvdb file name after '{name}'")
        grids, refused = confine(decode_name(args), os.path.dirname(path), "density grid")
        if refused:
            raise SceneError(path, lineno, refused)
        d.medium["density"] = str(grids[0])
    elif tag == "medium_density_scale":
        d.medium["density_scale"] = _number(args, path, lineno, name, lo=0.0, hi=MAX_SIGMA, open_lo=True)
    elif tag.startswith("medium_") and tag[7:] in MEDIUM_KEYS:
        key = tag[7:]
        if key == "g":
            g = parse_floats(args, (1,), path, lineno, name)[0]
            if not -MAX_G <= g <= MAX_G:
                raise SceneError(path, lineno, f"expected a value in [-{MAX_G}, {MAX_G}] after '{name}', got {g:g}")
            d.medium[key] = g
        elif key == "majorant":
            d.medium[key] = _number(args, path, lineno, name, lo=1.0, hi=MAX_MAJORANT)
        else:
            rgb = parse_floats(args, (1, 3), path, lineno, name)
            if any(not 0.0 <= v <= MAX_SIGMA for v in rgb):
                raise SceneError(path, lineno, f"expected values in [0, {MAX_SIGMA:g}] after '{name}', got "
                                               + " ".join(f"{v:g}" for v in rgb))
            d.medium[key] = tuple(rgb) * (3 // len(rgb))
    elif tag == "index_matched":
        if args:
            raise SceneError(path, lineno, f"expected nothing after 'index_matched', got {len(args)} values")
        d.index_matched = True
    elif tag == "ka":
        pass            # ambient colour: a path tracer computes the ambient light; silently ignored
    elif tag == "illum":
        if len(args) != 1:
            raise SceneError(path, lineno, f"expected 1 integer after 'illum', got {len(args)}")
        d.illum = parse_int(args[0], path, lineno, "illumination model")
    elif tag == "ns":
        d.phong["ns"] = _number(args, path, lineno, name, lo=0.0)
    elif tag in ("pr", "pm"):
        d.phong[tag] = _number(args, path, lineno, name, lo=0.0, hi=1.0)
    else:
        return False
    return True


def _bump_multiplier(args: list[bytes], path: str, lineno: int, tag: str) -> float | None:
    """The ``-bm`` option of a bump or normal map statement, if it has one (checked: a plain number
    in the bump column's range)."""
    for i, a in enumerate(args[:-1]):
        if a.decode("latin-1").lower() == "-bm":
            return _column_value(args[i + 1:i + 2], path, lineno, f"{tag} -bm", "bump")
    return None


def _column_value(args: list[bytes], path: str, lineno: int, tag: str, column: str) -> float:
    """One number in the range of a material schema column."""
    return _number(args, path, lineno, tag, lo=COLUMN[column].low, hi=COLUMN[column].high)


def _number(args: list[bytes], path: str, lineno: int, tag: str, *, lo: float, hi: float | None = None,
            open_lo: bool = False) -> float:
    """One number in [lo, hi] (or (lo, hi] with ``open_lo``)."""
    value = parse_floats(args, (1,), path, lineno, tag)[0]
    v32 = float(np.float32(value))      # checked as the kernel will see it: 1e-46 is 0 in float32
    if v32 < lo or value < lo or (open_lo and v32 == lo) or (hi is not None and v32 > hi):
        low = f"> {lo:g}" if open_lo else f">= {lo:g}"
        want = f"in [{lo:g}, {hi:g}]" if hi is not None else low
        raise SceneError(path, lineno, f"expected a value {want} after '{tag}', got {value:g}")
    return value


def _texture_path(args: list[bytes], path: str, lineno: int, tag: str) -> str:
    """The file name of a texture statement, after its options."""
    i = 0
    while i < len(args) - 1 and args[i].decode("latin-1").lower() in _TEX_OPTIONS:
        count = _TEX_OPTIONS[args[i].decode("latin-1").lower()]
        lo, hi = (count, count) if isinstance(count, int) else count
        i += 1 + lo
        while hi > lo and i < len(args) - 1 and _is_number(args[i]):
            i, hi = i + 1, hi - 1
    if i >= len(args):
        raise SceneError(path, lineno, f"expected a texture file name after '{tag}'")
    return decode_name(args[i:])


def _texture_options(args: list[bytes]) -> list[str]:
    """The options written before a texture's file name (e.g. ``-s``), as they are spelled."""
    return [a.decode("latin-1") for a in args[:-1] if a.decode("latin-1").lower() in _TEX_OPTIONS]


def _is_number(tok: bytes) -> bool:
    try:
        float(tok)
    except ValueError:
        return False
    return True
