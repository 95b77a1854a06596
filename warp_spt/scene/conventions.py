"""The command line's conventions for a scene it was not told about: which way is up, the look.

Two kinds of scene reach ``warp-spt``: the seed's own (its demo, its OBJ spheres ``b`` and MTL tags,
usually with an explicit ``-cam``), which must render exactly as the seed renders them, and users'
models exported by other tools, which are Y-up (the convention of OBJ exporters, and glTF's by
definition; a PLY file has none, so its header and shape decide) and usually come without lights
(an exporter's MTL has colours only). :func:`up_axis` and :func:`studio_look` are the rules, written
once; ``warp-spt``, its animations and ``warp-spt view`` all apply them. Pure functions of what the
loader recorded (:attr:`Scene.seed_dialect`), of the scene's lights and of the flags given.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

SEED_UP, MODEL_UP = "z", "y"


# Formats whose up axis is fixed by their specification once read: glTF is Y up by definition, and
# the USD reader turns a stage's upAxis to Y (usd/stage.py); --up is never suggested for them.
_DEFINITE = {"glTF": "glTF is Y up by definition", "USD": "a USD stage, turned Y up from its upAxis when read"}


@dataclass(frozen=True)
class UpChoice:
    """The up axis a command uses and why, for its "framed" line."""

    axis: str
    reason: str          # "" when the user gave --up
    definite: bool = False   # the format fixes it (glTF): no "--up ... to change"

    @property
    def note(self) -> str:
        """E.g. ``Y up (a standard OBJ model; --up z to change)``; empty for an explicit --up."""
        if not self.reason:
            return ""
        if self.definite:
            return f"{self.axis.upper()} up ({self.reason})"
        other = SEED_UP if self.axis == MODEL_UP else MODEL_UP
        return f"{self.axis.upper()} up ({self.reason}; --up {other} to change)"


def describe_formats(formats) -> str:
    """The scene's model files in the words of the up-axis line: "a standard OBJ model" (also a
    scene built in code), "a PLY model", "OBJ and PLY models"."""
    kinds = list(dict.fromkeys(formats))
    if not kinds or kinds == ["OBJ"]:
        return "a standard OBJ model"
    if len(kinds) == 1:
        return f"a {kinds[0]} model"
    return f"{' and '.join(kinds)} models"


def up_axis(given: str | None, *, demo: bool, seed_dialect: bool, cam_given: bool, z_scan: bool = False,
            formats=(), hint: tuple[str, str] | None = None, stands: str | None = None) -> UpChoice:
    """The world's up axis: ``--up`` always wins; the built-in demo, a scene in the seed's dialect
    or an explicit ``-cam`` (the seed's camera convention) keep the seed's Z. Otherwise by the
    model files' ``formats`` (:attr:`Scene.formats`):

    * glTF and USD only: Y, by their specifications (the USD reader has applied the stage's axis);
    * a PLY file (no convention of its own): the axis its header states (``hint``:
      :func:`warp_spt.io.ply.up_hint`, "sure"), else Z when it stands on a flat base in the XY
      plane (``z_scan``: :func:`warp_spt.scene.camera.looks_z_up`) and otherwise the axis it stands
      on (``stands``: :func:`warp_spt.scene.camera.stands_up`; both "likely"), else Y ("a guess");
    * anything else (a standard OBJ): Z for a scan on a flat base in the XY plane (``z_scan``) or a
      model that stands only with Z up (``stands``, :func:`~warp_spt.scene.camera.stands_up`'s strict
      rule: a bust with an open cut base, a horse; "likely"), else Y, as OBJ exporters write them.
    """
    if given:
        return UpChoice(given, "")
    if demo:
        return UpChoice(SEED_UP, "the built-in demo")
    if seed_dialect:
        return UpChoice(SEED_UP, "the seed's OBJ/MTL dialect")
    if cam_given:
        return UpChoice(SEED_UP, "-cam uses the seed's Z-up convention")
    kinds = list(dict.fromkeys(formats))
    if kinds and all(k in _DEFINITE for k in kinds):
        return UpChoice(MODEL_UP, "; ".join(_DEFINITE[k] for k in kinds), definite=True)
    what = describe_formats(kinds)
    if "PLY" not in kinds:
        if z_scan:
            return UpChoice(SEED_UP, "a scan or a set standing on a flat base or floor in the XY plane")
        if stands == SEED_UP:
            return UpChoice(SEED_UP, f"{what} that stands on its lowest points only with Z up (Y up, it would "
                                     "tip over); likely")
        return UpChoice(MODEL_UP, what)
    if hint is not None:
        return UpChoice(hint[0], f"{what}: {hint[1]}; sure")
    if z_scan:
        return UpChoice(SEED_UP, f"{what} standing on a flat base or floor in the XY plane; likely")
    if stands is not None:
        return UpChoice(stands, f"{what} that stands on its lowest points with {stands.upper()} up; likely")
    return UpChoice(MODEL_UP, f"{what}: PLY has no up convention and neither its header nor its shape tells; a guess")


# The studio's two forms (studio_look): with its own key light, or lit by the user's lights.
STUDIO_KEY, STUDIO_LIGHTS = "key", "lights"


def studio_look(given: bool | None, *, emitting: bool, user_lights: bool, seed_dialect: bool,
                sky_given: bool, env_given: bool = False) -> str:
    """The studio look's form, or "" for none: a ground and a soft grey sky under the scene's own
    materials, with the studio's key light (STUDIO_KEY) or, when the user brought lights (a sun,
    point or spot light: the command line's, the viewer's or a glTF file's; or an environment map,
    ``env_given``), with those as the key and no key light of the studio's (STUDIO_LIGHTS: the
    environment map then replaces the grey sky). ``--studio``/``--no-studio`` (``given``) win; else
    on for a scene with no emitting material (``emitting``) and no sky flag (an environment map is
    a light, not a sky flag), unless it is written in the seed's dialect (the seed's scenes are lit
    by the seed's sky). Whether an MTL file was read, and what kind its materials are, does not
    matter: an exporter's MTL has colours, not lights."""
    if given is False:
        return ""
    if given is None and (emitting or seed_dialect or (sky_given and not env_given)):
        return ""
    return STUDIO_LIGHTS if user_lights or env_given else STUDIO_KEY


def emits_light(scene) -> bool:
    """Whether some face or sphere of ``scene`` has an emitting material: an emission colour above
    zero or a texture in the emission slot (what makes the device scene compile its emitters)."""
    from warp_spt.scene.model import SLOT_EMISSION, TEX_PROC_BASE

    used = np.unique(np.concatenate([m.face_material for m in scene.meshes if len(m.indices)]
                                    + [scene.sphere_material]).astype(np.int64))
    mt = scene.materials
    tex = mt.tex[used][:, SLOT_EMISSION]
    return bool((mt.emission[used] > 0).any() or (tex >= 0).any() or (tex <= TEX_PROC_BASE).any())
