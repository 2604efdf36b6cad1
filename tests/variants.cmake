# Every structure variant through tests/test_variants.c: synthetic cases
# against the brute force, then 100,000 rays of each real scene up to a
# million triangles against as_verify's reference (label scenes); the larger
# scenes under the label large (GPU host).
as_add_test(test_variants_bvh_sah SOURCES test_variants.c ARGS bvh sah bvh2-child-bounds LABELS variants)

# as_add_variant(NAME STRUCTURE BUILDER LAYOUT)
function(as_add_variant name structure builder layout)
  add_test(NAME variant_${name} COMMAND test_variants_bvh_sah ${structure} ${builder} ${layout})
  set_tests_properties(variant_${name} PROPERTIES SKIP_RETURN_CODE 77 LABELS variants)
  foreach(scene bunny.ply.zst staircase2.ply.zst staircase.ply.zst bathroom.drc bmw-m6.drc)
    add_test(NAME variant_${name}_${scene} COMMAND test_variants_bvh_sah ${structure} ${builder} ${layout} scene ${scene} 100000)
    set_tests_properties(variant_${name}_${scene} PROPERTIES SKIP_RETURN_CODE 77 LABELS "variants;scenes")
  endforeach()
  foreach(scene bathroom2.drc chopper-titan.drc sanmiguel.drc)
    add_test(NAME variant_${name}_${scene} COMMAND test_variants_bvh_sah ${structure} ${builder} ${layout} scene ${scene} 100000)
    set_tests_properties(variant_${name}_${scene} PROPERTIES SKIP_RETURN_CODE 77 LABELS "variants;large")
  endforeach()
endfunction()

# Each family's variants are listed in its own file.
include(${CMAKE_CURRENT_SOURCE_DIR}/variants_bvh.cmake OPTIONAL)
include(${CMAKE_CURRENT_SOURCE_DIR}/variants_kd.cmake OPTIONAL)
include(${CMAKE_CURRENT_SOURCE_DIR}/variants_misc.cmake OPTIONAL)
