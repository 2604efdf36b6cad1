# The BVH: builder promises and agreement with the double-precision reference.
as_add_test(test_bvh_build SOURCES test_bvh_build.c LABELS bvh)
as_add_test(test_bvh_reference_soups SOURCES test_bvh_reference.c ARGS soups LABELS bvh)
foreach(case closed anyhit)
  add_test(NAME test_bvh_reference_${case} COMMAND test_bvh_reference_soups ${case})
  set_tests_properties(test_bvh_reference_${case} PROPERTIES SKIP_RETURN_CODE 77 LABELS bvh)
endforeach()
# Real scenes from ../shared/scenes: one .ply.zst, one .drc, 100,000 rays each.
foreach(scene staircase2.ply.zst bunny.drc)
  add_test(NAME test_bvh_reference_${scene} COMMAND test_bvh_reference_soups scene ${scene} 100000)
  set_tests_properties(test_bvh_reference_${scene} PROPERTIES SKIP_RETURN_CODE 77 LABELS "bvh;scenes")
endforeach()
# GPU hits equal CPU hits (skips without a GPU).
as_add_test(test_gpu_agreement SOURCES test_gpu_agreement.c LABELS gpu)
as_add_test(test_verify SOURCES test_verify.c LABELS bvh)
# The builders' threads (task pool and parallel steps).
as_add_test(test_task_pool SOURCES test_task_pool.c LABELS bvh)
