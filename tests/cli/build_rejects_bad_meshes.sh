#!/bin/sh
# as-build refuses bad input meshes with the documented exit code and a
# message on stderr that names the file and the problem, and writes nothing.
. "$(dirname "$0")/cli_lib.sh"

OUT=$WORK/out.asf
# expect_build_refused WHAT MESH RC PATTERN
expect_build_refused() {
    expect_refused "$1" "$2" "$3" "$4" "$TOOLS/as-build" "$2" -o "$OUT"
    if [ -e "$OUT" ]; then fail "$1: $OUT was written"; fi
    if [ -n "$(ls -A "$WORK" | grep -v '^refused\.')" ]; then fail "$1: left files behind: $(ls -A "$WORK")"; fi
}

expect_build_refused "missing file" "$DATA/no_such_mesh.obj" 2 "no such file.*\\[FILE_NOT_FOUND\\]"
expect_build_refused "unparseable mesh" "$DATA/unparseable.off" 3 "cannot parse as OFF.*\\[PARSE\\]"
expect_build_refused "NaN coordinate" "$DATA/nan_coordinate.obj" 3 "vertex 2 \\(line 4\\) has a non-finite coordinate \\(0, nan, 0\\) \\[INVALID_MESH\\]"
expect_build_refused "infinite coordinate" "$DATA/inf_coordinate.obj" 3 "vertex 1 \\(line 3\\) has a non-finite coordinate \\(inf, 0, 0\\) \\[INVALID_MESH\\]"
expect_build_refused "index out of range" "$DATA/index_out_of_range.obj" 3 "face 1 \\(line 7\\) refers to vertex [0-9]+ but the file has 4 vertices \\[INVALID_MESH\\]"
expect_build_refused "empty mesh" "$DATA/no_faces.obj" 3 "no triangles \\[INVALID_MESH\\]"
expect_build_refused "unknown extension" "$DATA/tri.mesh" 5 "unknown mesh format '\\.mesh'.*\\[UNSUPPORTED\\]"

# A directory that does not exist cannot take the output: I/O error.
expect_refused "output in a missing directory" "$WORK/no/such/dir/out.asf" 2 "\\[IO\\]" \
    "$TOOLS/as-build" "$DATA/tri.obj" -o "$WORK/no/such/dir/out.asf"

# The good fixture builds, so the refusals above are about the content.
run good "$TOOLS/as-build" "$DATA/tri.obj" -o "$OUT"
expect_rc "one-triangle mesh builds" 0
expect_grep "one-triangle mesh summary" "$WORK/good.out" "^triangles: +1 \\(faces in file 1,"
finish
