# BVH variants (as_add_variant is defined in variants.cmake).
as_add_variant(bvh_sah bvh sah bvh2-child-bounds)
as_add_variant(bvh_midcut bvh midcut bvh2-child-bounds)
as_add_variant(bvh_sweep bvh sweep bvh2-child-bounds)
as_add_variant(bvh_sbvh bvh sbvh bvh2-child-bounds)
as_add_variant(bvh_sah_own bvh sah bvh2-own-bounds)
