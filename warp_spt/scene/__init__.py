"""The host scene: what a render is about, as plain validated numpy data. No Warp here.

``model`` (Scene, MaterialTable, Material, ObjData, MeshData), ``material_schema`` (one column per
material field: the table, validation, upload and parameters derive from it), ``camera`` (Camera,
framing math), ``sky`` (Sky), ``environment`` (environment maps' host model), ``lights`` (sun, point
and spot lights), ``media`` (participating media), ``proctex_registry`` (procedural textures'
declarations), ``validate`` (every rule a scene must meet before it reaches a kernel), ``limits``,
``numbers`` (the one number syntax), ``errors`` (SceneError: file, line, message), ``conventions``
(up axis and studio rules), ``studio`` (the generated studio look), ``normals`` (smooth normals by
angle), ``recentre`` (far-from-origin scenes shifted in float64) and ``atlas_layout`` (the texture
atlas's size rules).
"""
