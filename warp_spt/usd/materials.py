"""UsdPreviewSurface materials onto the ``pbr`` kind, with their UsdUVTexture textures.

A colour input (diffuseColor, emissiveColor) connected to a texture's ``rgb`` names the file, decoded
from sRGB by the loader as every colour map is; a texture whose ``sourceColorSpace`` says otherwise
(``raw`` on a colour, ``sRGB`` on a data input) is read here and handed over in linear values. A
scalar input (metallic, roughness, opacity) reads the one channel it is connected to (r, g, b or a),
read here into a grey image: the kind reads metallic and roughness from the blue and green channels
of a packed map, which a USD file need not have. Asset paths resolve through USD's resolver and must
lie in the stage's folder (``usd/assets.py``, through ``io.paths.confine``); a texture inside a ``.usdz``
is read from the package in memory, its package confined as a file is.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from warp_spt.scene.atlas_layout import TEXEL_BUDGET
from warp_spt.scene.errors import SceneError
from warp_spt.scene.model import TextureRef
from warp_spt.scene.parts import pbr_material
from warp_spt.scene.validate import MAX_RADIANCE
from warp_spt.usd.assets import locate, package_bytes

# UsdPreviewSurface inputs read, and the pbr kind's field each becomes; the others warn once
_COLOURS = {"diffuseColor": "base_color", "emissiveColor": "emission"}
_SCALARS = {"metallic": "metallic", "roughness": "roughness", "opacity": "opacity", "ior": "ior",
            "clearcoat": "clearcoat", "clearcoatRoughness": "clearcoat_roughness"}
_IGNORED_DEFAULTS = {"useSpecularWorkflow": 0, "displacement": 0.0, "occlusion": 1.0}


class Materials:
    """The materials of one stage, each made once (by prim path) into a row of the file's table."""

    def __init__(self, path: str, warn) -> None:
        self.path = path
        self.warn = warn                       # (prim path, message): one warning per prim and message
        self.names: list[str] = []
        self.materials: dict = {}
        self._row: dict[str, int] = {}

    def row(self, material, names: list[str]) -> int:
        """The row of a UsdShade.Material (None: the default material, row 0)."""
        if material is None:
            return 0
        key = str(material.GetPath())
        if key not in self._row:
            name = f"{Path(self.path).name}: {key}"
            fields = self._fields(material)
            from warp_spt.scene.model import MaterialValueError

            try:
                self.materials[name] = pbr_material(name, self.path, fields)
            except MaterialValueError as err:
                raise SceneError(self.path, 0, f"{key}: {err.problem}") from None
            self._row[key] = len(names)
            names.append(name)
        return self._row[key]

    def display(self, colour: tuple[float, float, float], names: list[str]) -> int:
        """The row of an unbound prim's displayColor: UsdPreviewSurface's defaults in that colour (one
        row per colour)."""
        colour = tuple(min(max(c, 0.0), 1.0) for c in colour)
        key = "displayColor {:.6g} {:.6g} {:.6g}".format(*colour)
        if key not in self._row:
            name = f"{Path(self.path).name}: {key}"
            self.materials[name] = pbr_material(name, self.path, dict(base_color=colour, metallic=0.0, roughness=0.5))
            self._row[key] = len(names)
            names.append(name)
        return self._row[key]

    def emitter(self, name: str, radiance: tuple[float, float, float], names: list[str]) -> int:
        """A row for a UsdLux area light's surface: black, emitting ``radiance``."""
        names.append(name)
        self.materials[name] = pbr_material(name, self.path, dict(
            base_color=(0.0, 0.0, 0.0), emission=tuple(min(max(c, 0.0), MAX_RADIANCE) for c in radiance)))
        return len(names) - 1

    def _fields(self, material) -> dict:
        from pxr import UsdShade

        where = str(material.GetPath())
        shader = material.ComputeSurfaceSource()[0]
        fields: dict = dict(base_color=(0.18, 0.18, 0.18), metallic=0.0, roughness=0.5)    # the schema's defaults
        if not shader or shader.GetIdAttr().Get() != "UsdPreviewSurface":
            ident = shader.GetIdAttr().Get() if shader else None
            self.warn(where, f"{where}: its surface is {ident or 'not a shader'}, not a UsdPreviewSurface: drawn "
                      "with UsdPreviewSurface's defaults")
            return fields
        spath = str(shader.GetPath())
        for inp in shader.GetInputs():
            key = inp.GetBaseName()
            source = inp.GetConnectedSource() if inp.HasConnectedSource() else None
            texture = None
            if source:
                texture = UsdShade.Shader(source[0].GetPrim())
                if texture.GetIdAttr().Get() != "UsdUVTexture":
                    self.warn(spath, f"{spath}.inputs:{key}: connected to {texture.GetIdAttr().Get()}, which is not "
                              "read (only UsdUVTexture): its own value is used")
                    texture = None
            if key in _COLOURS:
                slot = _COLOURS[key]
                if texture is not None:
                    fields[f"{slot}_map"] = self._texture(texture, source[1], colour=True)
                    fields[slot] = (1.0, 1.0, 1.0)
                elif inp.Get() is not None:
                    fields[slot] = tuple(float(c) for c in inp.Get())
            elif key in _SCALARS:
                slot = _SCALARS[key]
                if texture is not None and slot in ("metallic", "roughness", "opacity"):
                    fields[f"{slot}_map"] = self._texture(texture, source[1], colour=False)
                    fields[slot] = 1.0
                elif inp.Get() is not None:
                    fields[slot] = float(inp.Get())
            elif key == "normal" and texture is not None:
                fields["normal_map"] = self._texture(texture, source[1], colour=False, normal=True)
            elif key == "opacityThreshold" and inp.Get():
                fields["alpha_cutoff"] = float(inp.Get())
            elif key in _IGNORED_DEFAULTS and (texture is not None or inp.Get() not in (None, _IGNORED_DEFAULTS[key])):
                self.warn(spath, f"{spath}.inputs:{key} is not read")
        fields["base_color"] = tuple(min(max(c, 0.0), 1.0) for c in fields["base_color"])
        fields["emission"] = tuple(min(max(c, 0.0), MAX_RADIANCE) for c in fields.get("emission", (0.0, 0.0, 0.0)))
        for k in ("metallic", "roughness", "opacity", "clearcoat", "clearcoat_roughness"):
            if k in fields:
                fields[k] = min(max(fields[k], 0.0), 1.0)
        return fields

    def _texture(self, texture, output: str, colour: bool, normal: bool = False) -> TextureRef | None:
        """The TextureRef of a UsdUVTexture's file for an input connected to its ``output``."""
        where = str(texture.GetPath())
        inp = texture.GetInput("file")
        asset = inp.Get() if inp else None
        if asset is None or not asset.path:
            self.warn(where, f"{where}: a UsdUVTexture without a file: its input's own value is used")
            return None
        space = texture.GetInput("sourceColorSpace")
        space = (space.Get() if space else None) or (texture.GetPrim().GetAttribute("sourceColorSpace").Get()
                                                     if texture.GetPrim().HasAttribute("sourceColorSpace") else None)
        space = str(space or "auto")
        resolved = asset.resolvedPath
        if not resolved:
            self.warn(where, f"{where}: texture {asset.path!r} not found: a neutral texel stands for it")
            return None
        name, packaged, refused = locate(resolved, self.path, "texture")
        if refused:
            raise SceneError(self.path, 0, f"{where}: {refused}")
        data = package_bytes(resolved) if packaged else None        # inside a .usdz: read from it in memory
        channel = output if output in ("r", "g", "b", "a") else "rgb"
        if colour and channel == "rgb" and space != "raw" and data is None:
            return TextureRef(name, self.path, 0, neutral=True)   # the loader decodes a colour map from sRGB
        if normal and channel == "rgb" and space != "sRGB" and data is None:
            return TextureRef(name, self.path, 0, neutral=True)   # the loader checks it is a normal map
        image = _read(data if data is not None else name, self.path, where)
        if image is None:
            self.warn(where, f"{where}: cannot read texture {asset.path!r}: a neutral texel stands for it")
            return None
        if channel != "rgb":
            image = np.repeat(image[..., "rgba".index(channel)][..., None], 3, axis=2)
        else:
            image = image[..., :3]
        srgb = space == "sRGB" or (space == "auto" and colour)
        if srgb:
            from warp_spt.io.loader import srgb_to_linear

            image = srgb_to_linear(image)
        return TextureRef(f"{name}:{channel}:{space}", self.path, 0, image=np.ascontiguousarray(image, np.float32))


def _read(source, path: str, where: str) -> np.ndarray | None:
    """(H, W, 4) float32 in [0, 1] (alpha 1 where the image has none), or None if it cannot be read."""
    import io

    from PIL import Image

    try:
        with Image.open(io.BytesIO(source) if isinstance(source, bytes) else source) as img:
            w, h = img.size
            if w * h > TEXEL_BUDGET:
                raise SceneError(path, 0, f"{where}: texture is {w}x{h} = {w * h:,} texels, more than the budget "
                                 f"of {TEXEL_BUDGET:,}")
            scale = 65535.0 if img.mode.startswith("I;16") or img.mode == "I" else 255.0
            if scale == 255.0:
                return np.asarray(img.convert("RGBA"), np.float32) / np.float32(255.0)
            grey = np.clip(np.asarray(img, np.float64) / scale, 0.0, 1.0).astype(np.float32)
            return np.concatenate([np.repeat(grey[..., None], 3, axis=2), np.ones_like(grey)[..., None]], axis=2)
    except (OSError, ValueError):
        return None
