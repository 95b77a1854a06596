"""Acceleration and ray queries: the top-level BVH over meshes, instances and spheres (``tlas``, numpy),
each mesh's 8-wide BVH (``wide_bvh``, built by the Warp kernels of ``wide_build``) and its traversal
(``wide_traversal``), the scene's closest-hit and any-hit queries (``ray_queries``), and the surface at
a hit with its shading frame (``surface``)."""
