# Installation as a package: the CMake targets as::as, as::as_static and
# as::as_shared (find_package(libas)) and libas.pc for pkg-config. Included
# from the top-level CMakeLists.txt after libas/ is added.
include(CMakePackageConfigHelpers)

set(AS_INSTALL_CMAKEDIR ${CMAKE_INSTALL_LIBDIR}/cmake/libas)

install(EXPORT libasTargets NAMESPACE as:: DESTINATION ${AS_INSTALL_CMAKEDIR})

# Where the static CUDA runtime came from, so that a consumer of as::as_static
# finds the same toolkit when it has no nvcc of its own on PATH.
set(AS_CUDA_TOOLKIT_ROOT "")
if(AS_HAVE_CUDA)
  get_filename_component(AS_CUDA_TOOLKIT_ROOT "${CUDAToolkit_BIN_DIR}" DIRECTORY)
endif()

configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/libasConfig.cmake.in
  ${PROJECT_BINARY_DIR}/libasConfig.cmake INSTALL_DESTINATION ${AS_INSTALL_CMAKEDIR})
# 0.x: a minor version may change the API, so only the same minor matches.
write_basic_package_version_file(${PROJECT_BINARY_DIR}/libasConfigVersion.cmake
  COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/libasConfig.cmake ${PROJECT_BINARY_DIR}/libasConfigVersion.cmake
  DESTINATION ${AS_INSTALL_CMAKEDIR})

# pkg-config. The prefix is found from the .pc file's own place, so that an
# install moved elsewhere (cmake --install --prefix) still points at itself.
# Libs.private and Requires.private are what libas.a needs besides itself:
# the shared library carries them on its own.
if(IS_ABSOLUTE "${CMAKE_INSTALL_LIBDIR}")
  set(AS_PC_PREFIX "${CMAKE_INSTALL_PREFIX}")
  set(AS_PC_LIBDIR "${CMAKE_INSTALL_LIBDIR}")
else()
  file(RELATIVE_PATH _as_pc_up "/root/${CMAKE_INSTALL_LIBDIR}/pkgconfig" "/root")
  string(REGEX REPLACE "/$" "" _as_pc_up "${_as_pc_up}")
  set(AS_PC_PREFIX "\${pcfiledir}/${_as_pc_up}")
  set(AS_PC_LIBDIR "\${prefix}/${CMAKE_INSTALL_LIBDIR}")
endif()
if(IS_ABSOLUTE "${CMAKE_INSTALL_INCLUDEDIR}")
  set(AS_PC_INCLUDEDIR "${CMAKE_INSTALL_INCLUDEDIR}")
else()
  set(AS_PC_INCLUDEDIR "\${prefix}/${CMAKE_INSTALL_INCLUDEDIR}")
endif()
set(AS_PC_REQUIRES_PRIVATE "libzstd zlib draco openmesh")
# The C++ runtime for the two import shims (OpenMesh, Draco); the static
# CUDA runtime and what it needs for the launcher.
set(AS_PC_LIBS_PRIVATE "-lstdc++ -lm -pthread")
if(AS_HAVE_CUDA)
  string(APPEND AS_PC_LIBS_PRIVATE " -L${CUDAToolkit_LIBRARY_DIR} -lcudart_static -ldl -lrt")
endif()
configure_file(${PROJECT_SOURCE_DIR}/libas.pc.in ${PROJECT_BINARY_DIR}/libas.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/libas.pc DESTINATION ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
