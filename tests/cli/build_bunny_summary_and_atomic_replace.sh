#!/bin/sh
# as-build on the bundled bunny prints its summary and writes the file through
# a temporary file and a rename: nothing is left beside it, an existing file
# is replaced as a whole (a hard link to the old file keeps the old bytes),
# and a failed build leaves the existing file byte-identical.
. "$(dirname "$0")/cli_lib.sh"

ASF=$WORK/bunny.asf
run build "$TOOLS/as-build" "$BUNNY" -o "$ASF"
expect_rc "as-build bunny.drc" 0
S=$WORK/build.out
expect_grep "summary: triangles" "$S" "^triangles: +69451 \\(faces in file 69451, polygons fanned 0, zero-area 0 never hit\\)$"
expect_grep "summary: nodes and leaves" "$S" "^nodes: +[1-9][0-9]* inner, [1-9][0-9]* leaves \\(0 empty\\), [0-9]+\\.[0-9]+ triangles per leaf$"
expect_grep "summary: max depth" "$S" "^max depth: +[1-9][0-9]* \\(average leaf depth [0-9]+\\.[0-9]+\\)$"
expect_grep "summary: SAH cost" "$S" "^SAH cost: +[0-9]+\\.[0-9]+$"
expect_grep "summary: size in MB" "$S" "^size: +[0-9]+\\.[0-9]+ MB \\([0-9.]+ bytes per triangle\\)$"
expect_grep "summary: build ms" "$S" "^build: +[0-9]+\\.[0-9]+ ms$"
expect_grep "summary: written file" "$S" "^written: +$ASF$"
expect_eq "no output on stderr when it is not a terminal" "" "$(cat "$WORK/build.err")"
if [ -s "$ASF" ]; then ok "output file exists"; else fail "output file $ASF missing or empty"; fi
expect_eq "nothing but the output beside it" "build.err build.out bunny.asf" "$(ls "$WORK" | tr '\n' ' ' | sed 's/ $//')"

# A node count equal to the leaf count minus one is what a binary tree with
# no empty leaves has; the summary and the file agree on it.
nodes=$(sed -n 's/^nodes: *\([0-9]*\) inner.*/\1/p' "$S")
leaves=$(sed -n 's/^nodes: *[0-9]* inner, \([0-9]*\) leaves.*/\1/p' "$S")
expect_eq "leaves = inner nodes + 1" "$((nodes + 1))" "$leaves"

# Replace: keep a hard link to the old file and a copy of its bytes, build
# with other parameters over it.
cp "$ASF" "$WORK/old-copy.asf"
ln "$ASF" "$WORK/old-link.asf"
run rebuild "$TOOLS/as-build" "$BUNNY" -o "$ASF" --leaf-size 8
expect_rc "as-build over an existing file" 0
expect_same_file "the old file's inode still holds the old bytes (renamed over, not rewritten)" "$WORK/old-copy.asf" "$WORK/old-link.asf"
if cmp -s "$ASF" "$WORK/old-copy.asf"; then fail "the rebuilt file with --leaf-size 8 equals the old one"; else ok "the target now holds the new build"; fi
expect_grep "the new build has leaf size 8" "$WORK/rebuild.out" "^parameters: +leaf size 8,"
rm -f "$WORK/old-link.asf" "$WORK/old-copy.asf"

# A failed build over an existing file leaves it as it was, and no temporary file.
cp "$ASF" "$WORK/before.asf"
for bad in nan_coordinate.obj unparseable.off no_faces.obj; do
    run badbuild "$TOOLS/as-build" "$DATA/$bad" -o "$ASF"
    expect_rc "as-build $bad over an existing file" 3
    expect_same_file "existing file byte-identical after the failed build of $bad" "$WORK/before.asf" "$ASF"
done
leftover=$(ls "$WORK" | grep '\.tmp' || true)
expect_eq "no temporary file left after the failed builds" "" "$leftover"
finish
