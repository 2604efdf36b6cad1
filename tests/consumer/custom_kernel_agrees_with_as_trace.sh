#!/bin/sh
# examples/custom_kernel: a kernel built only on the installed device headers
# traces the bunny's BVH from the mapped file and gets, ray for ray, the hits
# of as_trace on the CPU, bit for bit. Skips (77) without a CUDA device.
# Usage: custom_kernel_agrees_with_as_trace.sh EXAMPLES_DIR SOURCE_DIR WORK_DIR
set -u
examples=$1 source=$2 work=$3
rm -rf "$work" && mkdir -p "$work" || exit 1
"$examples/build_and_save" "$work/bunny.asf" "$source/scenes/bunny.drc" >/dev/null || exit 1
"$examples/custom_kernel" "$work/bunny.asf" 512 512 >"$work/kernel.out" 2>&1
rc=$?
cat "$work/kernel.out"
[ $rc -eq 77 ] && exit 77
if [ $rc -ne 0 ]; then echo "FAIL custom_kernel exits $rc"; exit 1; fi
grep -Eq "^$work/bunny.asf: 262144 rays, [1-9][0-9]* hits; 262144 of 262144 agree with as_trace on the CPU$" \
  "$work/kernel.out" || { echo "FAIL every hit agrees"; exit 1; }
echo "ok   custom_kernel_agrees_with_as_trace"
