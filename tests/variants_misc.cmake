# BIH, octree and uniform grid variants (as_add_variant is defined in
# variants.cmake), and their builders' unit tests.
as_add_variant(bih bih bih bih)
as_add_variant(octree octree octree octree)
as_add_variant(grid grid grid grid)
as_add_test(test_misc_build_bih SOURCES test_misc_build.c ARGS bih LABELS "variants;misc")
foreach(k octree grid)
  add_test(NAME test_misc_build_${k} COMMAND test_misc_build_bih ${k})
  set_tests_properties(test_misc_build_${k} PROPERTIES SKIP_RETURN_CODE 77 LABELS "variants;misc")
endforeach()
as_add_stiff(bih bih bih bih)
as_add_stiff(octree octree octree octree)
as_add_stiff(grid grid grid grid)
