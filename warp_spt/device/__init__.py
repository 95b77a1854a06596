"""What every kernel reads: the device structs and ``Features`` (``structs``), the material and media
tables' device halves (``material_table``, ``media_table``), the texture atlas and procedural
textures (``textures``, ``proctex``), the lobe flags (``lobes``), the camera's primary rays
(``camera_rays``), sampling warps and the PCG stream (``sampling``), zero adjoints (``adjoint``), and
the layout constants host code shares (``layout``, Warp-free). Every device family imports from here;
nothing here imports a family."""
