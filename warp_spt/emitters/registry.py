"""The light kinds, one line each: their order is that of their entries in the light table and of
their fields in ``table.Lights``. A new kind is a module of this package exporting ``KIND`` (a
``base.LightKind``) and one line here."""

from __future__ import annotations

from warp_spt.emitters import envmap, punctual, sky, sphere, triangle

KINDS = (
    triangle.KIND,
    sphere.KIND,
    sky.KIND,
    envmap.KIND,
    punctual.KIND,
)
