# BVH variants (as_add_variant is defined in variants.cmake).
as_add_variant(bvh_sah bvh sah bvh2-child-bounds)
as_add_variant(bvh_midcut bvh midcut bvh2-child-bounds)
as_add_variant(bvh_sweep bvh sweep bvh2-child-bounds)
as_add_variant(bvh_sbvh bvh sbvh bvh2-child-bounds)
as_add_variant(bvh_sah_own bvh sah bvh2-own-bounds)
as_add_variant(bvh_sah_cwbvh bvh sah cwbvh)
as_add_variant(bvh_sbvh_cwbvh bvh sbvh cwbvh)
# Builder and layout promises (tests/test_bvh_builders.c): threads, cancel,
# coincident copies, flat scenes, split-plane quads, damaged copies, the
# layout round trip and the SAH cost against the binned build.
as_add_test(test_bvh_builders_midcut SOURCES test_bvh_builders.c ARGS midcut bvh2-child-bounds LABELS bvh)
foreach(case sweep:bvh2-child-bounds sbvh:bvh2-child-bounds sah:bvh2-own-bounds sbvh:bvh2-own-bounds sah:cwbvh
             sbvh:cwbvh)
  string(REPLACE ":" ";" parts ${case})
  list(GET parts 0 builder)
  list(GET parts 1 layout)
  string(REPLACE "bvh2-" "" short ${layout})
  string(REPLACE "-bounds" "" short ${short})
  add_test(NAME test_bvh_builders_${builder}_${short} COMMAND test_bvh_builders_midcut ${builder} ${layout})
  set_tests_properties(test_bvh_builders_${builder}_${short} PROPERTIES SKIP_RETURN_CODE 77 LABELS bvh)
endforeach()
# The stiff-case suite (tests/stiff_tests.cmake) on every BVH variant.
foreach(v midcut:bvh2-child-bounds sweep:bvh2-child-bounds sbvh:bvh2-child-bounds sah:bvh2-own-bounds sah:cwbvh
          sbvh:cwbvh)
  string(REPLACE ":" ";" parts ${v})
  list(GET parts 0 builder)
  list(GET parts 1 layout)
  if(layout STREQUAL "bvh2-own-bounds")
    as_add_stiff(bvh_${builder}_own bvh ${builder} ${layout})
  elseif(layout STREQUAL "cwbvh")
    as_add_stiff(bvh_${builder}_cwbvh bvh ${builder} ${layout})
  else()
    as_add_stiff(bvh_${builder} bvh ${builder} ${layout})
  endif()
endforeach()
