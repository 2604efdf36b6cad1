#!/bin/sh
# scripts/bench_scene.py (the per-scene GPU benchmark; here on the CPU, tiny)
# builds each variant asked for, traces every workload and writes a markdown
# table and JSON with a positive Mrays/s for each; an unknown variant is a
# usage error (exit 1) and a failing variant is reported in the table.
. "$(dirname "$0")/cli_lib.sh"
need_python

OUT=$WORK/bunny.md
run bench python3 "$SRC/scripts/bench_scene.py" --bin "$TOOLS" "$BUNNY" --out "$OUT" --device cpu --runs 1 \
    --width 48 --height 32 --variants bvh-sah,kd-ropes-sah,grid
expect_rc "bench_scene.py on three variants" 0
expect_eq "three rows in the JSON" 3 "$(json_get "$WORK/bunny.json" 'len(j["rows"])')"
expect_eq "every row has the six workloads with Mrays/s above 0" "True" \
    "$(json_get "$WORK/bunny.json" 'all(len(r["workloads"]) == 6 and all(w["mrays_per_s"] > 0 for w in r["workloads"].values()) for r in j["rows"])')"
expect_grep "the table has a row per variant" "$OUT" "^\\| kd-ropes-sah \\| [0-9.]+ \\| [0-9]+ \\|"
run unknown python3 "$SRC/scripts/bench_scene.py" --bin "$TOOLS" "$BUNNY" --out "$OUT" --variants bvh-nope
expect_rc "an unknown variant" 1
printf 'not a mesh\n' >"$WORK/bad.obj"
run bad python3 "$SRC/scripts/bench_scene.py" --bin "$TOOLS" "$WORK/bad.obj" --out "$WORK/bad.md" --device cpu \
    --variants grid
expect_rc "a scene that cannot be built still gives a table" 0
expect_grep "which says why" "$WORK/bad.md" "^\\| grid \\| build: exit 3"
finish
