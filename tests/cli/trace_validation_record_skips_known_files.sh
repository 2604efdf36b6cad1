#!/bin/sh
# as-trace --validation-record R: a file that passes validation has its
# fingerprint added to R, the same bytes are not walked again, and any other
# bytes (a damaged copy, another structure) are walked and, when damaged,
# refused as without a record. Without the option nothing changes.
. "$(dirname "$0")/cli_lib.sh"
need_python

GOOD=$WORK/good.asf
REC=$WORK/record
build_bunny "$GOOD"
"$TOOLS/as-inspect" --format json "$GOOD" >"$WORK/good.json" || { echo "FAIL - as-inspect of the intact file"; exit 1; }
BVH2=$(section_offset "$WORK/good.json" BVH2)
NODES=$(json_get "$WORK/good.json" 'j["nodes"]')

run first "$TOOLS/as-trace" --device cpu -W 16 -H 16 --validation-record "$REC" "$GOOD"
expect_rc "first trace with a record that does not exist yet" 0
expect_grep "the first trace validates and adds the fingerprint" "$WORK/first.out" \
    "^load: .*validation [0-9.]+, fingerprint [0-9.]+, added to $REC\\)"
expect_eq "the record holds one fingerprint line" 1 "$(grep -Ec '^[0-9a-f]{32}$' "$REC")"

run second "$TOOLS/as-trace" --device cpu -W 16 -H 16 --validation-record "$REC" "$GOOD"
expect_rc "second trace of the same file" 0
expect_grep "the second trace skips the walk" "$WORK/second.out" \
    "^load: .*validation skipped: fingerprint [0-9.]+, listed in $REC\\)"
expect_eq "the record still holds one line" 1 "$(wc -l <"$REC" | tr -d ' ')"

run json "$TOOLS/as-trace" --device cpu -W 16 -H 16 --format json --validation-record "$REC" "$GOOD"
expect_eq "JSON says the walk was skipped" skipped "$(json_get "$WORK/json.out" 'j["validation"]')"

# The same bytes under another name, and a copy without the build record
# (which the fingerprint leaves out), are the same structure.
cp "$GOOD" "$WORK/copy.asf"
run copy "$TOOLS/as-trace" --device cpu -W 16 -H 16 --validation-record "$REC" "$WORK/copy.asf"
expect_grep "a copy of the file is skipped too" "$WORK/copy.out" "validation skipped"
"$TOOLS/as-build" "$BUNNY" -o "$WORK/norecord.asf" -q --no-build-record || fail "as-build --no-build-record"
run norecord "$TOOLS/as-trace" --device cpu -W 16 -H 16 --validation-record "$REC" "$WORK/norecord.asf"
expect_grep "the same tree without its build record is skipped" "$WORK/norecord.out" "validation skipped"

# A damaged copy is another fingerprint: walked, refused, and not recorded.
patch "$GOOD" "$WORK/damaged.asf" $((BVH2 + 48)) "$(le32 "$NODES")"
expect_refused "a damaged copy (checksums off) is walked and refused" "$WORK/damaged.asf" 3 \
    "node 0 child 0 refers to node $NODES, outside \\[1, $NODES\\) \\[INVALID_STRUCTURE\\]" \
    "$TOOLS/as-trace" --device cpu --no-checksum -W 16 -H 16 --validation-record "$REC" "$WORK/damaged.asf"
expect_eq "the refused file added nothing" 1 "$(wc -l <"$REC" | tr -d ' ')"

# Another structure is walked and added; lines that are not fingerprints
# are ignored.
printf 'not a fingerprint\n\n' >>"$REC"
"$TOOLS/as-build" "$BUNNY" -o "$WORK/grid.asf" -q --structure grid || fail "as-build of a grid"
run grid "$TOOLS/as-trace" --device cpu -W 16 -H 16 --validation-record "$REC" "$WORK/grid.asf"
expect_grep "another structure is walked and added" "$WORK/grid.out" "validation [0-9.]+, fingerprint [0-9.]+, added to"
expect_eq "the record now lists two fingerprints" 2 "$(grep -Ec '^[0-9a-f]{32}$' "$REC")"
run grid2 "$TOOLS/as-trace" --device cpu -W 16 -H 16 --validation-record "$REC" "$WORK/grid.asf"
expect_grep "and skipped the next time" "$WORK/grid2.out" "validation skipped"

# A record that cannot be read is an error, not a reason to skip.
mkdir -p "$WORK/dir-record"
run dirrec "$TOOLS/as-trace" --device cpu -W 16 -H 16 --validation-record "$WORK/dir-record" "$GOOD"
expect_rc "a directory as the record" 2

# Without the option the load line is as before.
run plain "$TOOLS/as-trace" --device cpu -W 16 -H 16 "$GOOD"
expect_grep "without a record every trace validates" "$WORK/plain.out" "^load: .*\\(open and checks [0-9.]+, validation [0-9.]+\\)$"
finish
