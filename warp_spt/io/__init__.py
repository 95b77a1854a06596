"""Files in and out: OBJ and MTL text to a host Scene, images to files. No Warp at import.

``tokens`` (the one guarded opener, lines and tokens), ``numbers`` (the one number syntax), ``obj``
with its two scanners ``obj_scan`` and ``obj_bulk``, ``mtl``, ``loader`` (load_scene: materials and
textures resolved, the Scene assembled and validated), ``images`` (tone maps, atomic writers) and
``templates`` (``{frame}`` file names).
"""
