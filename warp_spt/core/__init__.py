"""The device core: the host Scene uploaded to Warp, and the Warp functions that read it.

``device_scene`` (DeviceScene, Features: what the kernels specialise on), ``geometry`` and ``bvh``
(the top-level BVH over per-OBJ ``wp.Mesh`` BVHs and spheres), ``surface`` (the shading point),
``materials``, ``textures`` (the atlas), ``proctex`` (procedural textures), ``lights`` and
``sampling`` (warps from the square to directions and points).
"""
