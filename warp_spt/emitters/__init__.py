"""Lights: a closed set of kinds, one module each, behind one interface, dispatched statically.

* ``base``: what a kind registers (``LightKind``) and the sample it returns (``LightSample``);
* ``triangle``, ``sphere``: area lights (emitting triangles of meshes, emitting spheres), whose
  radiance is the emission of their surface's material;
* ``envmap``: an environment map, an infinite light importance-sampled from its texels;
* ``punctual``: the sun, point and spot lights, which no ray meets (delta lights in MIS);
* ``sky``: an infinite light, seen by rays that miss the scene, with its colours as a device array
  carrying gradients (the parameters ``sky.color``, ``sky.zenith``, ``sky.nadir``);
* ``registry``: the kinds, one line each (``KINDS``);
* ``table``: the light table (each kind's entries, the choice among them by power, the device
  struct ``Lights``) and its host-side build (``light_table``);
* ``dispatch``: ``make_lights``, the interface the integrators call (``sample_li``, ``le``,
  ``pdf_li``, ``le_miss``, ``pdf_miss``) over the kinds a scene's features use, and ``detach_lights``
  for path replay.

Adding a kind (an environment map, say): a module here exporting ``KIND`` (its ``data`` struct,
``sample_li``/``pdf_li`` and, for an infinite light, ``le``; its host ``weigh`` and ``upload``)
and one line in ``registry.KINDS``.
"""

from __future__ import annotations

from warp_spt.emitters.base import KIND_PUNCTUAL, LightKind, LightSample
from warp_spt.emitters.dispatch import detach_lights, make_lights
from warp_spt.emitters.registry import KINDS
from warp_spt.emitters.sky import (
    SkyLight,
    sample_sky,
    sky_density,
    sky_emits,
    sky_frame,
    sky_pdf,
    sky_radiance,
)
from warp_spt.emitters.table import (
    PARAMETER_KINDS,
    PATHWISE_FIELDS,
    Lights,
    alias_field,
    alias_parameters,
    light_table,
    parameter_arrays,
    pick_entry,
    reuse_pick,
    table_key,
)
from warp_spt.emitters.triangle import MAX_SPHERICAL, MIN_SPHERICAL
from warp_spt.emitters.envmap import EnvLight, env_pdf, env_radiance, environment_emits, sample_env
from warp_spt.scene.sky import SKY_ENVIRONMENT


def sky_features(sky) -> dict:
    """The feature flags a sky sets (``Features.sky``: some infinite light emits; ``environment``:
    it is an environment map, whose code is compiled in)."""
    env = sky.kind == SKY_ENVIRONMENT
    return {"sky": sky_emits(sky) or environment_emits(sky), "environment": env}

__all__ = ["EnvLight", "env_pdf", "env_radiance", "environment_emits", "sample_env", "sky_features", "KINDS", "KIND_PUNCTUAL", "MAX_SPHERICAL", "MIN_SPHERICAL", "PARAMETER_KINDS", "PATHWISE_FIELDS", "LightKind", "LightSample", "Lights", "SkyLight",
           "alias_field", "alias_parameters", "detach_lights", "light_table", "make_lights", "parameter_arrays", "pick_entry",
           "reuse_pick", "sample_sky", "sky_density", "sky_emits", "sky_frame", "sky_pdf", "sky_radiance",
           "table_key"]
