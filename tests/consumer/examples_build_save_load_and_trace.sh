#!/bin/sh
# examples/build_and_save and examples/load_and_trace as docs/embedding.md
# runs them: the three-triangle scene is built, saved (the same bytes twice,
# without a build record) and loaded; the CPU trace draws the square's two
# halves with the small triangle in front of its centre, and the centre ray
# hits that triangle at the barycentrics its vertices give. The bundled bunny
# is imported, built and traced too, and a missing file is refused with the
# tools' exit code 2.
# Usage: examples_build_save_load_and_trace.sh EXAMPLES_DIR SOURCE_DIR WORK_DIR
set -u
examples=$1 source=$2 work=$3
rm -rf "$work" && mkdir -p "$work" || exit 1
failures=0
check() { # NAME CONDITION...
  name=$1; shift
  if "$@"; then echo "ok   $name"; else echo "FAIL $name"; failures=$((failures + 1)); fi
}

"$examples/build_and_save" "$work/tri.asf" >"$work/build.out" 2>&1
check "build_and_save without a mesh exits 0" test $? -eq 0
check "build_and_save reports the three triangles" grep -qx "mesh: 3 triangles, 7 vertices" "$work/build.out"
check "build_and_save builds the default structure" \
  grep -qx "structure: bvh, layout bvh2-child-bounds, builder sah" "$work/build.out"
check "build_and_save names the file it saved" grep -qx "saved: $work/tri.asf" "$work/build.out"
"$examples/build_and_save" "$work/tri2.asf" >/dev/null 2>&1
check "two saves of one scene are byte-identical" cmp -s "$work/tri.asf" "$work/tri2.asf"

"$examples/load_and_trace" "$work/tri.asf" >"$work/trace.out" 2>&1
check "load_and_trace exits 0" test $? -eq 0
# Triangle 0 is the square's lower right half, 1 its upper left half, 2 the
# small triangle (apex up) one unit in front of the centre.
cat >"$work/expected.out" <<EXPECTED
$work/tri.asf: bvh (bvh2-child-bounds), 3 triangles
.........................................
.........................................
.........................................
.........................................
.........................................
...............11111111110...............
...............11111111100...............
...............11111111100...............
...............11111110000...............
...............11111210000...............
...............11111200000...............
...............11112220000...............
...............11110000000...............
...............11000000000...............
...............10000000000...............
...............10000000000...............
.........................................
.........................................
.........................................
.........................................
.........................................
EXPECTED
head -n 22 "$work/trace.out" >"$work/picture.out"
check "load_and_trace draws the known picture" diff "$work/expected.out" "$work/picture.out"
check "the centre ray hits triangle 2 at u 0.25, v 0.5" \
  grep -Eqx "centre ray: triangle 2 at t = [0-9.]+, u = 0.25, v = 0.5" "$work/trace.out"
check "load_and_trace counts the hits of its picture" grep -qx "hits: 121 of 861 rays" "$work/trace.out"

"$examples/build_and_save" "$work/bunny.asf" "$source/scenes/bunny.drc" >"$work/bunny_build.out" 2>&1
check "build_and_save imports the bunny" grep -qx "mesh: 69451 triangles, 34834 vertices" "$work/bunny_build.out"
"$examples/load_and_trace" "$work/bunny.asf" 64 48 >"$work/bunny_trace.out" 2>&1
check "load_and_trace on the bunny exits 0" test $? -eq 0
check "the bunny fills the middle of the picture" grep -Eq "^centre ray: triangle [0-9]+ at t = " "$work/bunny_trace.out"
hits=$(sed -n 's/^hits: \([0-9]*\) of 3072 rays$/\1/p' "$work/bunny_trace.out")
check "some rays miss the bunny and some hit it" test "${hits:-0}" -gt 0 -a "${hits:-0}" -lt 3072

"$examples/load_and_trace" "$work/missing.asf" >"$work/missing.out" 2>&1
check "a missing file exits 2" test $? -eq 2
check "a missing file is named in the error" grep -q "missing.asf" "$work/missing.out"

[ "$failures" -eq 0 ]
