#!/bin/sh
# An installed libas serves programs outside its tree, as docs/embedding.md
# says: `cmake --install` into a fresh prefix, then tests/consumer/consumer.c
# built with find_package(libas) (as::as, as::as_static, and as::as under
# LIBAS_USE_STATIC_LIBS) and with pkg-config (the shared library, and libas.a
# with --static, whose Libs.private and Requires.private must be enough to
# link it); each program runs and prints the version it was built from, the
# triangle counts of two imported meshes (OpenMesh and Draco) and the known
# hits of its three triangles. With CUDA, examples/custom_kernel.cu is built
# against the installed device headers both ways too, and runs where a GPU is.
# Usage: installed_package_serves_cmake_and_pkg_config.sh CMAKE BUILD_DIR
#        SOURCE_DIR WORK_DIR VERSION LIBDIR CC HAS_CUDA [NVCC]
set -u
cmake=$1 build=$2 source=$3 work=$4 version=$5 libdir=$6 cc=$7 has_cuda=$8 nvcc=${9:-}
prefix=$work/prefix
rm -rf "$work" && mkdir -p "$work" || exit 1
failures=0
check() { # NAME CONDITION...
  name=$1; shift
  if "$@"; then echo "ok   $name"; else echo "FAIL $name"; failures=$((failures + 1)); return 1; fi
}
meshes="$source/tests/data/cube.obj $source/scenes/bunny.drc"
cat >"$work/expected.out" <<EXPECTED
libas $version (compiled against $version)
mesh 1: 12 triangles
mesh 2: 69451 triangles
structure: bvh2-child-bounds, 3 triangles
ray 0: prim 0 t 5 u 0.5 v 0.25
ray 1: prim 1 t 5 u 0.25 v 0.5
ray 2: prim 2 t 4 u 0.25 v 0.5
ray 3: miss
EXPECTED
runs_as_expected() { # PROGRAM
  # shellcheck disable=SC2086
  "$1" $meshes >"$1.out" 2>&1 && diff "$work/expected.out" "$1.out"
}

"$cmake" --install "$build" --prefix "$prefix" >"$work/install.out" 2>&1
check "cmake --install into a fresh prefix" test $? -eq 0
for f in include/as/as.h include/as/as_version.h include/as/device/bvh2_traverse.h \
         include/as/device/as_kernel_common.h "$libdir/libas.a" "$libdir/libas.so" \
         "$libdir/cmake/libas/libasConfig.cmake" "$libdir/pkgconfig/libas.pc"; do
  check "installed: $f" test -f "$prefix/$f"
done
check "the launcher's header is not installed" test ! -e "$prefix/include/as/device/trace_gpu.h"

# CMake: find_package(libas) from the prefix alone.
kernel_arg=""
[ "$has_cuda" = ON ] && [ -n "$nvcc" ] &&
  kernel_arg="-DCONSUMER_KERNEL_SOURCE=$source/examples/custom_kernel.cu -DCMAKE_CUDA_COMPILER=$nvcc"
# shellcheck disable=SC2086
"$cmake" -S "$source/tests/consumer" -B "$work/cmake" -DCMAKE_PREFIX_PATH="$prefix" \
  -DCMAKE_C_COMPILER="$cc" -DCMAKE_BUILD_TYPE=Release $kernel_arg >"$work/cmake.out" 2>&1 &&
  "$cmake" --build "$work/cmake" >>"$work/cmake.out" 2>&1
check "find_package(libas) project configures and builds" test $? -eq 0 || cat "$work/cmake.out"
check "as::as consumer prints the version and the known hits" runs_as_expected "$work/cmake/consumer"
check "as::as links the shared library" sh -c "readelf -d '$work/cmake/consumer' | grep -q 'NEEDED.*libas\.so'"
check "as::as_static consumer prints the version and the known hits" runs_as_expected "$work/cmake/consumer_static"
check "as::as_static needs no libas.so" sh -c "test -x '$work/cmake/consumer_static' && ! readelf -d '$work/cmake/consumer_static' | grep -q 'NEEDED.*libas\.so'"

