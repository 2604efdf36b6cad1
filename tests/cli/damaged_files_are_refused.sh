#!/bin/sh
# Truncated and corrupted copies of a built file are refused by
# `as-inspect --validate` and `as-trace --device cpu`, with exit 3 (5 for a
# newer version) and a message that names the file and what is wrong.
. "$(dirname "$0")/cli_lib.sh"
need_python

GOOD=$WORK/good.asf
# The container's own checks, on a file of three sections (no build record).
"$TOOLS/as-build" "$BUNNY" -o "$GOOD" -q --no-build-record || { echo "FAIL - as-build of $BUNNY failed, cannot go on"; exit 1; }
"$TOOLS/as-inspect" --format json "$GOOD" >"$WORK/good.json" || { echo "FAIL - as-inspect of the intact file"; exit 1; }
SIZE=$(wc -c <"$GOOD")
META=$(section_offset "$WORK/good.json" META)
BVH2=$(section_offset "$WORK/good.json" BVH2)
TRI4=$(section_offset "$WORK/good.json" TRI4)

# refused_by_both WHAT FILE RC PATTERN
refused_by_both() {
    expect_refused "as-inspect --validate: $1" "$2" "$3" "$4" "$TOOLS/as-inspect" --validate "$2"
    expect_refused "as-trace --device cpu: $1" "$2" "$3" "$4" "$TOOLS/as-trace" --device cpu -W 16 -H 16 "$2"
}

# The intact file passes both, so the refusals below come from the damage.
run intact "$TOOLS/as-inspect" --validate "$GOOD"
expect_rc "as-inspect --validate on the intact file" 0
run intact "$TOOLS/as-trace" --device cpu -W 16 -H 16 "$GOOD"
expect_rc "as-trace --device cpu on the intact file" 0

# Truncations.
for n in 0 10 63; do
    head -c "$n" "$GOOD" >"$WORK/cut$n.asf"
    refused_by_both "truncated to $n bytes" "$WORK/cut$n.asf" 3 "file is $n bytes, shorter than the 64-byte header \\[CORRUPT\\]"
done
for n in 64 $((SIZE / 2)) $((SIZE - 1)); do
    head -c "$n" "$GOOD" >"$WORK/cut$n.asf"
    refused_by_both "truncated to $n bytes" "$WORK/cut$n.asf" 3 "truncated: header says $SIZE bytes, file has $n \\[CORRUPT\\]"
done
cp "$GOOD" "$WORK/long.asf" && printf 'x' >>"$WORK/long.asf"
refused_by_both "one byte appended" "$WORK/long.asf" 3 "file_size at offset 32 says $SIZE bytes, file has $((SIZE + 1)) \\[CORRUPT\\]"

# Header (offsets from formats/SPEC.md 2.2).
patch "$GOOD" "$WORK/h.asf" 0 flip
refused_by_both "magic damaged" "$WORK/h.asf" 3 "not an .asf file \\(bad magic at offset 0\\) \\[CORRUPT\\]"
patch "$GOOD" "$WORK/h.asf" 8 0200
refused_by_both "major version 2" "$WORK/h.asf" 5 "container version 2\\.1 is newer than this reader \\(1\\.x\\) \\[VERSION\\]"
patch "$GOOD" "$WORK/h.asf" 8 0000
refused_by_both "major version 0" "$WORK/h.asf" 3 "container version 0\\.1 at offset 8 was never defined \\[CORRUPT\\]"
patch "$GOOD" "$WORK/h.asf" 12 flip
refused_by_both "header_size damaged" "$WORK/h.asf" 3 "header_size [0-9]+ at offset 12 .*\\[CORRUPT\\]"
patch "$GOOD" "$WORK/h.asf" 16 ff
refused_by_both "section_count damaged" "$WORK/h.asf" 3 "\\[(CORRUPT|CHECKSUM)\\]"
patch "$GOOD" "$WORK/h.asf" 32 4000000000000000
refused_by_both "file_size says 64 bytes" "$WORK/h.asf" 3 "file_size at offset 32 says 64 bytes, file has $SIZE \\[CORRUPT\\]"
patch "$GOOD" "$WORK/h.asf" 40 flip
refused_by_both "table_checksum damaged" "$WORK/h.asf" 3 "section table \\(offset 64, 256 bytes\\): checksum mismatch.*\\[CHECKSUM\\]"
patch "$GOOD" "$WORK/h.asf" 50 01
refused_by_both "reserved header byte set" "$WORK/h.asf" 3 "reserved header byte at offset 50 .*\\[CORRUPT\\]"

