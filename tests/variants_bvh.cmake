# BVH variants (as_add_variant is defined in variants.cmake).
as_add_variant(bvh_sah bvh sah bvh2-child-bounds)
