#!/bin/sh
# Runs each libFuzzer harness for SECONDS over a scratch copy of its seed
# corpus (the committed corpus is not grown by a run). Exits 1 when any
# harness finds a crash, leak or timeout; the reproducer is kept and named.
#
#   fuzz/run_fuzzers.sh BUILD_DIR SECONDS [HARNESS...]
#
# SECONDS is per harness; the harnesses are asf_reader, ray_file,
# structure_trace and mesh_import (all of them by default). BUILD_DIR must be
# configured with -DAS_FUZZ=ON -DAS_SANITIZE=ON under Clang.
set -u

if [ $# -lt 2 ]; then
    echo "usage: $0 BUILD_DIR SECONDS [HARNESS...]" >&2
    exit 2
fi
build=$1
seconds=$2
shift 2
harnesses=${*:-asf_reader ray_file structure_trace mesh_import}
here=$(cd "$(dirname "$0")" && pwd)
work=$(mktemp -d "${TMPDIR:-/tmp}/as_fuzz.XXXXXX") || exit 2

status=0
for harness in $harnesses; do
    exe=$build/fuzz/fuzz_$harness
    if [ ! -x "$exe" ]; then
        echo "$exe: not built (configure with -DAS_FUZZ=ON under Clang)" >&2
        status=1
        continue
    fi
    mkdir -p "$work/$harness/corpus" "$work/$harness/artifacts"
    cp "$here/corpus/$harness/"* "$work/$harness/corpus/"
    echo "== fuzz_$harness for ${seconds}s"
    # -max_len: the seeds are under 8 KB; longer inputs only slow the search.
    if ! "$exe" -max_total_time="$seconds" -max_len=8192 -timeout=10 -rss_limit_mb=2048 \
            -print_final_stats=1 -artifact_prefix="$work/$harness/artifacts/" \
            "$work/$harness/corpus" >"$work/$harness/log" 2>&1; then
        tail -n 40 "$work/$harness/log" >&2
        echo "fuzz_$harness FAILED; reproducer(s) in $work/$harness/artifacts:" >&2
        ls "$work/$harness/artifacts" >&2
        status=1
    else
        grep -E '^stat::number_of_executed_units|^stat::new_units_added' "$work/$harness/log"
        echo "fuzz_$harness ok"
    fi
done

# Keep the scratch directory only when it holds something to look at.
if [ $status -eq 0 ]; then
    rm -rf "$work"
fi
exit $status