# LIBAS_USE_STATIC_LIBS makes as::as the static library.
"$cmake" -S "$source/tests/consumer" -B "$work/cmake_static" -DCMAKE_PREFIX_PATH="$prefix" \
  -DCMAKE_C_COMPILER="$cc" -DCMAKE_BUILD_TYPE=Release -DLIBAS_USE_STATIC_LIBS=ON >"$work/cmake_static.out" 2>&1 &&
  "$cmake" --build "$work/cmake_static" --target consumer >>"$work/cmake_static.out" 2>&1
check "LIBAS_USE_STATIC_LIBS project configures and builds" test $? -eq 0 || cat "$work/cmake_static.out"
check "as::as with LIBAS_USE_STATIC_LIBS prints the version and the known hits" \
  runs_as_expected "$work/cmake_static/consumer"
check "as::as with LIBAS_USE_STATIC_LIBS needs no libas.so" \
  sh -c "test -x '$work/cmake_static/consumer' && ! readelf -d '$work/cmake_static/consumer' | grep -q 'NEEDED.*libas\.so'"

# pkg-config, with nothing but the prefix's libas.pc on the search path.
export PKG_CONFIG_PATH="$prefix/$libdir/pkgconfig"
check "pkg-config --modversion is the version" test "$(pkg-config --modversion libas)" = "$version"
# shellcheck disable=SC2046
"$cc" -std=c11 "$source/tests/consumer/consumer.c" $(pkg-config --cflags --libs libas) \
  -Wl,-rpath,"$prefix/$libdir" -o "$work/consumer_pc" >"$work/pc.out" 2>&1
check "pkg-config --cflags --libs builds the consumer" test $? -eq 0 || cat "$work/pc.out"
check "pkg-config consumer prints the version and the known hits" runs_as_expected "$work/consumer_pc"
# --static adds Libs.private and the Requires.private packages; the archive
# itself is named so that the linker cannot take libas.so instead.
static_libs=$(pkg-config --static --libs libas | sed "s|-las\\b|$prefix/$libdir/libas.a|")
# shellcheck disable=SC2046,SC2086
"$cc" -std=c11 "$source/tests/consumer/consumer.c" $(pkg-config --cflags libas) $static_libs \
  -o "$work/consumer_pc_static" >"$work/pc_static.out" 2>&1
check "pkg-config --static links libas.a with its private dependencies" test $? -eq 0 || cat "$work/pc_static.out"
check "static pkg-config consumer prints the version and the known hits" runs_as_expected "$work/consumer_pc_static"

if [ -n "$kernel_arg" ]; then
  check "find_package(libas) builds custom_kernel.cu on the installed device headers" \
    test -x "$work/cmake/custom_kernel"
  # shellcheck disable=SC2046
  "$nvcc" -arch=sm_90 "$source/examples/custom_kernel.cu" $(pkg-config --cflags --libs libas) \
    -Xlinker -rpath -Xlinker "$prefix/$libdir" -o "$work/custom_kernel_pc" >"$work/nvcc.out" 2>&1
  check "nvcc with pkg-config builds custom_kernel.cu" test $? -eq 0 || cat "$work/nvcc.out"
  "$prefix/bin/as-build" "$source/scenes/bunny.drc" -o "$work/bunny.asf" >/dev/null 2>&1
  for k in "$work/cmake/custom_kernel" "$work/custom_kernel_pc"; do
    "$k" "$work/bunny.asf" 128 128 >"$k.out" 2>&1
    rc=$?
    if [ $rc -eq 77 ]; then
      echo "skip $k: no CUDA device"
    else
      check "$(basename "$k") agrees with as_trace on the CPU" \
        grep -Eq "16384 of 16384 agree with as_trace on the CPU$" "$k.out"
    fi
  done
fi

[ "$failures" -eq 0 ]
