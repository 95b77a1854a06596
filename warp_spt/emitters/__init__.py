"""Lights: a closed set of kinds, one module each, behind one interface, dispatched statically.

* ``base``: what a kind registers (``LightKind``) and the sample it returns (``LightSample``);
* ``triangle``, ``sphere``: area lights (emitting triangles of meshes, emitting spheres), whose
  radiance is the emission of their surface's material;
* ``environment``: an environment map, an infinite light importance-sampled from its texels;
* ``punctual``: the sun, point and spot lights, which no ray meets (delta lights in MIS);
* ``sky``: an infinite light, seen by rays that miss the scene, with its colours as a device array
  carrying gradients (the parameters ``sky.color``, ``sky.zenith``, ``sky.nadir``);
* ``registry``: the kinds (``KINDS``, from ``scene.families.LIGHT_KINDS``) and what they declare a
  scene and a sky need (``declare``, ``declare_sky``: ``Features.lights``);
* ``table``: the light table (each kind's entries, the choice among them by power, the device
  struct ``Lights``) and its host-side build (``light_table``);
* ``dispatch``: ``make_lights``, the interface the integrators call (``sample_li``, ``le``,
  ``pdf_li``, ``le_miss``, ``pdf_miss``) over the kinds a scene's features use, and ``detach_lights``
  for path replay.

Adding a kind: a module here, ``NAME.py``, exporting ``KIND`` (a ``LightKind("NAME", ...)``: its
``data`` struct, ``make`` with ``sample_li``/``pdf_li`` and, for an infinite light, ``le``, or for a
delta light ``radiance``; its host ``weigh``, ``upload`` and ``declare``/``declare_sky``), and its
name in ``scene.families.LIGHT_KINDS``. Nothing else names it: the table, the dispatch, the
features, the integrators' "are there lights to sample" (``Features.samples_lights``) and path
replay follow (tests/emitters/test_probe_kinds.py registers one of each shape and renders them).
"""

from __future__ import annotations

from warp_spt.emitters.base import KIND_PUNCTUAL, LightKind, LightSample
from warp_spt.emitters.dispatch import detach_lights, make_lights
from warp_spt.emitters.registry import KINDS, declare, declare_sky
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
from warp_spt.emitters.environment import EnvLight, env_pdf, env_radiance, environment_emits, sample_env


__all__ = ["EnvLight", "env_pdf", "env_radiance", "environment_emits", "sample_env", "declare", "declare_sky", "KINDS",
           "KIND_PUNCTUAL", "MAX_SPHERICAL", "MIN_SPHERICAL", "PARAMETER_KINDS", "PATHWISE_FIELDS",
           "LightKind", "LightSample", "Lights", "SkyLight", "alias_field", "alias_parameters",
           "detach_lights", "light_table", "make_lights", "parameter_arrays", "pick_entry", "reuse_pick",
           "sample_sky", "sky_density", "sky_emits", "sky_frame", "sky_pdf", "sky_radiance", "table_key"]
