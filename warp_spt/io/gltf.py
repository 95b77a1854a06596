"""glTF 2.0 and GLB, read by the :mod:`warp_spt.gltf` package (a room of its own: the format has as many
sections as the other readers together); its public names, importable beside the other readers'."""

from warp_spt.gltf import *  # noqa: F401,F403
from warp_spt.gltf import __all__  # noqa: F401
