# Using libas from other code (docs/embedding.md): the examples run as their
# documentation says, and the installed package builds programs outside the
# tree through CMake and pkg-config. Scripts in tests/consumer.
if(TARGET build_and_save)
  add_test(NAME examples_build_save_load_and_trace
    COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/consumer/examples_build_save_load_and_trace.sh
            $<TARGET_FILE_DIR:build_and_save> ${PROJECT_SOURCE_DIR}
            ${CMAKE_CURRENT_BINARY_DIR}/examples_build_save_load_and_trace)
  set_tests_properties(examples_build_save_load_and_trace PROPERTIES LABELS examples)
endif()
if(TARGET custom_kernel)
  add_test(NAME examples_custom_kernel_agrees_with_as_trace
    COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/consumer/custom_kernel_agrees_with_as_trace.sh
            $<TARGET_FILE_DIR:custom_kernel> ${PROJECT_SOURCE_DIR}
            ${CMAKE_CURRENT_BINARY_DIR}/examples_custom_kernel)
  set_tests_properties(examples_custom_kernel_agrees_with_as_trace PROPERTIES
    SKIP_RETURN_CODE 77 LABELS "examples;gpu")
endif()

# A sanitized libas needs the sanitizer runtime in every program that links
# it, which a consumer built as a user builds it does not have: the package
# is tested in plain builds.
if(NOT AS_SANITIZE)
  set(_as_consumer_nvcc "")
  if(AS_HAVE_CUDA)
    set(_as_consumer_nvcc ${CMAKE_CUDA_COMPILER})
  endif()
  add_test(NAME packaging_installed_package_serves_cmake_and_pkg_config
    COMMAND sh ${CMAKE_CURRENT_SOURCE_DIR}/consumer/installed_package_serves_cmake_and_pkg_config.sh
            ${CMAKE_COMMAND} ${PROJECT_BINARY_DIR} ${PROJECT_SOURCE_DIR}
            ${CMAKE_CURRENT_BINARY_DIR}/packaging_consumer ${PROJECT_VERSION} ${CMAKE_INSTALL_LIBDIR}
            ${CMAKE_C_COMPILER} ${AS_HAVE_CUDA} ${_as_consumer_nvcc})
  set_tests_properties(packaging_installed_package_serves_cmake_and_pkg_config PROPERTIES LABELS packaging)
endif()
