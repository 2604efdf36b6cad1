# BIH, octree and uniform grid variants (as_add_variant is defined in
# variants.cmake), and their builders' unit tests.
as_add_variant(bih bih bih bih)
as_add_variant(octree octree octree octree)
as_add_variant(grid grid grid grid)
