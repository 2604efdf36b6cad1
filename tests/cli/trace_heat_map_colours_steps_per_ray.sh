#!/bin/sh
# as-trace --heat-map: a PNG of the requested size whose pixels are each
# primary ray's traversal steps on the viridis ramp (dark purple few, yellow
# many), scaled to the image's 99th percentile or to --heat-max, with the
# scale printed in text and JSON. A BVH and a uniform grid of the same bunny
# spend their steps in different places, so their heat maps differ: the BVH
# is hottest on the bunny's silhouette, the grid on the empty cells around it.
. "$(dirname "$0")/cli_lib.sh"
need_python

build_bunny "$WORK/bvh.asf"
"$TOOLS/as-build" "$BUNNY" -o "$WORK/grid.asf" --structure grid -q || { echo "FAIL - grid build failed"; exit 1; }

# pixels PNG EXPR: evaluates EXPR over the decoded image: w, h, and px[y][x]
# an (r, g, b) tuple (as-trace writes every row with filter 0).
pixels() { python3 - "$1" "$2" <<'PY'
import struct, sys, zlib
b = open(sys.argv[1], "rb").read()
w, h = struct.unpack(">II", b[16:24])
pos, idat = 8, b""
while pos < len(b):
    n, t = struct.unpack(">I4s", b[pos:pos + 8])
    if t == b"IDAT": idat += b[pos + 8:pos + 8 + n]
    pos += 12 + n
raw = zlib.decompress(idat)
row = 1 + 3 * w
assert all(raw[y * row] == 0 for y in range(h))
px = [[tuple(raw[y * row + 1 + 3 * x:y * row + 4 + 3 * x]) for x in range(w)] for y in range(h)]
print(eval(sys.argv[2]))
PY
}
PURPLE="(68, 1, 84)"
YELLOW="(253, 231, 37)"

for k in bvh grid; do
    run $k "$TOOLS/as-trace" --device cpu -W 64 -H 48 --heat-map "$WORK/$k.png" "$WORK/$k.asf"
    expect_rc "$k: as-trace --heat-map" 0
    expect_grep "$k: the scale is printed, from the 99th percentile" "$WORK/$k.out" \
        "^heat map: +$WORK/$k.png: steps per primary ray, 0 dark purple to [1-9][0-9]* yellow \\(99th percentile\\)$"
    expect_grep "$k: the counting pass ran (steps per ray reported)" "$WORK/$k.out" "^ +steps per ray [0-9.]+ \\(max [1-9][0-9]*\\)"
    expect_eq "$k: PNG signature and IHDR 64 x 48, 8-bit RGB" "True 64 48 8 2" \
        "$(python3 -c 'import struct, sys; b = open(sys.argv[1], "rb").read(); w, h, d, c = struct.unpack(">IIBB", b[16:26]); print(b[:8] == b"\x89PNG\r\n\x1a\n" and b[12:16] == b"IHDR", w, h, d, c)' "$WORK/$k.png")"
    expect_eq "$k: 99th percentile: about 1% of the pixels (the ramp's top) are yellow" "True" \
        "$(pixels "$WORK/$k.png" "0 < sum(p == $YELLOW for r in px for p in r) <= 0.02 * w * h + 1")"
done
expect_eq "BVH: a corner ray, far from the bunny, is near the cold end" "True" \
    "$(pixels "$WORK/bvh.png" "px[0][0][0] <= 72 and px[0][0][2] <= 140")"
expect_eq "BVH: the centre (on the bunny) is hotter than the corner" "True" \
    "$(pixels "$WORK/bvh.png" "px[h // 2][w // 2][1] > px[0][0][1] + 40")"
expect_eq "grid: rays through the empty cells above the bunny's back are hotter than one through the bunny" "True" \
    "$(pixels "$WORK/grid.png" "max(px[h // 4][x][1] for x in range(w // 2, 3 * w // 4)) > px[h // 2][w // 2][1] + 40")"
expect_eq "BVH and grid heat maps differ in most pixels" "True" \
    "$(python3 - "$WORK/bvh.png" "$WORK/grid.png" <<'PY'
import struct, sys, zlib
def dec(p):
    b = open(p, "rb").read(); pos, idat = 8, b""
    while pos < len(b):
        n, t = struct.unpack(">I4s", b[pos:pos + 8])
        if t == b"IDAT": idat += b[pos + 8:pos + 8 + n]
        pos += 12 + n
    return zlib.decompress(idat)
a, b = dec(sys.argv[1]), dec(sys.argv[2])
print(len(a) == len(b) and sum(x != y for x, y in zip(a, b)) > len(a) // 4)
PY
)"

# A fixed scale: every ray that took a step or more is yellow at --heat-max 1;
# the BVH's rays all visit the root, so the whole image is.
run fixed "$TOOLS/as-trace" --device cpu -W 64 -H 48 --heat-map "$WORK/fixed.png" --heat-max 1 "$WORK/bvh.asf"
expect_rc "as-trace --heat-max 1" 0
expect_grep "fixed scale printed" "$WORK/fixed.out" "^heat map: .*0 dark purple to 1 yellow \\(--heat-max\\)$"
expect_eq "--heat-max 1: every pixel yellow" "True" "$(pixels "$WORK/fixed.png" "all(p == $YELLOW for r in px for p in r)")"
run big "$TOOLS/as-trace" --device cpu -W 64 -H 48 --heat-map "$WORK/big.png" --heat-max 100000 "$WORK/bvh.asf"
expect_eq "--heat-max 100000: no pixel leaves the purple end of the ramp" "True" "$(pixels "$WORK/big.png" "all(p == $PURPLE for r in px for p in r)")"

run json "$TOOLS/as-trace" --device cpu -W 64 -H 48 --heat-map "$WORK/j.png" -f json "$WORK/grid.asf"
expect_rc "as-trace --heat-map -f json" 0
TEXT_SCALE=$(sed -n 's/^heat map: .* to \([0-9]*\) yellow.*/\1/p' "$WORK/grid.out")
expect_eq "JSON: the same 99th percentile scale as the text" "$TEXT_SCALE percentile 99" \
    "$(json_get "$WORK/json.out" '"%d %s" % (j["heat_max_steps"], j["heat_scale"])')"
expect_same_file "JSON and text runs write the same heat map" "$WORK/grid.png" "$WORK/j.png"

run rays "$TOOLS/as-trace" --device cpu --rays "$WORK/none.rays" --heat-map "$WORK/x.png" "$WORK/bvh.asf"
expect_rc "--heat-map with --rays (no camera, no pixels)" 1
run zero "$TOOLS/as-trace" --device cpu --heat-map "$WORK/x.png" --heat-max 0 "$WORK/bvh.asf"
expect_rc "--heat-max 0" 1
finish
