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
