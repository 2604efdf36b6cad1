#!/bin/sh
# With --no-checksum the section checksums are not there to catch damage; the
# structure's own checks still refuse a damaged file: child indices out of
# range, cycles, counts on inner nodes, source indices, non-finite vertices,
# triangles outside their leaf's box, META's kind, layout version and
# reserved fields. Exit 3 (5 for an unknown kind or newer layout version).
. "$(dirname "$0")/cli_lib.sh"
need_python

GOOD=$WORK/good.asf
build_bunny "$GOOD"
"$TOOLS/as-inspect" --format json "$GOOD" >"$WORK/good.json" || { echo "FAIL - as-inspect of the intact file"; exit 1; }
META=$(section_offset "$WORK/good.json" META)
BVH2=$(section_offset "$WORK/good.json" BVH2)
TRI4=$(section_offset "$WORK/good.json" TRI4)
NODES=$(json_get "$WORK/good.json" 'j["nodes"]')
TRIS=$(json_get "$WORK/good.json" 'j["triangles"]')
D=$WORK/damaged.asf

# refused_unchecked WHAT RC PATTERN: $D is refused by as-inspect --validate
# --no-checksum and by as-trace --no-checksum (which validates by default).
refused_unchecked() {
    expect_refused "as-inspect --validate --no-checksum: $1" "$D" "$2" "$3" "$TOOLS/as-inspect" --validate --no-checksum "$D"
    expect_refused "as-trace --no-checksum: $1" "$D" "$2" "$3" "$TOOLS/as-trace" --device cpu --no-checksum -W 16 -H 16 "$D"
}

# Node 0 is the root; its child[0] is at +48, child[1] at +52, count[0] at +56.
ROOT_CHILDREN=$(python3 -c 'import struct, sys; print("%d %d" % struct.unpack_from("<2i", open(sys.argv[1], "rb").read(), int(sys.argv[2]) + 48))' "$GOOD" "$BVH2")
C0=${ROOT_CHILDREN% *}
patch "$GOOD" "$D" $((BVH2 + 48)) "$(le32 "$NODES")"
refused_unchecked "root child index one past the last node" 3 "node 0 child 0 refers to node $NODES, outside \\[1, $NODES\\) \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BVH2 + 48)) "$(le32 2147483647)"
refused_unchecked "root child index 2^31-1" 3 "node 0 child 0 refers to node 2147483647, outside \\[1, $NODES\\) \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BVH2 + 48)) "$(le32 0)"
refused_unchecked "root child pointing at the root (cycle)" 3 "node 0 child 0 refers to node 0, outside \\[1, $NODES\\) \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BVH2 + 52)) "$(le32 "$C0")"
refused_unchecked "both root children the same node (shared subtree)" 3 "node $C0 is referenced twice \\(again by node 0\\).*\\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BVH2 + 56)) "$(le32 3)"
refused_unchecked "count on an inner child" 3 "node 0 child 0 is an inner node with count 3 \\(must be 0\\) \\[INVALID_STRUCTURE\\]"

# TRI4: v0.w is the source index; vertices must be finite and inside the leaf box.
patch "$GOOD" "$D" $((TRI4 + 12)) "$(le32 "$TRIS")"
refused_unchecked "source index one past the mesh" 3 "TRI4 triangle 0 refers to source triangle $TRIS but META says the mesh has $TRIS \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((TRI4 + 16)) 0000c07f
refused_unchecked "NaN vertex" 3 "TRI4 triangle 0 has a non-finite vertex \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((TRI4 + 32)) 0000807f
refused_unchecked "infinite vertex" 3 "TRI4 triangle 0 has a non-finite vertex \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" "$TRI4" 00002042
refused_unchecked "vertex moved outside its leaf's box" 3 "TRI4 triangle 0 lies outside the box of its leaf \\(node [0-9]+ child [01]\\) \\[INVALID_STRUCTURE\\]"

# META (SPEC.md 3.2).
patch "$GOOD" "$D" $((META + 36)) 00090000
refused_unchecked "unknown structure kind" 5 "structure kind 0x0900 cannot be traced by this build.*\\[UNSUPPORTED\\]"
patch "$GOOD" "$D" $((META + 40)) 02020000
refused_unchecked "unknown layout" 5 "layout 0x0202 cannot be traced by this build.*\\[UNSUPPORTED\\]"
patch "$GOOD" "$D" $((META + 44)) 02000000
refused_unchecked "newer layout version" 5 "layout version 2 is newer than this build reads \\(1\\) \\[VERSION\\]"
patch "$GOOD" "$D" $((META + 124)) 01000000
refused_unchecked "META reserved0 set" 3 "META section \\(offset $META\\) has non-zero reserved fields \\[CORRUPT\\]"
patch "$GOOD" "$D" $((META + 200)) 01
refused_unchecked "META reserved byte 200 set" 3 "META section \\(offset $META\\) has non-zero reserved fields \\[CORRUPT\\]"
patch "$GOOD" "$D" $((META + 68)) "$(le32 1)"
refused_unchecked "META triangle count below the source indices" 3 "refers to source triangle [0-9]+ but META says the mesh has 1 \\[INVALID_STRUCTURE\\]"

# as-trace has no way to skip validation: a damaged child index with the
# checksums off is still refused before any ray is traced.
patch "$GOOD" "$D" $((BVH2 + 48)) "$(le32 "$NODES")"
expect_refused "as-trace always validates" "$D" 3 "refers to node $NODES, outside .*\\[INVALID_STRUCTURE\\]" \
    "$TOOLS/as-trace" --device cpu --no-checksum -W 16 -H 16 "$D"
finish
