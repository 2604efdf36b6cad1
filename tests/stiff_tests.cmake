# The stiff-case suite on every registered variant (as_add_stiff in
# variants.cmake's families): the library generator's cases (test_stiff) and
# a second, independent set of the same kinds (test_stiff_more).
foreach(_stiff test_stiff test_stiff_more)
  add_executable(${_stiff} ${_stiff}.c)
  target_link_libraries(${_stiff} PRIVATE as_internal)
  target_compile_definitions(${_stiff} PRIVATE _POSIX_C_SOURCE=200809L AS_SCENES_DIR="${AS_SCENES_DIR}"
    AS_SOURCE_DIR="${PROJECT_SOURCE_DIR}" AS_BINARY_DIR="${PROJECT_BINARY_DIR}")
endforeach()
function(as_add_stiff name structure builder layout)
  add_test(NAME stiff_${name} COMMAND test_stiff ${structure} ${builder} ${layout})
  set_tests_properties(stiff_${name} PROPERTIES SKIP_RETURN_CODE 77 LABELS stiff)
  # The same cases traced by the CUDA kernels; skipped without a GPU.
  add_test(NAME gpu_stiff_${name} COMMAND test_stiff --gpu ${structure} ${builder} ${layout})
  set_tests_properties(gpu_stiff_${name} PROPERTIES SKIP_RETURN_CODE 77 LABELS "gpu;stiff")
  # The second set, on the CPU and the GPU alike.
  add_test(NAME stiff_more_${name} COMMAND test_stiff_more ${structure} ${builder} ${layout})
  set_tests_properties(stiff_more_${name} PROPERTIES SKIP_RETURN_CODE 77 LABELS stiff)
  add_test(NAME gpu_stiff_more_${name} COMMAND test_stiff_more --gpu ${structure} ${builder} ${layout})
  set_tests_properties(gpu_stiff_more_${name} PROPERTIES SKIP_RETURN_CODE 77 LABELS "gpu;stiff")
endfunction()
as_add_stiff(bvh_sah bvh sah bvh2-child-bounds)
# The generator itself (as_stiff_case_generate): defaults, refusals, the same
# bytes for the same seed, other meshes for another.
add_test(NAME stiff_generator COMMAND test_stiff --generator)
set_tests_properties(stiff_generator PROPERTIES LABELS stiff)
