"""Scene files in: OBJ, MTL, glTF 2.0, PLY and light files to a host Scene. No Warp at import.

``tokens`` (the one guarded opener, lines and tokens), ``obj`` with its two scanners ``obj_scan`` and
``obj_bulk``, ``mtl``, ``gltf`` (glTF and GLB: meshes, nodes as instances, pbr materials, cameras,
punctual lights, animation), ``ply`` (ASCII and binary PLY), ``light_file`` (sun, point and spot
lights), ``loader`` (``load_scene``: materials and textures resolved, the Scene assembled and
validated) and ``templates`` (``{frame}`` file names). Image files are ``images/``'s.
"""
