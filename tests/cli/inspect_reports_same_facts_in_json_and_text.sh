#!/bin/sh
# as-inspect --format json is valid JSON with every documented field, and the
# text output states the same facts (section bytes, nodes, leaves, depth, SAH
# cost, build parameters, histograms).
. "$(dirname "$0")/cli_lib.sh"
need_python

ASF=$WORK/bunny.asf
build_bunny "$ASF"
run json "$TOOLS/as-inspect" --format json "$ASF"
expect_rc "as-inspect --format json" 0
J=$WORK/json.out
if python3 -c 'import json, sys; json.load(sys.stdin)' <"$J" 2>"$WORK/parse.err"; then
    ok "json output parses"
else
    fail "json output does not parse: $(cat "$WORK/parse.err" | tail -1)"
    finish
fi

# Every field is present with the right type.
missing=$(python3 - "$J" <<'PY'
import json, sys
j = json.load(open(sys.argv[1]))
need = {"sections": list, "megabytes": float, "bytes": int, "bytes_per_triangle": float, "triangles": int,
        "nodes": int, "children_per_node": float, "leaves": int, "max_depth": int, "average_leaf_depth": float,
        "depth_histogram": list, "leaf_size_histogram": list, "sah_cost": float, "build": dict,
        "structure": str, "layout": str, "layout_version": int, "writer": str, "source_hash": str, "bounds": list}
bad = [k for k, t in need.items() if not isinstance(j.get(k), t)]
for i, s in enumerate(j.get("sections", [])):
    for k, t in {"tag": str, "stored_bytes": int, "raw_bytes": int, "compression": str, "checksum": str,
                 "checksum_status": str, "offset": int, "elements": int, "stride": int, "required": bool}.items():
        if not isinstance(s.get(k), t): bad.append("sections[%d].%s" % (i, k))
for k, t in {"builder": str, "max_leaf_size": int, "bins": int, "cost_traversal": (int, float), "cost_intersection": (int, float)}.items():
    if not isinstance(j.get("build", {}).get(k), t): bad.append("build." + k)
print(" ".join(bad))
PY
)
expect_eq "json has every field with its type" "" "$missing"

expect_eq "json section tags (BREC: the build record as-build writes; CSUM: the chunk checksums every file ends with)" "META BVH2 TRI4 BREC CSUM" "$(json_get "$J" '" ".join(s["tag"] for s in j["sections"])')"
expect_eq "json sections uncompressed" "none none none none none" "$(json_get "$J" '" ".join(s["compression"] for s in j["sections"])')"
expect_eq "json checksums verified" "verified verified verified verified verified" "$(json_get "$J" '" ".join(s["checksum_status"] for s in j["sections"])')"
expect_eq "json checksums are 16 hex digits" "True" "$(json_get "$J" 'all(len(s["checksum"]) == 16 and int(s["checksum"], 16) >= 0 for s in j["sections"])')"
expect_eq "json triangles" "69451" "$(json_get "$J" 'j["triangles"]')"
expect_eq "json structure, layout, version" "bvh bvh2-child-bounds 1" "$(json_get "$J" '"%s %s %d" % (j["structure"], j["layout"], j["layout_version"])')"
expect_eq "json default build parameters" "sah 4 32 1 1" "$(json_get "$J" '"%s %d %d %g %g" % tuple(j["build"][k] for k in ("builder", "max_leaf_size", "bins", "cost_traversal", "cost_intersection"))')"
expect_eq "json bytes = sum of raw section bytes but the build record's and the chunk checksums'" "True" "$(json_get "$J" 'j["bytes"] == sum(s["raw_bytes"] for s in j["sections"] if s["tag"] not in ("BREC", "CSUM"))')"
expect_eq "json build time recorded: positive ms, threads and cores" "True" "$(json_get "$J" 'j["build"]["build_ms"] > 0 and j["build"]["threads"] >= 1 and j["build"]["cores"] >= 1')"
expect_eq "json megabytes = bytes / 1e6" "True" "$(json_get "$J" 'abs(j["megabytes"] - j["bytes"] / 1e6) < 1e-6')"
expect_eq "json bytes_per_triangle = bytes / triangles" "True" "$(json_get "$J" 'abs(j["bytes_per_triangle"] - j["bytes"] / j["triangles"]) < 1e-3')"
expect_eq "json BVH2 elements = nodes" "True" "$(json_get "$J" '[s for s in j["sections"] if s["tag"] == "BVH2"][0]["elements"] == j["nodes"]')"
expect_eq "json TRI4 elements = triangles (bunny has no zero-area ones)" "True" "$(json_get "$J" '[s for s in j["sections"] if s["tag"] == "TRI4"][0]["elements"] == j["triangles"]')"
expect_eq "json depth histogram counts every leaf" "True" "$(json_get "$J" 'sum(j["depth_histogram"]) == j["leaves"]')"
expect_eq "json depth histogram ends at max_depth" "True" "$(json_get "$J" 'len(j["depth_histogram"]) == j["max_depth"] + 1')"
expect_eq "json leaf-size histogram counts every leaf" "True" "$(json_get "$J" 'sum(j["leaf_size_histogram"]) == j["leaves"]')"
expect_eq "json leaf-size histogram counts every triangle" "True" "$(json_get "$J" 'sum(i * n for i, n in enumerate(j["leaf_size_histogram"])) == j["triangles"]')"
expect_eq "json leaves no larger than the leaf size" "True" "$(json_get "$J" 'len(j["leaf_size_histogram"]) <= j["build"]["max_leaf_size"] + 1')"
expect_eq "json average depth from the histogram" "True" "$(json_get "$J" 'abs(j["average_leaf_depth"] - sum(d * n for d, n in enumerate(j["depth_histogram"])) / j["leaves"]) < 1e-3')"
expect_eq "json SAH cost positive" "True" "$(json_get "$J" 'j["sah_cost"] > 0')"
expect_eq "json not validated without --validate" "False" "$(json_get "$J" 'j["validated"]')"

