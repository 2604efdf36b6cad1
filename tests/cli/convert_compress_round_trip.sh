#!/bin/sh
# as-convert --compress then --decompress gives back the original file byte
# for byte; the compressed file is smaller, shows zstd in as-inspect with the
# same raw bytes and checksums, and traces to identical hits.
. "$(dirname "$0")/cli_lib.sh"
need_python

ORIG=$WORK/orig.asf
build_bunny "$ORIG"
run compress "$TOOLS/as-convert" "$ORIG" -o "$WORK/z.asf" --compress
expect_rc "as-convert --compress" 0
run decompress "$TOOLS/as-convert" "$WORK/z.asf" -o "$WORK/back.asf" --decompress
expect_rc "as-convert --decompress" 0
expect_same_file "compress then decompress is byte-identical to the original" "$ORIG" "$WORK/back.asf"
run plain "$TOOLS/as-convert" "$ORIG" -o "$WORK/copy.asf"
expect_rc "as-convert without options" 0
expect_same_file "as-convert without options stores raw: byte-identical" "$ORIG" "$WORK/copy.asf"
run level "$TOOLS/as-convert" "$ORIG" -o "$WORK/z1.asf" --compress=1
expect_rc "as-convert --compress=1" 0
run level "$TOOLS/as-convert" "$WORK/z1.asf" -o "$WORK/back1.asf" --decompress
expect_same_file "compress=1 then decompress is byte-identical to the original" "$ORIG" "$WORK/back1.asf"
run badlevel "$TOOLS/as-convert" "$ORIG" -o "$WORK/z99.asf" --compress=23
expect_rc "as-convert --compress=23" 1
expect_grep "level out of range named" "$WORK/badlevel.err" "--compress level must be 1\\.\\.22, got '23'"

osize=$(wc -c <"$ORIG")
zsize=$(wc -c <"$WORK/z.asf")
if [ "$zsize" -lt "$osize" ]; then ok "compressed file is smaller ($zsize < $osize bytes)"; else fail "compressed file is not smaller: $zsize >= $osize bytes"; fi

"$TOOLS/as-inspect" --format json "$ORIG" >"$WORK/orig.json"
run zjson "$TOOLS/as-inspect" --format json "$WORK/z.asf"
expect_rc "as-inspect on the compressed file" 0
Z=$WORK/zjson.out
# The META section (256 bytes) may stay raw when zstd would not make it smaller (SPEC.md 2.6).
expect_eq "BVH2, TRI4 and the build record compressed with zstd (CSUM is stored raw)" "zstd zstd zstd none" "$(json_get "$Z" '" ".join(s["compression"] for s in j["sections"] if s["tag"] != "META")')"
expect_eq "compressed sections stored smaller than raw" "True" "$(json_get "$Z" 'all(s["stored_bytes"] < s["raw_bytes"] for s in j["sections"] if s["compression"] == "zstd")')"
expect_eq "checksums verified after decompression" "True" "$(json_get "$Z" 'all(s["checksum_status"] == "verified" for s in j["sections"])')"
expect_eq "same raw bytes and checksums as the original" \
    "$(json_get "$WORK/orig.json" '[(s["tag"], s["raw_bytes"], s["checksum"]) for s in j["sections"]]')" \
    "$(json_get "$Z" '[(s["tag"], s["raw_bytes"], s["checksum"]) for s in j["sections"]]')"
expect_eq "same structure statistics as the original" \
    "$(json_get "$WORK/orig.json" '[j[k] for k in ("nodes", "leaves", "max_depth", "sah_cost", "bytes", "depth_histogram", "leaf_size_histogram")]')" \
    "$(json_get "$Z" '[j[k] for k in ("nodes", "leaves", "max_depth", "sah_cost", "bytes", "depth_histogram", "leaf_size_histogram")]')"
run ztext "$TOOLS/as-inspect" "$WORK/z.asf"
expect_grep "text output shows BVH2 compressed" "$WORK/ztext.out" "^  BVH2 required .* yes +verified "
run zvalidate "$TOOLS/as-inspect" --validate "$WORK/z.asf"
expect_rc "as-inspect --validate on the compressed file" 0

# Same hits from the camera rays of both files.
run trace "$TOOLS/as-trace" --device cpu -W 96 -H 64 --hits-out "$WORK/orig.hits" "$ORIG"
expect_rc "as-trace of the original" 0
run ztrace "$TOOLS/as-trace" --device cpu -W 96 -H 64 --hits-out "$WORK/z.hits" "$WORK/z.asf"
expect_rc "as-trace of the compressed file" 0
expect_same_file "compressed and original files give identical hit files" "$WORK/orig.hits" "$WORK/z.hits"
expect_grep "some camera rays hit the bunny" "$WORK/trace.out" "^primary +6144 rays \\(closest hit\\), [1-9][0-9]* hit: "

# as-convert refuses a damaged input and leaves no output.
head -c 1000 "$ORIG" >"$WORK/cut.asf"
expect_refused "as-convert of a truncated file" "$WORK/cut.asf" 3 "truncated.*\\[CORRUPT\\]" "$TOOLS/as-convert" "$WORK/cut.asf" -o "$WORK/cut-out.asf"
if [ -e "$WORK/cut-out.asf" ]; then fail "as-convert wrote output for a damaged input"; else ok "no output for a damaged input"; fi
finish
