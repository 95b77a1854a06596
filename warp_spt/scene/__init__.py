"""The host scene: what a render is about, as plain validated numpy data. No Warp here.

``model`` (Scene, MaterialTable, Material, ObjData, MeshData), ``camera`` (Camera, framing math),
``sky`` (Sky), ``validate`` (every rule a scene must meet before it reaches a kernel), ``limits``,
``errors`` (SceneError: file, line, message), ``studio`` (the generated studio look), ``recentre``
(far-from-origin scenes shifted in float64) and ``atlas_layout`` (the texture atlas's size rules).
"""
