#!/bin/sh
# as-trace --rebuild MESH: beside the load line, the build time the file
# records (BREC: ms and threads) and the time of a build of the same
# structure measured now on this CPU with --threads, from the same mesh
# (checked by hash: another mesh is refused with exit 3 before any trace);
# "the same structure" only when the rebuild's counts match the file's. The
# JSON has the recorded time always (null without a build record) and the
# measured one with --rebuild.
. "$(dirname "$0")/cli_lib.sh"
need_python

build_bunny "$WORK/bvh.asf"
"$TOOLS/as-build" "$BUNNY" -o "$WORK/norec.asf" --structure kd --no-build-record -q || { echo "FAIL - kd build failed"; exit 1; }
"$TOOLS/as-build" "$BUNNY" -o "$WORK/grid8.asf" --structure grid --lambda 8 --threads 1 -q || { echo "FAIL - grid build failed"; exit 1; }
"$TOOLS/as-inspect" -f json "$WORK/bvh.asf" >"$WORK/inspect.json"
# The milliseconds as as-inspect prints them (the JSON's three decimals,
# rounded again to one, can round the other way), the threads from its JSON.
RECORDED_MS=$("$TOOLS/as-inspect" "$WORK/bvh.asf" | sed -n 's/^build time: *\([0-9.]*\) ms on .*/\1/p')
RECORDED=$(json_get "$WORK/inspect.json" '"'"$RECORDED_MS"' ms on %d thread%s" % (j["build"]["threads"], "" if j["build"]["threads"] == 1 else "s")')

run plain "$TOOLS/as-trace" --device cpu -W 32 -H 24 "$WORK/bvh.asf"
expect_rc "as-trace without --rebuild" 0
if grep -q '^rebuild:' "$WORK/plain.out"; then fail "no rebuild line without --rebuild"; else ok "no rebuild line without --rebuild"; fi

run bvh "$TOOLS/as-trace" --device cpu -W 32 -H 24 --threads 2 --rebuild "$BUNNY" "$WORK/bvh.asf"
expect_rc "as-trace --rebuild" 0
expect_grep "the rebuild line follows the load line" "$WORK/bvh.out" "^load: "
expect_eq "rebuild line right after the load line" "rebuild:" "$(sed -n '/^load:/{n;p;}' "$WORK/bvh.out" | cut -c1-8)"
expect_grep "recorded and measured-now times, with thread counts, same structure" "$WORK/bvh.out" \
    "^rebuild: +[0-9]+\\.[0-9] ms on [0-9]+ threads? as recorded in the file; [0-9]+\\.[0-9] ms on 2 threads measured now from $BUNNY \\(the same structure\\)$"
expect_grep "the recorded time is the one as-inspect reads from the file ($RECORDED)" "$WORK/bvh.out" "^rebuild: +$RECORDED as recorded"

run norec "$TOOLS/as-trace" --device cpu -W 32 -H 24 --threads 1 --rebuild "$BUNNY" "$WORK/norec.asf"
expect_rc "--rebuild of a file without a build record" 0
expect_grep "no record: said so, and measured now on 1 thread" "$WORK/norec.out" \
    "^rebuild: +not recorded in the file; [0-9]+\\.[0-9] ms on 1 thread measured now from .* \\(the same structure\\)$"

run grid8 "$TOOLS/as-trace" --device cpu -W 32 -H 24 --rebuild "$BUNNY" "$WORK/grid8.asf"
expect_rc "--rebuild of a grid built with --lambda 8 (not recorded in the file)" 0
expect_grep "a rebuild that does not match the file says so" "$WORK/grid8.out" \
    "^rebuild: .* on 1 thread as recorded in the file; .* \\(a different structure: the file's build had settings the file does not record\\)$"

run json "$TOOLS/as-trace" --device cpu -W 32 -H 24 --threads 1 --rebuild "$BUNNY" -f json "$WORK/bvh.asf"
expect_rc "--rebuild -f json" 0
expect_eq "JSON: recorded ms and threads, measured ms on 1 thread, same structure" "True True 1 True" \
    "$(json_get "$WORK/json.out" 'j["rebuild_recorded_ms"] > 0, j["rebuild_recorded_threads"] >= 1, j["rebuild_measured_threads"], j["rebuild_measured_ms"] > 0 and j["rebuild_same_structure"]' | tr -d '(),')"
run json2 "$TOOLS/as-trace" --device cpu -W 32 -H 24 -f json "$WORK/norec.asf"
expect_eq "JSON without a record or --rebuild: nulls" "None None None" \
    "$(json_get "$WORK/json2.out" 'j["rebuild_recorded_ms"], j["rebuild_recorded_threads"], j["rebuild_measured_ms"]' | tr -d '(),')"

expect_refused "another mesh is not the structure's" "$DATA/tri.obj" 3 "not the mesh the structure was built from" \
    "$TOOLS/as-trace" --device cpu -W 32 -H 24 --rebuild "$DATA/tri.obj" "$WORK/bvh.asf"
if [ -s "$WORK/refused.out" ]; then fail "refused before tracing: nothing on stdout, got $(head -c 200 "$WORK/refused.out")"; else ok "refused before tracing: nothing on stdout"; fi
expect_refused "a missing mesh" "$WORK/none.obj" 2 "no such file" \
    "$TOOLS/as-trace" --device cpu -W 32 -H 24 --rebuild "$WORK/none.obj" "$WORK/bvh.asf"
finish
