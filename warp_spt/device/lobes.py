"""Lobe flags: what kind of scattering a BSDF lobe does (pbrt-v4's BxDFFlags, in our own terms).

A lobe is diffuse, glossy or specular (a delta: no density), and reflects or transmits; a sample's
``flags`` are one kind OR one direction, a material's (``lobes`` of the material contract,
``warp_spt.bsdfs.common``) the union over its lobes at a point. Integrators decide from
these alone: light sampling and MIS where a lobe has a density (``LOBE_SMOOTH``), singular
continuation where the sampled lobe is ``LOBE_SPECULAR``, ray offsets through the surface where it
is ``LOBE_TRANSMISSION``. Plain ints, usable on the host and (as ``wp.constant``) in kernels.
"""

from __future__ import annotations

import warp as wp

LOBE_REFLECTION = wp.constant(1)
LOBE_TRANSMISSION = wp.constant(2)
LOBE_DIFFUSE = wp.constant(4)
LOBE_GLOSSY = wp.constant(8)
LOBE_SPECULAR = wp.constant(16)

LOBE_SMOOTH = wp.constant(4 | 8)          # lobes with a density: light sampling and MIS apply
LOBE_ALL = wp.constant(1 | 2 | 4 | 8 | 16)


def lobe_names(flags: int) -> str:
    """``flags`` in words, e.g. "diffuse|specular|reflection" (for messages and tests)."""
    names = [("diffuse", 4), ("glossy", 8), ("specular", 16), ("reflection", 1), ("transmission", 2)]
    return "|".join(n for n, bit in names if flags & bit) or "none"
