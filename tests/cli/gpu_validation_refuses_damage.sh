#!/bin/sh
# On the GPU, as-trace validates a structure of every layout after its
# upload and before any kernel reads it, with the CPU's checks: each damage
# that validate_catches_damage_without_checksums.sh (BVH2), test_kd.c (KD,
# ropes), test_misc_build.c (BIH, octree, grid) and test_bvh_builders.c
# (cwbvh) show the CPU refusing is
# refused here too (exit 3, the file and the node, leaf, cell, PRIM entry or
# triangle named), and intact files, SBVH leaves included, pass and are
# traced. Skipped without a usable GPU.
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

# u32 FILE OFFSET: the little-endian uint32 there.
u32() { python3 -c 'import struct, sys; print(struct.unpack_from("<I", open(sys.argv[1], "rb").read(), int(sys.argv[2]))[0])' "$1" "$2"; }
# f32 X: X as a little-endian float32 in hex.
f32() { python3 -c 'import struct, sys; print(struct.pack("<f", float(sys.argv[1])).hex())' "$1"; }
NAN=0000c07f

# layout_file NAME BUILD-OPTIONS...: builds the bunny as $WORK/NAME.asf,
# checks that the intact file passes on the GPU (validated there) and sets
# GOOD to it and J to its as-inspect JSON.
layout_file() {
    _n=$1
    shift
    GOOD=$WORK/$_n.asf
    J=$WORK/$_n.json
    "$TOOLS/as-build" "$BUNNY" "$@" -o "$GOOD" -q || { echo "FAIL - as-build $*"; exit 1; }
    "$TOOLS/as-inspect" --format json "$GOOD" >"$J" || { echo "FAIL - as-inspect of $GOOD"; exit 1; }
    run "intact_$_n" "$TOOLS/as-trace" --device gpu -W 32 -H 32 "$GOOD"
    expect_rc "$_n: the intact file passes on the GPU" 0
    expect_grep "$_n: and was validated there" "$WORK/intact_$_n.out" "validation [0-9.]+ on the GPU"
}

