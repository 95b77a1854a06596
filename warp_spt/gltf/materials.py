"""Materials: glTF's metallic-roughness model and the KHR_materials_* extensions onto the ``pbr`` kind;
their textures (images by URI, data URI or buffer view) and the base colour's texture transform."""

from __future__ import annotations

import math
import urllib.parse
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from warp_spt.gltf.accessors import Accessors
from warp_spt.gltf.document import _err
from warp_spt.scene.media import MAX_SIGMA, Medium
from warp_spt.scene.model import CHECKER_NAME, Material, TextureRef
from warp_spt.scene.parts import pbr_material
from warp_spt.scene.validate import MAX_RADIANCE

MAX_UV = 1e30          # transformed texture coordinates: float32 with room to spare (1e39 became inf)


@dataclass
class GltfMaterial:
    """A glTF material as written (metallic-roughness model; a specular-glossiness one converted to it), for the
    ``pbr`` kind."""

    name: str
    base_color: tuple[float, float, float, float] = (1.0, 1.0, 1.0, 1.0)
    base_color_texture: int | None = None     # index into /textures
    metallic: float = 1.0
    roughness: float = 1.0
    metallic_roughness_texture: int | None = None
    normal_texture: int | None = None
    normal_scale: float = 1.0
    emissive: tuple[float, float, float] = (0.0, 0.0, 0.0)
    emissive_texture: int | None = None
    alpha_mode: str = "OPAQUE"
    alpha_cutoff: float = 0.5
    double_sided: bool = False
    extensions: dict = field(default_factory=dict)

SPEC_GLOSS = "KHR_materials_pbrSpecularGlossiness"
DIELECTRIC_F0 = 0.04


def specular_glossiness(diffuse, specular, glossiness: float) -> tuple[tuple[float, ...], float, float]:
    """(base colour RGBA, metallic, roughness) for specular-glossiness factors, by the conversion of
    Khronos' glTF sample viewer and glTF-Transform: the metallic that explains the specular's
    perceived brightness beside the diffuse's over a dielectric F0 of 0.04, the base colour blended
    between the diffuse's and the specular's by metallic squared, roughness = 1 - glossiness."""
    def brightness(c):
        return math.sqrt(0.299 * c[0] ** 2 + 0.587 * c[1] ** 2 + 0.114 * c[2] ** 2)

    one_minus_specular = 1.0 - max(specular)
    d, s = brightness(diffuse), brightness(specular)
    if s < DIELECTRIC_F0:
        metallic = 0.0
    else:
        a = DIELECTRIC_F0
        b = d * one_minus_specular / (1.0 - DIELECTRIC_F0) + s - 2.0 * DIELECTRIC_F0
        c = DIELECTRIC_F0 - s
        metallic = min(max((-b + math.sqrt(max(b * b - 4.0 * a * c, 0.0))) / (2.0 * a), 0.0), 1.0)
    eps = 1e-6
    from_diffuse = [x * one_minus_specular / (1.0 - DIELECTRIC_F0) / max(1.0 - metallic, eps) for x in diffuse[:3]]
    from_specular = [(x - DIELECTRIC_F0 * (1.0 - metallic)) / max(metallic, eps) for x in specular]
    w = metallic * metallic
    rgb = [min(max(fd + (fs - fd) * w, 0.0), 1.0) for fd, fs in zip(from_diffuse, from_specular)]
    return (*rgb, diffuse[3]), metallic, min(max(1.0 - glossiness, 0.0), 1.0)


