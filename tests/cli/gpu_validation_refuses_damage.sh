#!/bin/sh
# On the GPU, as-trace validates a BVH2 after its upload and before any
# kernel reads it, with the CPU's checks: each damage that
# validate_catches_damage_without_checksums.sh shows the CPU refusing is
# refused here too (exit 3, the file and the node or triangle named), and
# intact files, SBVH leaves included, pass and are traced. Skipped without a
# usable GPU.
. "$(dirname "$0")/cli_lib.sh"
need_python

GOOD=$WORK/good.asf
build_bunny "$GOOD"
run probe "$TOOLS/as-trace" --device gpu -W 16 -H 16 "$GOOD"
if grep -q NO_DEVICE "$WORK/probe.err"; then
    echo "skipped: no usable CUDA device"
    exit 77
fi
expect_rc "as-trace --device gpu of the intact file" 0
expect_grep "it says the validation ran on the GPU" "$WORK/probe.out" "validation [0-9.]+ on the GPU"

SBVH=$WORK/sbvh.asf
"$TOOLS/as-build" "$BUNNY" --builder sbvh -o "$SBVH" -q || { echo "FAIL - as-build --builder sbvh"; exit 1; }
run sbvh "$TOOLS/as-trace" --device gpu -W 64 -H 64 "$SBVH"
expect_rc "an SBVH (leaf boxes hold clipped triangles) passes on the GPU" 0
expect_grep "and was validated there" "$WORK/sbvh.out" "validation [0-9.]+ on the GPU"

"$TOOLS/as-inspect" --format json "$GOOD" >"$WORK/good.json" || { echo "FAIL - as-inspect of the intact file"; exit 1; }
META=$(section_offset "$WORK/good.json" META)
BVH2=$(section_offset "$WORK/good.json" BVH2)
TRI4=$(section_offset "$WORK/good.json" TRI4)
NODES=$(json_get "$WORK/good.json" 'j["nodes"]')
TRIS=$(json_get "$WORK/good.json" 'j["triangles"]')
D=$WORK/damaged.asf

refused_on_gpu() {
    expect_refused "as-trace --device gpu --no-checksum: $1" "$D" "$2" "$3" \
        "$TOOLS/as-trace" --device gpu --no-checksum -W 16 -H 16 "$D"
}

ROOT_CHILDREN=$(python3 -c 'import struct, sys; print("%d %d" % struct.unpack_from("<2i", open(sys.argv[1], "rb").read(), int(sys.argv[2]) + 48))' "$GOOD" "$BVH2")
C0=${ROOT_CHILDREN% *}
patch "$GOOD" "$D" $((BVH2 + 48)) "$(le32 "$NODES")"
refused_on_gpu "root child index one past the last node" 3 "node 0 child 0 refers to a node outside \\[1, $NODES\\) \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BVH2 + 48)) "$(le32 2147483647)"
refused_on_gpu "root child index 2^31-1" 3 "node 0 child 0 refers to a node outside \\[1, $NODES\\) \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BVH2 + 48)) "$(le32 0)"
refused_on_gpu "root child pointing at the root (cycle)" 3 "node 0 child 0 refers to a node outside \\[1, $NODES\\) \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BVH2 + 52)) "$(le32 "$C0")"
refused_on_gpu "both root children the same node (shared subtree)" 3 "node $C0 is referenced twice.*\\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BVH2 + 56)) "$(le32 3)"
refused_on_gpu "count on an inner child" 3 "node 0 child 0 is an inner node with a count \\(must be 0\\) \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BVH2 + 0)) 0000c07f
refused_on_gpu "NaN in the root's box of child 0" 3 "node 0 child 0 has a non-finite or inverted box \\[INVALID_STRUCTURE\\]"

patch "$GOOD" "$D" $((TRI4 + 12)) "$(le32 "$TRIS")"
refused_on_gpu "source index one past the mesh" 3 "TRI4 triangle 0 refers to a source triangle beyond the $TRIS META says the mesh has \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((TRI4 + 16)) 0000c07f
refused_on_gpu "NaN vertex" 3 "TRI4 triangle 0 has a non-finite vertex \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((TRI4 + 32)) 0000807f
refused_on_gpu "infinite vertex" 3 "TRI4 triangle 0 has a non-finite vertex \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" "$TRI4" 00002042
refused_on_gpu "vertex moved outside its leaf's box" 3 "TRI4 triangle 0 lies outside the box of its leaf \\[INVALID_STRUCTURE\\]"

# META's counts against the arrays; the depth comes from pointer jumping.
patch "$GOOD" "$D" $((META + 104)) "$(le32 5)"
refused_on_gpu "META node count" 3 "META says 5 nodes but BVH2 holds $NODES \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((META + 112)) "$(le32 5)"
refused_on_gpu "META leaf count" 3 "META leaf count is 5 but the tree has [0-9]+ leaves \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((META + 120)) "$(le32 2)"
refused_on_gpu "META max depth" 3 "META says max depth 2 but the deepest leaf is at [0-9]+ \\[INVALID_STRUCTURE\\]"
finish
