# No data lost: writes over an existing file are atomic, and a full disk, a
# failed write, sync or rename, or a killed as-build leave the previous file
# intact (label hardening).
as_add_test(test_atomic_write SOURCES test_atomic_write.c LABELS "formats;hardening")

add_test(NAME cli_build_killed_leaves_previous_file
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/cli/build_killed_leaves_previous_file.sh
          $<TARGET_FILE_DIR:as-build> ${PROJECT_SOURCE_DIR} ${AS_SCENES_DIR})
set_tests_properties(cli_build_killed_leaves_previous_file PROPERTIES
  SKIP_RETURN_CODE 77 LABELS "cli;hardening")
