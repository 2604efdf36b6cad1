# tools/as-accuracy (label tools): both modes run on the CPU on the bundled
# bunny at 64 x 48 with two variants or two builders, then their JSON, CSV,
# markdown and SVG are checked (tests/cli/check_accuracy_outputs.py). The
# figures themselves come from the GPU host; these say the command works.
foreach(_mode accuracy build-sweep)
  add_test(NAME tools_as_accuracy_${_mode}
    COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/cli/check_accuracy_outputs.py ${_mode} $<TARGET_FILE_DIR:as-build>
            ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_BINARY_DIR}/as-accuracy-out)
  set_tests_properties(tools_as_accuracy_${_mode} PROPERTIES LABELS tools TIMEOUT 300)
endforeach()

# scripts/recompute_errors.py recomputes the error figures from the files
# alone (formats/SPEC.md, a float64 brute force, no libas code): on the
# bundled bunny, traced on the CPU with every ray verified by as-trace, its
# counts must equal as-trace's for both triangle tests and for a layout that
# keeps its triangles in TRIS (KD); and a hit file broken in known ways must
# be counted as broken, so that the check is seen to fail.
foreach(_case "bvh;watertight" "bvh;moller-trumbore" "kd;watertight")
  list(GET _case 0 _structure)
  list(GET _case 1 _intersector)
  add_test(NAME recompute_errors_bunny_${_structure}_${_intersector}
    COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/data/recompute/check_recompute.py match $<TARGET_FILE_DIR:as-build>
            ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_BINARY_DIR}/recompute-out ${_structure} ${_intersector})
  set_tests_properties(recompute_errors_bunny_${_structure}_${_intersector} PROPERTIES LABELS "tools;accuracy" TIMEOUT 300)
endforeach()
add_test(NAME recompute_errors_damaged_hits
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/data/recompute/check_recompute.py damaged $<TARGET_FILE_DIR:as-build>
          ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_BINARY_DIR}/recompute-out)
set_tests_properties(recompute_errors_damaged_hits PROPERTIES LABELS "tools;accuracy" TIMEOUT 300)
# scripts/recompute_published.sh against the bunny's published H100 rows.
add_test(NAME recompute_published_bunny
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/data/recompute/check_recompute.py published $<TARGET_FILE_DIR:as-build>
          ${PROJECT_SOURCE_DIR} ${CMAKE_CURRENT_BINARY_DIR}/recompute-out)
set_tests_properties(recompute_published_bunny PROPERTIES LABELS "tools;accuracy" TIMEOUT 300)
