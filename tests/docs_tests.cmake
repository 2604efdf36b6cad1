# The documentation held to the tools (label docs): each man page against its
# tool's --help and exit status, rendered by groff, its examples run.
add_test(NAME docs_man_pages_match_tools
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/docs/check_man_pages.py $<TARGET_FILE_DIR:as-build> ${PROJECT_SOURCE_DIR})
set_tests_properties(docs_man_pages_match_tools PROPERTIES SKIP_RETURN_CODE 77 LABELS docs)
