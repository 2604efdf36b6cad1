#!/bin/sh
# META's node_count, leaf_count and max_depth describe the arrays
# (SPEC.md 3.2, 3.3: BVH2.element_count = META.node_count); a file whose META
# disagrees with them is damaged, and --validate says so even when the
# checksums are not verified.
. "$(dirname "$0")/cli_lib.sh"
need_python

GOOD=$WORK/good.asf
build_bunny "$GOOD"
"$TOOLS/as-inspect" --format json "$GOOD" >"$WORK/good.json" || { echo "FAIL - as-inspect of the intact file"; exit 1; }
META=$(section_offset "$WORK/good.json" META)
D=$WORK/damaged.asf
for field in "node_count 104 5 node" "leaf_count 112 5 leaf" "max_depth 120 2 depth"; do
    set -- $field
    patch "$GOOD" "$D" $((META + $2)) "$(le32 "$3")"
    run v "$TOOLS/as-inspect" --validate --no-checksum "$D"
    expect_rc "as-inspect --validate --no-checksum with META.$1 = $3" 3
    expect_grep "the message names the file and $4" "$WORK/v.err" "$D: .*$4"
done
finish
