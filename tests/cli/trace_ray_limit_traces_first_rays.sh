#!/bin/sh
# as-trace --ray-limit N traces the first N rays of each workload: the
# secondary rays still start at every primary hit, so a workload's count and
# the hits, image and hit file of the primary rays are those of a run without
# the limit; a workload with no more than N rays is traced whole; with --rays
# the hit file has the first N hits; whitted and a limit of 0 are usage
# errors.
. "$(dirname "$0")/cli_lib.sh"
need_python

ASF=$WORK/bunny.asf
build_bunny "$ASF"
T="$TOOLS/as-trace $ASF --device cpu -W 48 -H 32 --format json"

run whole $T -w ao --hits-out "$WORK/whole.hits"
expect_rc "as-trace -w ao without a limit" 0
AO=$(json_get "$WORK/whole.out" '[w["rays"] for w in j["workloads"] if w["workload"] == "ao"][0]')
AO_HIT=$(json_get "$WORK/whole.out" '[w["hit"] for w in j["workloads"] if w["workload"] == "ao"][0]')
expect_eq "without a limit, no workload_rays" "False" \
    "$(json_get "$WORK/whole.out" 'any("workload_rays" in w for w in j["workloads"])')"

run limited $T -w ao --ray-limit 1000 --hits-out "$WORK/limited.hits"
expect_rc "as-trace -w ao --ray-limit 1000" 0
expect_eq "primary: 1000 of the 1536 rays traced" "1000 1536" \
    "$(json_get "$WORK/limited.out" '" ".join("%d %d" % (w["rays"], w["workload_rays"]) for w in j["workloads"] if w["workload"] == "primary")')"
expect_eq "ao: 1000 of the same rays as without the limit" "1000 $AO" \
    "$(json_get "$WORK/limited.out" '" ".join("%d %d" % (w["rays"], w["workload_rays"]) for w in j["workloads"] if w["workload"] == "ao")')"
expect_same_file "the primary hits written are every pixel's, as without the limit" "$WORK/whole.hits" "$WORK/limited.hits"

run over $T -w ao --ray-limit 100000000
expect_rc "a limit above every workload's rays" 0
expect_eq "the workloads are traced whole" "1536 $AO $AO_HIT" \
    "$(json_get "$WORK/over.out" '" ".join(str(w[k]) for w in j["workloads"] for k in (("rays",) if w["workload"] == "primary" else ("rays", "hit")))')"

run text "$TOOLS/as-trace" "$ASF" --device cpu -W 48 -H 32 -w diffuse --shuffle --ray-limit 64
expect_rc "as-trace -w diffuse --shuffle --ray-limit 64 (text)" 0
expect_grep "the text names the traced and the workload's rays" "$WORK/text.out" \
    "^diffuse random +64 rays of [0-9]+ \\(closest hit\\)"

# --rays: the first N rays of the file, and their hits.
python3 - "$WORK/probe.rays" <<'PY'
import struct, sys
inf = float("inf")
rays = [(-0.0168405, 0.110152, 1.0, 0.0, 0.01 * (i - 5), 0.0, -1.0, inf) for i in range(10)]
with open(sys.argv[1], "wb") as f:
    f.write(b"ASRAYS\0\0" + struct.pack("<HHIQQ", 1, 0, 32, len(rays), 0))
    for r in rays:
        f.write(struct.pack("<8f", *r))
PY
run file_all "$TOOLS/as-trace" "$ASF" --device cpu --rays "$WORK/probe.rays" --hits-out "$WORK/all.hits"
expect_rc "as-trace --rays, every ray" 0
run file_first "$TOOLS/as-trace" "$ASF" --device cpu --rays "$WORK/probe.rays" --ray-limit 4 --hits-out "$WORK/first.hits"
expect_rc "as-trace --rays --ray-limit 4" 0
expect_grep "the file's first 4 of 10 rays" "$WORK/file_first.out" "^file +4 rays of 10 "
expect_eq "the hit file holds the first 4 hits of the whole file's" "True" "$(python3 -c '
import struct, sys
a, b = open(sys.argv[1], "rb").read(), open(sys.argv[2], "rb").read()
print(struct.unpack_from("<Q", b, 16)[0] == 4 and len(b) == 32 + 4 * 16 and b[32:] == a[32:32 + 4 * 16])' "$WORK/all.hits" "$WORK/first.hits")"

run whitted "$TOOLS/as-trace" "$ASF" --device cpu -W 8 -H 8 -w whitted --ray-limit 10
expect_rc "--ray-limit with whitted" 1
expect_grep "says why" "$WORK/whitted.err" "does not apply to whitted"
run zero "$TOOLS/as-trace" "$ASF" --device cpu -W 8 -H 8 --ray-limit 0
expect_rc "--ray-limit 0" 1
finish
