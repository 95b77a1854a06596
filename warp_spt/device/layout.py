"""The device layout's constants that host code needs too, Warp-free (the wide BVH's host build
reads them without importing Warp)."""

# Children per wide BVH node: one AVX register of float32 lanes, so a node's eight slab tests are a few
# vector instructions (benchmarks/bench_wide_bvh.py: 8 beat 4 for closest hits, about tied for shadow rays).
WIDTH = 8
