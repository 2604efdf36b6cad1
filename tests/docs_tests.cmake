# The documentation held to the tools (label docs): each man page against its
# tool's --help and exit status, rendered by groff, its examples run; and every
# command the guides show, run and its output compared with the one shown
# (tests/docs/run_doc_commands.py says how a page shows commands and output).
add_test(NAME docs_man_pages_match_tools
  COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/docs/check_man_pages.py $<TARGET_FILE_DIR:as-build> ${PROJECT_SOURCE_DIR})
set_tests_properties(docs_man_pages_match_tools PROPERTIES SKIP_RETURN_CODE 77 LABELS docs)

foreach(_page getting-started guide choosing)
  add_test(NAME docs_${_page}_commands_print_what_it_shows
    COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/docs/run_doc_commands.py ${PROJECT_SOURCE_DIR}/docs/${_page}.md
            $<TARGET_FILE_DIR:as-build> ${PROJECT_SOURCE_DIR} ${AS_SCENES_DIR})
  set_tests_properties(docs_${_page}_commands_print_what_it_shows PROPERTIES SKIP_RETURN_CODE 77 LABELS docs)
endforeach()
# The guide works on a scene of ../shared/scenes.
set_tests_properties(docs_guide_commands_print_what_it_shows PROPERTIES LABELS "docs;scenes")

# docs/embedding.md installs this build tree into a scratch prefix and builds
# tests/consumer against it through CMake and pkg-config, then runs the CPU
# examples of build/examples (--build links the tree as `build`). A
# sanitized libas cannot serve a consumer built as a user builds it
# (tests/packaging.cmake), and the examples must be there.
if(NOT AS_SANITIZE AND TARGET build_and_save)
  add_test(NAME docs_embedding_commands_print_what_it_shows
    COMMAND ${CMAKE_CURRENT_SOURCE_DIR}/docs/run_doc_commands.py --build ${PROJECT_BINARY_DIR}
            ${PROJECT_SOURCE_DIR}/docs/embedding.md $<TARGET_FILE_DIR:as-build> ${PROJECT_SOURCE_DIR}
            ${AS_SCENES_DIR})
  set_tests_properties(docs_embedding_commands_print_what_it_shows PROPERTIES
    SKIP_RETURN_CODE 77 LABELS docs)
endif()

# The API reference is generated from as.h (scripts/gen_api_doc.py): this
# fails when docs/api.md is not what the header gives, and when a function
# of the header has no comment at its declaration.
add_test(NAME docs_api_reference_is_current
  COMMAND ${PROJECT_SOURCE_DIR}/scripts/gen_api_doc.py --check ${PROJECT_SOURCE_DIR}/docs/api.md
          --header ${PROJECT_SOURCE_DIR}/libas/include/as/as.h)
set_tests_properties(docs_api_reference_is_current PROPERTIES LABELS docs)