class Materials(Accessors):
    def _base_pointer(self, mat: int) -> tuple[dict, str, str]:
        """(the object holding the base colour texture, its pointer, the texture's key): a specular-
        glossiness material's diffuse texture (the extension, where read, wins over its fallback)."""
        m = self.item("materials", mat)
        sg = self.get(self.obj(m, "extensions", f"/materials/{mat}"), SPEC_GLOSS, dict, f"/materials/{mat}/extensions")
        if sg is not None:
            return sg, f"/materials/{mat}/extensions/{SPEC_GLOSS}", "diffuseTexture"
        return self.obj(m, "pbrMetallicRoughness", f"/materials/{mat}"), f"/materials/{mat}/pbrMetallicRoughness", \
            "baseColorTexture"

    def _base_texture(self, mat: int | None) -> dict | None:
        if mat is None:
            return None
        parent, ptr, key = self._base_pointer(mat)
        return self.get(parent, key, dict, ptr)

    def _uv_set(self, mat: int | None) -> int:
        info = self._base_texture(mat)
        if info is None:
            return 0
        ptr = "/".join(self._base_pointer(mat)[1:])
        tt = self.get(self.obj(info, "extensions", ptr), "KHR_texture_transform", dict, f"{ptr}/extensions")
        k = self.get(tt, "texCoord", int, f"{ptr}/extensions/KHR_texture_transform") if tt else None
        k = self.get(info, "texCoord", int, ptr, 0) if k is None else k
        if not 0 <= k < 16:
            raise _err(self.path, f"{ptr}/texCoord", f"texCoord {k} must lie in 0..15")
        return k

    def _uv_transform(self, uv: np.ndarray, mat: int | None) -> np.ndarray:
        """KHR_texture_transform of the base colour texture: offset + rotation(-r) * scale * uv, in
        glTF's uv space (v down), as the extension defines it."""
        info = self._base_texture(mat)
        if info is None:
            return uv
        ptr = "/".join(self._base_pointer(mat)[1:]) + "/extensions/KHR_texture_transform"
        tt = self.get(self.obj(info, "extensions", ptr.rsplit("/", 2)[0]), "KHR_texture_transform", dict,
                      ptr.rsplit("/", 1)[0])
        if not tt:
            return uv
        offset = self.numbers(tt, "offset", ptr, 2, [0.0, 0.0])
        rotation = self.get(tt, "rotation", float, ptr, 0.0)
        scale = self.numbers(tt, "scale", ptr, 2, [1.0, 1.0])
        c, s = math.cos(rotation), math.sin(rotation)
        su, sv = uv[:, 0] * scale[0], uv[:, 1] * scale[1]
        out = np.stack([c * su + s * sv + offset[0], -s * su + c * sv + offset[1]], axis=1)
        if not np.abs(out).max(initial=0.0) <= MAX_UV:       # stored as float32 (also NaN)
            raise _err(self.path, ptr, f"offset {offset} and scale {scale} take texture coordinates beyond "
                       f"+-{MAX_UV:g}")
        return out

    def _image(self, tex: int, ptr: str) -> TextureRef | None:
        """Texture ``tex``'s image, or None (a neutral texel: the factors alone) with a warning where it
        has none that can be read; an image whose bytes turn out unreadable is the loader's warning
        (``TextureRef.neutral``). A file outside the glTF's folder stays an error."""
        t = self.item("textures", tex)
        tptr = f"/textures/{tex}"
        source = self.index(t, "source", tptr, "images")
        if source is None:
            self.warn_once(tptr, f"{tptr}: a texture without a 'source' image (or only an extension's) is not "
                           "read: a neutral texel stands for it")
            return None
        img = self.item("images", source)
        iptr = f"/images/{source}"
        uri = self.get(img, "uri", str, iptr)
        name = f"images/{source}"
        if uri is not None and not uri.startswith("data:"):
            if self._local_file(uri, f"{iptr}/uri", missing_ok=True) is None:     # local; the loader reads it
                return None
            return TextureRef(urllib.parse.unquote(uri), self.path, 0, neutral=True)
        if uri is not None:
            return TextureRef(name, self.path, 0, image=self.uri(uri, f"{iptr}/uri"), neutral=True)
        view = self.index(img, "bufferView", iptr, "bufferViews")
        if view is None:
            raise _err(self.path, iptr, "an image needs a 'uri' or a 'bufferView'")
        buf, off, length, _ = self.view(view)
        return TextureRef(name, self.path, 0, image=buf[off:off + length], neutral=True)

    def _checked_material(self, mat: int | None, names: list[str]) -> tuple[str, Material]:
        """:meth:`_material`, its values within the material schema's ranges (SceneError naming the
        file, the material's pointer and name, and the field)."""
        from warp_spt.scene.model import MaterialValueError

        try:
            return self._material(mat, names)
        except MaterialValueError as err:   # its name is "FILE: NAME"; the file is named already
            raise _err(self.path, f"/materials/{mat}" if mat is not None else "",
                       f"material {err.name.split(': ', 1)[-1]!r}: {err.problem}") from None

    def _material(self, mat: int | None, names: list[str]) -> tuple[str, Material]:
        """A unique name and a material of the ``pbr`` kind: glTF's metallic-roughness model and the
        KHR_materials_* that the kind has columns for. The packed metallic-roughness texture is named by
        both maps (the kind reads its B and G channels); the base colour texture's alpha is the opacity
        map of a MASK or BLEND material. Colour maps are decoded from sRGB by the loader (by slot)."""
        if mat is None:          # glTF's default material: white, metallic 1, roughness 1
            name = f"{Path(self.path).name}: default material"
            return name, self._pbr_material(name, dict(base_color=(1.0, 1.0, 1.0), metallic=1.0, roughness=1.0))
        rec = self._material_record(mat)
        # named after the file: materials of the same name in two files of a scene stay apart
        name = f"{Path(self.path).name}: {rec.name or f'material {mat}'}"
        while name in names or name == CHECKER_NAME:
            name = f"{name} ({mat})"
        mptr = f"/materials/{mat}"
        eptr = f"{mptr}/extensions"
        ext = lambda key: self.obj(rec.extensions, key, eptr)      # noqa: E731
        image = lambda k, where: None if k is None else self._image(k, f"{mptr}/{where}")  # noqa: E731
        tex = image(rec.base_color_texture, "pbrMetallicRoughness/baseColorTexture")
        strength = self.get(ext("KHR_materials_emissive_strength"), "emissiveStrength", float,
                            f"{eptr}/KHR_materials_emissive_strength", 1.0)
        orm = image(rec.metallic_roughness_texture, "pbrMetallicRoughness/metallicRoughnessTexture")
        fields = dict(base_color=tuple(min(max(c, 0.0), 1.0) for c in rec.base_color[:3]), base_color_map=tex,
                      metallic=min(max(rec.metallic, 0.0), 1.0), roughness=min(max(rec.roughness, 0.0), 1.0),
                      metallic_map=orm, roughness_map=orm,
                      normal=min(max(rec.normal_scale, 0.0), 10.0), normal_map=image(rec.normal_texture, "normalTexture"),
                      emission=tuple(min(max(c * strength, 0.0), MAX_RADIANCE) for c in rec.emissive),
                      emission_map=image(rec.emissive_texture, "emissiveTexture"))
        if rec.alpha_mode == "MASK":
            fields["alpha_cutoff"] = rec.alpha_cutoff
        if rec.alpha_mode != "OPAQUE":
            fields["opacity"] = min(max(rec.base_color[3], 0.0), 1.0)
            fields["opacity_map"] = tex
        ior = ext("KHR_materials_ior")
        if ior:
            fields["ior"] = self.get(ior, "ior", float, f"{eptr}/KHR_materials_ior", 1.5)
        transmission = ext("KHR_materials_transmission")
        if transmission:
            fields["transmission"] = self.get(transmission, "transmissionFactor", float,
                                              f"{eptr}/KHR_materials_transmission", 0.0)
            # without KHR_materials_volume a transmissive glTF surface is thin-walled
            volume = ext("KHR_materials_volume")
            vptr = f"{eptr}/KHR_materials_volume"
            fields["thin"] = not volume or self.get(volume, "thicknessFactor", float, vptr, 0.0) == 0.0
            if not fields["thin"]:
                fields["interior"] = self._attenuation(volume, vptr)
        specular = ext("KHR_materials_specular")
        if specular:
            sptr = f"{eptr}/KHR_materials_specular"
            fields["specular"] = self.get(specular, "specularFactor", float, sptr, 1.0)
            fields["specular_color"] = tuple(self.numbers(specular, "specularColorFactor", sptr, 3, [1.0, 1.0, 1.0]))
        anisotropy = ext("KHR_materials_anisotropy")
        if anisotropy:
            aptr = f"{eptr}/KHR_materials_anisotropy"
            fields["anisotropy"] = self.get(anisotropy, "anisotropyStrength", float, aptr, 0.0)
            fields["anisotropy_rotation"] = self.get(anisotropy, "anisotropyRotation", float, aptr, 0.0)
        clearcoat = ext("KHR_materials_clearcoat")
        if clearcoat:
            cptr = f"{eptr}/KHR_materials_clearcoat"
            fields["clearcoat"] = min(max(self.get(clearcoat, "clearcoatFactor", float, cptr, 0.0), 0.0), 1.0)
            fields["clearcoat_roughness"] = min(max(self.get(clearcoat, "clearcoatRoughnessFactor", float, cptr,
                                                             0.0), 0.0), 1.0)
            info = self.get(clearcoat, "clearcoatNormalTexture", dict, cptr)
            if info is not None:
                nptr = f"{cptr}/clearcoatNormalTexture"
                fields["clearcoat_normal_map"] = image(self.index(info, "index", nptr, "textures", required=True),
                                                       "extensions/KHR_materials_clearcoat/clearcoatNormalTexture")
                fields["clearcoat_normal"] = min(max(self.get(info, "scale", float, nptr, 1.0), 0.0), 10.0)
            self._unread_textures(clearcoat, cptr, ("clearcoatTexture", "clearcoatRoughnessTexture"), "the coat")
        sheen = ext("KHR_materials_sheen")
        if sheen:
            shptr = f"{eptr}/KHR_materials_sheen"
            fields["sheen_color"] = tuple(min(max(c, 0.0), 1.0) for c in self.numbers(
                sheen, "sheenColorFactor", shptr, 3, [0.0, 0.0, 0.0]))
            fields["sheen_roughness"] = min(max(self.get(sheen, "sheenRoughnessFactor", float, shptr, 0.0), 0.0), 1.0)
            self._unread_textures(sheen, shptr, ("sheenColorTexture", "sheenRoughnessTexture"), "the sheen")
        return name, self._pbr_material(name, fields)

    def _attenuation(self, volume: dict, ptr: str) -> Medium | None:
        """The absorbing interior of a thick transmissive material: sigma_a = -ln(attenuationColor) /
        attenuationDistance (Beer-Lambert, as the extension defines it), no scattering; None where it
        absorbs nothing (the defaults: white, an infinite distance). A colour channel of 0 absorbs as
        strongly as a medium may (MAX_SIGMA)."""
        colour = self.numbers(volume, "attenuationColor", ptr, 3, [1.0, 1.0, 1.0])
        if not all(0.0 <= c <= 1.0 for c in colour):
            raise _err(self.path, f"{ptr}/attenuationColor", f"each channel must lie in [0, 1], got {colour}")
        distance = self.get(volume, "attenuationDistance", float, ptr, math.inf)
        if not distance > 0.0:
            raise _err(self.path, f"{ptr}/attenuationDistance", f"must be greater than 0, got {distance}")
        sigma = tuple(min(max(-math.log(c), 0.0) / distance, MAX_SIGMA) if c > 0.0 else MAX_SIGMA for c in colour)
        if math.isinf(distance) or max(sigma) == 0.0:
            return None
        return Medium(sigma_a=sigma)

    def _unread_textures(self, ext: dict, ptr: str, keys: tuple[str, ...], what: str) -> None:
        for key in keys:
            if key in ext:
                self.warn_once(f"{ptr}/{key}", f"{ptr}/{key} is not read: {what} has its factors alone")

    def _pbr_material(self, name: str, fields: dict) -> Material:
        return pbr_material(name, self.path, fields)

    def _material_record(self, mat: int) -> GltfMaterial:
        m = self.item("materials", mat)
        ptr = f"/materials/{mat}"
        pbr = self.obj(m, "pbrMetallicRoughness", ptr)
        pptr = f"{ptr}/pbrMetallicRoughness"

        def texture(obj: dict, key: str, p: str) -> int | None:
            info = self.get(obj, key, dict, p)
            return None if info is None else self.index(info, "index", f"{p}/{key}", "textures", required=True)

        normal = self.get(m, "normalTexture", dict, ptr) or {}
        alpha = self.get(m, "alphaMode", str, ptr, "OPAQUE")
        if alpha not in ("OPAQUE", "MASK", "BLEND"):
            raise _err(self.path, f"{ptr}/alphaMode", f"expected OPAQUE, MASK or BLEND, got {alpha!r}")
        base_color = tuple(self.numbers(pbr, "baseColorFactor", pptr, 4, [1.0, 1.0, 1.0, 1.0]))
        metallic = self.get(pbr, "metallicFactor", float, pptr, 1.0)
        roughness = self.get(pbr, "roughnessFactor", float, pptr, 1.0)
        base_texture = texture(pbr, "baseColorTexture", pptr)
        mr_texture = texture(pbr, "metallicRoughnessTexture", pptr)
        sg = self.get(self.obj(m, "extensions", ptr), SPEC_GLOSS, dict, f"{ptr}/extensions")
        if sg is not None:
            sptr = f"{ptr}/extensions/{SPEC_GLOSS}"
            base_color, metallic, roughness = specular_glossiness(
                self.numbers(sg, "diffuseFactor", sptr, 4, [1.0, 1.0, 1.0, 1.0]),
                self.numbers(sg, "specularFactor", sptr, 3, [1.0, 1.0, 1.0]),
                self.get(sg, "glossinessFactor", float, sptr, 1.0))
            base_texture, mr_texture = texture(sg, "diffuseTexture", sptr), None
            if texture(sg, "specularGlossinessTexture", sptr) is not None:
                self.warn_once((SPEC_GLOSS, mat), f"{sptr}/specularGlossinessTexture is not read: the material's "
                               "specular and glossiness factors are converted to metal-rough, its texture not")
        return GltfMaterial(
            name=self.get(m, "name", str, ptr, ""),
            base_color=base_color,
            base_color_texture=base_texture,
            metallic=metallic,
            roughness=roughness,
            metallic_roughness_texture=mr_texture,
            normal_texture=texture(m, "normalTexture", ptr),
            normal_scale=self.get(normal, "scale", float, f"{ptr}/normalTexture", 1.0),
            emissive=tuple(self.numbers(m, "emissiveFactor", ptr, 3, [0.0, 0.0, 0.0])),
            emissive_texture=texture(m, "emissiveTexture", ptr),
            alpha_mode=alpha,
            alpha_cutoff=self.get(m, "alphaCutoff", float, ptr, 0.5),
            double_sided=self.get(m, "doubleSided", bool, ptr, False),
            extensions=self.obj(m, "extensions", ptr),
        )