# Own bounds (BVHO, 32 bytes a node: lo[3], hi[3], child at +24, count at
# +28; children child and child + 1 come after their parent).
layout_file own --layout bvh2-own-bounds
META=$(section_offset "$J" META)
BVHO=$(section_offset "$J" BVHO)
TRI4=$(section_offset "$J" TRI4)
RECORDS=$(json_get "$J" '[s for s in j["sections"] if s["tag"] == "BVHO"][0]["elements"]')
TRIS=$(json_get "$J" 'j["triangles"]')
C0=$(u32 "$GOOD" $((BVHO + 24)))
patch "$GOOD" "$D" $((BVHO + 24)) "$(le32 $((RECORDS - 1)))"
refused_on_gpu "own bounds: root's children past the last node" 3 "BVHO node 0's children are outside \\(0, $RECORDS\\) \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BVHO + 24)) "$(le32 0)"
refused_on_gpu "own bounds: root's children at the root (cycle)" 3 "BVHO node 0's children are outside \\(0, $RECORDS\\) \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BVHO + 28)) "$(le32 3)"
refused_on_gpu "own bounds: count on the root" 3 "BVHO node 0 is an inner node with a count \\(must be 0\\) \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BVHO + 32 * C0)) "$NAN"
refused_on_gpu "own bounds: NaN in the box of the root's first child" 3 "BVHO node $C0's box is non-finite, inverted or not inside its parent's box \\[INVALID_STRUCTURE\\]"
# Two inner nodes A < B < A's first child: B's children made A's.
SHARED=$(python3 -c '
import struct, sys
b = open(sys.argv[1], "rb").read(); off = int(sys.argv[2]); n = int(sys.argv[3])
child = [struct.unpack_from("<i", b, off + 32 * i + 24)[0] for i in range(n)]
for a in range(1, n):
    if child[a] > a + 1 and child[a + 1] >= 0:
        print(a + 1, child[a]); break' "$GOOD" "$BVHO" "$RECORDS")
patch "$GOOD" "$D" $((BVHO + 32 * ${SHARED% *} + 24)) "$(le32 "${SHARED#* }")"
refused_on_gpu "own bounds: two nodes share their children" 3 "BVHO node ${SHARED#* } is referenced twice.*\\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((TRI4 + 12)) "$(le32 "$TRIS")"
refused_on_gpu "own bounds: source index one past the mesh" 3 "TRI4 triangle 0 refers to a source triangle beyond the $TRIS META says the mesh has \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((TRI4 + 16)) "$NAN"
refused_on_gpu "own bounds: NaN vertex" 3 "TRI4 triangle 0 has a non-finite vertex \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" "$TRI4" 00002042
refused_on_gpu "own bounds: vertex moved outside its leaf's box" 3 "TRI4 triangle 0 lies outside the box of its leaf \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((META + 104)) "$(le32 5)"
refused_on_gpu "own bounds: META node count" 3 "META says 5 nodes but BVHO \\(inner nodes\\) holds [0-9]+ \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((META + 120)) "$(le32 2)"
refused_on_gpu "own bounds: META max depth" 3 "META says max depth 2 but the deepest leaf is at [0-9]+ \\[INVALID_STRUCTURE\\]"

# KD (KDN8, 8 bytes a node: word0 split or PRIM offset, word1 (above << 2) |
# axis or (leaf index << 2) | 3; PRIM lists: count, then triangles), the
# damages of test_kd.c's validation_rejects_damage, on both KD layouts.
kd_damages() {
    _l=$1
    META=$(section_offset "$J" META)
    KDN8=$(section_offset "$J" KDN8)
    PRIM=$(section_offset "$J" PRIM)
    TRIS=$(section_offset "$J" TRIS)
    KDNODES=$(json_get "$J" '[s for s in j["sections"] if s["tag"] == "KDN8"][0]["elements"]')
    INNER=$(json_get "$J" 'j["nodes"]')
    W1=$(u32 "$GOOD" $((KDN8 + 4)))
    AXIS=$((W1 & 3))
    # A non-empty leaf whose leaf index is not 0: node, PRIM offset, leaf index.
    LEAF=$(python3 -c '
import struct, sys
b = open(sys.argv[1], "rb").read(); off, n, prim = int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])
for i in range(n):
    w0, w1 = struct.unpack_from("<II", b, off + 8 * i)
    if w1 & 3 == 3 and w1 >> 2 != 0 and struct.unpack_from("<I", b, prim + 4 * w0)[0] > 0:
        print(i, w0, w1 >> 2); break' "$GOOD" "$KDN8" "$KDNODES" "$PRIM")
    set -- $LEAF
    L=$1 LOFF=$2
    patch "$GOOD" "$D" $((KDN8 + 4)) "$(le32 $((((KDNODES + 5) << 2) | AXIS)))"
    refused_on_gpu "$_l: above child past the end" 3 "node 0 has children outside \\(0, $KDNODES\\) or out of order \\[INVALID_STRUCTURE\\]"
    patch "$GOOD" "$D" $((KDN8 + 4)) "$(le32 "$AXIS")"
    refused_on_gpu "$_l: above child pointing at the root" 3 "node 0 has children outside \\(0, $KDNODES\\) or out of order \\[INVALID_STRUCTURE\\]"
    patch "$GOOD" "$D" "$KDN8" "$(f32 1e9)"
    refused_on_gpu "$_l: split outside the node box" 3 "node 0's split is not finite and strictly inside its box \\[INVALID_STRUCTURE\\]"
    patch "$GOOD" "$D" "$KDN8" "$NAN"
    refused_on_gpu "$_l: split NaN" 3 "node 0's split is not finite and strictly inside its box \\[INVALID_STRUCTURE\\]"
    patch "$GOOD" "$D" $((KDN8 + 8 * L)) f0ffffff
    refused_on_gpu "$_l: leaf list past PRIM" 3 "leaf node $L: PRIM offset outside the [0-9]+ entries \\[INVALID_STRUCTURE\\]"
    patch "$GOOD" "$D" $((PRIM + 4 * LOFF)) ffffff7f
    refused_on_gpu "$_l: leaf count past PRIM" 3 "leaf node $L: its triangles run past the [0-9]+ PRIM entries \\[INVALID_STRUCTURE\\]"
    patch "$GOOD" "$D" $((PRIM + 4 * LOFF + 4)) "$(le32 1073741824)"
    refused_on_gpu "$_l: triangle index past TRIS" 3 "leaf node $L refers to a triangle outside the $TRIS_COUNT of TRIS \\[INVALID_STRUCTURE\\]"
    patch "$GOOD" "$D" $((KDN8 + 8 * L + 4)) 03000000
    refused_on_gpu "$_l: duplicate leaf index" 3 "leaf index 0 is used by two leaf nodes \\[INVALID_STRUCTURE\\]"
    patch "$GOOD" "$D" $((TRIS + 3 * 48 + 12)) "$(le32 4)"
    refused_on_gpu "$_l: TRIS source index" 3 "TRIS triangle 3 does not carry its own source index \\[INVALID_STRUCTURE\\]"
    patch "$GOOD" "$D" $((TRIS + 2 * 48 + 20)) "$NAN"
    refused_on_gpu "$_l: TRIS NaN vertex" 3 "TRIS triangle 2 has a non-finite vertex \\[INVALID_STRUCTURE\\]"
    patch "$GOOD" "$D" $((META + 104)) "$(le32 $((INNER + 1)))"
    refused_on_gpu "$_l: META node count" 3 "META says $((INNER + 1)) inner nodes but the tree has $INNER \\[INVALID_STRUCTURE\\]"
    patch "$GOOD" "$D" $((META + 92)) "$NAN"
    refused_on_gpu "$_l: META scene box NaN" 3 "META scene box is not finite or inverted on axis 0 \\[INVALID_STRUCTURE\\]"
}
layout_file kd --structure kd
TRIS_COUNT=$(json_get "$J" 'j["triangles"]')
kd_damages kd-standard
layout_file kdropes --structure kd --layout kd-ropes
kd_damages kd-ropes
# The ropes and leaf boxes (24 bytes a leaf) must be the tree's.
KDRP=$(section_offset "$J" KDRP)
KDLB=$(section_offset "$J" KDLB)
R=$(u32 "$GOOD" $((KDRP + 24)))
if [ "$R" = 0 ]; then patch "$GOOD" "$D" $((KDRP + 24)) "$(le32 1)"; else patch "$GOOD" "$D" $((KDRP + 24)) "$(le32 0)"; fi
refused_on_gpu "kd-ropes: rope to another node" 3 "KDRP leaf 1: ropes differ from the ones the tree defines \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((KDRP + 4)) "$(le32 2147483632)"
refused_on_gpu "kd-ropes: rope past the end" 3 "KDRP leaf 0: ropes differ from the ones the tree defines \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((KDLB + 12)) "$(f32 0.123)"
refused_on_gpu "kd-ropes: leaf box changed" 3 "KDLB leaf 0: box differs from the one the tree defines \\[INVALID_STRUCTURE\\]"

# PRIM and TRIS of the BIH, octree and grid (test_misc_build.c).
spatial_damages() {
    _l=$1
    PRIM=$(section_offset "$J" PRIM)
    TRIS=$(section_offset "$J" TRIS)
    patch "$GOOD" "$D" "$PRIM" ffffff7f
    refused_on_gpu "$_l: PRIM entry out of range" 3 "PRIM entry 0 refers to a triangle outside the [0-9]+ of TRIS \\[INVALID_STRUCTURE\\]"
    patch "$GOOD" "$D" $((TRIS + 48 + 12)) "$(le32 0)"
    refused_on_gpu "$_l: TRIS source index" 3 "TRIS triangle 1 does not carry its own source index \\[INVALID_STRUCTURE\\]"
}

# BIH (BIHN, 12 bytes a node: clip[2], info = (child or PRIM start << 2) | axis).
layout_file bih --structure bih
spatial_damages bih
BIHN=$(section_offset "$J" BIHN)
BNODES=$(json_get "$J" '[s for s in j["sections"] if s["tag"] == "BIHN"][0]["elements"]')
INFO=$(u32 "$GOOD" $((BIHN + 8)))
patch "$GOOD" "$D" $((BIHN + 8)) "$(le32 $((((BNODES + 5) << 2) | (INFO & 3))))"
refused_on_gpu "bih: child out of range" 3 "node 0's children are outside \\[1, $BNODES\\) \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BIHN + 8)) "$(le32 0)"
refused_on_gpu "bih: child loops to the root" 3 "node 0's children are outside \\[1, $BNODES\\) \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((BIHN + 4)) "$NAN"
refused_on_gpu "bih: NaN clip plane" 3 "node 0 has a non-finite clip plane \\[INVALID_STRUCTURE\\]"
BLEAF=$(python3 -c '
import struct, sys
b = open(sys.argv[1], "rb").read(); off, n = int(sys.argv[2]), int(sys.argv[3])
print(next(i for i in range(n) if struct.unpack_from("<I", b, off + 12 * i + 8)[0] & 3 == 3))' "$GOOD" "$BIHN" "$BNODES")
patch "$GOOD" "$D" $((BIHN + 12 * BLEAF)) "$(le32 1000000)"
refused_on_gpu "bih: leaf past PRIM" 3 "leaf node $BLEAF: its PRIM range runs outside the [0-9]+ entries \\[INVALID_STRUCTURE\\]"

# Octree (OCTH: lo[3], size; OCTN, 8 bytes a node: first, count; count
# 0xffffffff for an inner node).
layout_file octree --structure octree
spatial_damages octree
OCTH=$(section_offset "$J" OCTH)
OCTN=$(section_offset "$J" OCTN)
ONODES=$(json_get "$J" '[s for s in j["sections"] if s["tag"] == "OCTN"][0]["elements"]')
patch "$GOOD" "$D" "$OCTN" "$(le32 0)"
refused_on_gpu "octree: children before the parent" 3 "node 0's children are not after it inside the $ONODES nodes \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" "$OCTN" "$(le32 $((ONODES - 4)))"
refused_on_gpu "octree: children past the end" 3 "node 0's children are not after it inside the $ONODES nodes \\[INVALID_STRUCTURE\\]"
OLEAF=$(python3 -c '
import struct, sys
b = open(sys.argv[1], "rb").read(); off, n = int(sys.argv[2]), int(sys.argv[3])
print(next(i for i in range(n) if struct.unpack_from("<I", b, off + 8 * i + 4)[0] != 0xFFFFFFFF))' "$GOOD" "$OCTN" "$ONODES")
patch "$GOOD" "$D" $((OCTN + 8 * OLEAF + 4)) "$(le32 1000000)"
refused_on_gpu "octree: leaf past PRIM" 3 "leaf node $OLEAF: its PRIM range runs outside the [0-9]+ entries \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((OCTH + 12)) "$NAN"
refused_on_gpu "octree: NaN root cube" 3 "OCTH root cube is not finite with a positive edge \\[INVALID_STRUCTURE\\]"

# Grid (GRDH: lo[3], hi[3], cell[3], inv_cell[3], dims[3] at +48; GRDC:
# cells + 1 offsets).
layout_file grid --structure grid
spatial_damages grid
GRDH=$(section_offset "$J" GRDH)
GRDC=$(section_offset "$J" GRDC)
OFFSETS=$(json_get "$J" '[s for s in j["sections"] if s["tag"] == "GRDC"][0]["elements"]')
patch "$GOOD" "$D" $((GRDH + 52)) "$(le32 0)"
refused_on_gpu "grid: zero cells on an axis" 3 "GRDH axis 1 has 0 cells \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((GRDH + 48)) "$(le32 $(($(u32 "$GOOD" $((GRDH + 48))) + 1)))"
refused_on_gpu "grid: more cells than offsets" 3 "GRDH axis 0: cell size and inverse disagree .*\\[INVALID_STRUCTURE\\]"
LAST=$(u32 "$GOOD" $((GRDC + 4 * (OFFSETS - 1))))
patch "$GOOD" "$D" $((GRDC + 4 * (OFFSETS / 2))) "$(le32 $((LAST + 7)))"
refused_on_gpu "grid: decreasing offsets" 3 "GRDC offset of cell $((OFFSETS / 2)) decreases \\[INVALID_STRUCTURE\\]"

# Compressed wide BVH (CWBV, 80 bytes a node: p[3] at +0, e[3] at +12, imask
# at +15, child_base at +16, tri_base at +20, meta[8] at +24, qlo at +32, qhi
# at +56; node 0 is the root).
layout_file cwbvh --builder sbvh --layout cwbvh
META=$(section_offset "$J" META)
CWBV=$(section_offset "$J" CWBV)
CNODES=$(json_get "$J" '[s for s in j["sections"] if s["tag"] == "CWBV"][0]["elements"]')
patch "$GOOD" "$D" "$CWBV" "$NAN"
refused_on_gpu "cwbvh: NaN grid origin" 3 "CWBV node 0 has a non-finite origin \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((CWBV + 12)) ff
refused_on_gpu "cwbvh: exponent 255" 3 "CWBV node 0 has an exponent outside \\[1, 254\\] \\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((CWBV + 16)) "$(le32 "$CNODES")"
refused_on_gpu "cwbvh: children past the last node" 3 "CWBV node 0 has a child outside .*\\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((CWBV + 16)) "$(le32 0)"
refused_on_gpu "cwbvh: the root its own child (cycle)" 3 "CWBV node 0 has a child outside .*\\[INVALID_STRUCTURE\\]"
patch "$GOOD" "$D" $((META + 104)) "$(le32 5)"
refused_on_gpu "cwbvh: META node count" 3 "META says 5 nodes but CWBV holds $CNODES \\[INVALID_STRUCTURE\\]"
finish