# Section table (entries of 64 bytes from offset 64; SPEC.md 2.3).
for off in 64 68 $((64 + 64 + 8)) $((64 + 64 + 16)) $((64 + 128 + 40)) $((64 + 128 + 48)); do
    patch "$GOOD" "$WORK/t.asf" "$off" flip
    refused_by_both "section table byte $off damaged" "$WORK/t.asf" 3 "section table \\(offset 64, 256 bytes\\): checksum mismatch.*\\[CHECKSUM\\]"
done

# Section contents: caught by their checksums.
patch "$GOOD" "$WORK/m.asf" "$META" flip
refused_by_both "META writer damaged" "$WORK/m.asf" 3 "section META \\(index 0, offset $META\\): checksum mismatch.*\\[CHECKSUM\\]"
patch "$GOOD" "$WORK/m.asf" $((META + 36)) 00020000
refused_by_both "META structure kind changed" "$WORK/m.asf" 3 "section META \\(index 0, offset $META\\): checksum mismatch.*\\[CHECKSUM\\]"
patch "$GOOD" "$WORK/b.asf" $((BVH2 + 48)) "$(le32 7)"
refused_by_both "BVH2 root child index changed" "$WORK/b.asf" 3 "section BVH2 \\(index 1, offset $BVH2\\): checksum mismatch.*\\[CHECKSUM\\]"
patch "$GOOD" "$WORK/b.asf" $((BVH2 + 64 * 100 + 4)) flip
refused_by_both "BVH2 box of node 100 damaged" "$WORK/b.asf" 3 "section BVH2 \\(index 1, offset $BVH2\\): checksum mismatch.*\\[CHECKSUM\\]"
patch "$GOOD" "$WORK/r.asf" $((TRI4 + 48 * 1000 + 20)) flip
refused_by_both "TRI4 vertex of triangle 1000 damaged" "$WORK/r.asf" 3 "section TRI4 \\(index 2, offset $TRI4\\): checksum mismatch.*\\[CHECKSUM\\]"
TRI4_END=$((TRI4 + $(json_get "$WORK/good.json" '[s for s in j["sections"] if s["tag"] == "TRI4"][0]["stored_bytes"]')))
patch "$GOOD" "$WORK/r.asf" $((TRI4_END - 1)) flip
refused_by_both "last byte of TRI4 (an unused w) damaged" "$WORK/r.asf" 3 "section TRI4 \\(index 2, offset $TRI4\\): checksum mismatch.*\\[CHECKSUM\\]"
# Padding after the last section is "unused: readers ignore" (SPEC.md 2.5).
if [ "$TRI4_END" -lt "$SIZE" ]; then
    patch "$GOOD" "$WORK/p.asf" $((SIZE - 1)) flip
    run padding "$TOOLS/as-inspect" --validate "$WORK/p.asf"
    expect_rc "as-inspect --validate accepts damaged padding after the last section" 0
fi

# The same damage to a compressed file.
"$TOOLS/as-convert" "$GOOD" -o "$WORK/z.asf" --compress=3 || fail "as-convert --compress=3"
"$TOOLS/as-inspect" --format json "$WORK/z.asf" >"$WORK/z.json"
ZBVH2=$(section_offset "$WORK/z.json" BVH2)
ZSIZE=$(wc -c <"$WORK/z.asf")
patch "$WORK/z.asf" "$WORK/zb.asf" $((ZBVH2 + 100)) flip
refused_by_both "compressed BVH2 damaged" "$WORK/zb.asf" 3 "section BVH2 .*\\[(CORRUPT|CHECKSUM)\\]"
head -c $((ZSIZE / 2)) "$WORK/z.asf" >"$WORK/zcut.asf"
refused_by_both "compressed file truncated to half" "$WORK/zcut.asf" 3 "truncated: header says $ZSIZE bytes, file has $((ZSIZE / 2)) \\[CORRUPT\\]"

# The optional build record: a NaN build time is refused even where no
# checksum would catch it.
build_bunny "$WORK/rec.asf"
"$TOOLS/as-inspect" --format json "$WORK/rec.asf" >"$WORK/rec.json"
BREC=$(section_offset "$WORK/rec.json" BREC)
patch "$WORK/rec.asf" "$WORK/recnan.asf" "$BREC" 000000000000f87f
expect_refused "as-inspect --no-checksum: BREC build time NaN" "$WORK/recnan.asf" 3 \
    "BREC section \\(offset $BREC\\): build time nan ms is not a finite non-negative number.*\\[CORRUPT\\]" \
    "$TOOLS/as-inspect" --no-checksum "$WORK/recnan.asf"
finish
