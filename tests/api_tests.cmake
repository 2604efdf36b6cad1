# Public-API queries beyond tracing: closest points on the BVH family, the
# memory estimate before a build, loading from a caller's mapped region.
as_add_test(test_closest_point SOURCES test_closest_point.c LABELS bvh)
as_add_test(test_load_mapped SOURCES test_load_mapped.c LABELS formats)
as_add_test(test_memory_estimate SOURCES test_memory_estimate.c LABELS bvh)
as_add_test(test_fingerprint SOURCES test_fingerprint.c LABELS formats)