# The text output states the same facts.
run text "$TOOLS/as-inspect" "$ASF"
expect_rc "as-inspect (text)" 0
T=$WORK/text.out
for tag in META BVH2 TRI4; do
    line=$(json_get "$J" '"  %s required %12d %12d %12d %6d  no    verified" % tuple([s for s in j["sections"] if s["tag"] == "'$tag'"][0][k] for k in ("tag", "offset", "stored_bytes", "raw_bytes", "stride"))')
    expect_grep "text section line for $tag" "$T" "^$(printf '%s' "$line" | sed 's/ *$//') "
done
# JSON gives the time to 0.001 ms and the text to 0.1: a time within 0.0005
# of a tenth's midpoint may round either way from the JSON's figure.
expect_grep "text build time as recorded" "$T" "^build time: +($(json_get "$J" '"|".join(sorted({"%.1f" % (j["build"]["build_ms"] + d) for d in (-0.0005, 0.0005)})).replace(".", "\\.")')) ms on $(json_get "$J" 'j["build"]["threads"]') threads \\($(json_get "$J" 'j["build"]["cores"]') cores\\), as recorded in the file$"
expect_grep "text triangles" "$T" "^triangles: +$(json_get "$J" 'j["triangles"]')$"
expect_grep "text memory" "$T" "^memory: +$(json_get "$J" '"%.3f" % j["megabytes"]') MB, $(json_get "$J" '"%.1f" % j["bytes_per_triangle"]') bytes per triangle$"
expect_grep "text nodes, leaves and children per node" "$T" "^nodes: +$(json_get "$J" 'j["nodes"]') inner, $(json_get "$J" 'j["leaves"]') leaves, $(json_get "$J" '"%.2f" % j["children_per_node"]') children per inner node$"
expect_eq "json children per node of a binary tree" "2.0000" "$(json_get "$J" '"%.4f" % j["children_per_node"]')"
expect_grep "text depth" "$T" "^depth: +max $(json_get "$J" 'j["max_depth"]'), average leaf depth $(json_get "$J" '"%.2f" % j["average_leaf_depth"]')$"
expect_grep "text SAH cost" "$T" "^SAH cost: +$(json_get "$J" '"%.3f" % j["sah_cost"]') \\(ratio 1.00\\/1: traversal 1, intersection 1\\)$"
expect_grep "text build parameters" "$T" "^build: +sah, leaf size 4, bins 32$"
expect_grep "text source hash" "$T" "^source hash: +$(json_get "$J" 'j["source_hash"]')$"
for d in $(json_get "$J" '" ".join("%d:%d" % (i, n) for i, n in enumerate(j["depth_histogram"]) if n)'); do
    expect_grep "text depth histogram row ${d%%:*}" "$T" "^ +${d%%:*} +${d#*:}  #*$"
done
for d in $(json_get "$J" '" ".join("%d:%d" % (i, n) for i, n in enumerate(j["leaf_size_histogram"]) if n)'); do
    expect_grep "text leaf-size histogram row ${d%%:*}" "$T" "^ +${d%%:*} +${d#*:}  #*$"
done

run validate "$TOOLS/as-inspect" --validate --format json "$ASF"
expect_rc "as-inspect --validate on an intact file" 0
expect_eq "json validated with --validate" "True" "$(json_get "$WORK/validate.out" 'j["validated"]')"
run validate "$TOOLS/as-inspect" --validate "$ASF"
expect_grep "text validation passed" "$WORK/validate.out" "^validation: +passed$"
run nocheck "$TOOLS/as-inspect" --no-checksum --format json "$ASF"
expect_eq "json checksums not checked with --no-checksum" "not checked not checked not checked not checked not checked" "$(json_get "$WORK/nocheck.out" '" ".join(s["checksum_status"] for s in j["sections"])')"
finish
