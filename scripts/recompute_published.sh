#!/bin/sh
# Recompute published error figures independently, on the device that made them.
#
#   scripts/recompute_published.sh OUT SCENE CAMERA ACCURACY_JSON VARIANT...
#
# For each VARIANT ("STRUCTURE BUILDER LAYOUT NAME", NAME as in as-accuracy's
# rows, e.g. "bvh sbvh bvh2-child-bounds BVH (SBVH)") and each intersector:
# builds SCENE, writes the camera's 1920x1080 primary rays with
# scripts/recompute_errors.py (not libas), traces them with as-trace on
# DEVICE into a hit file with --verify, then shadow rays from those hits
# (an any-hit query), and has recompute_errors.py check a sample of each hit
# file by brute force against as-trace's own figures on the same rays and
# against the published row of ACCURACY_JSON (as-accuracy's output for the
# same camera). CAMERA is a camera file, EYE@TARGET@UP@FOV, or - for
# as-trace's default camera.
#
# Environment: BIN (tools folder, default build/tools), DEVICE (gpu),
# SAMPLES (rays each check draws, 10000), VERIFY (rays as-trace verifies,
# 1000000), INTERSECTORS (default "watertight-double watertight
# moller-trumbore"), W and H (1920, 1080).
#
# Writes OUT/*.json (one per check) and OUT/summary.md, the table of every
# check. Exit status: 0 when every check agrees, 6 when one disagrees, 1
# usage, 2 a step failed.
set -u
[ $# -ge 5 ] || { echo "usage: $0 OUT SCENE CAMERA ACCURACY_JSON 'STRUCTURE BUILDER LAYOUT NAME'..." >&2; exit 1; }
OUT=$1 SCENE=$2 CAMERA=$3 ACC=$4; shift 4
HERE=$(cd "$(dirname "$0")" && pwd)
R="python3 $HERE/recompute_errors.py"
BIN=${BIN:-build/tools} DEVICE=${DEVICE:-gpu} SAMPLES=${SAMPLES:-10000} VERIFY=${VERIFY:-1000000}
INTERSECTORS=${INTERSECTORS:-"watertight-double watertight moller-trumbore"}
W=${W:-1920} H=${H:-1080}
mkdir -p "$OUT" || exit 2
case $CAMERA in
-) CAM_ARGS= ;;
# --eye=X: a value that starts with a minus sign is not taken for an option.
*@*@*@*) CAM_ARGS="--eye=$(echo "$CAMERA" | cut -d@ -f1) --target=$(echo "$CAMERA" | cut -d@ -f2) --up=$(echo "$CAMERA" | cut -d@ -f3) --fov=$(echo "$CAMERA" | cut -d@ -f4)" ;;
*) CAM_ARGS="--camera $CAMERA" ;;
esac
status=0
step() { "$@" || { echo "recompute_published: failed: $*" >&2; exit 2; }; }
# check NAME RAYS HITS TRACE_JSON WORKLOAD VARIANT INTERSECTOR [--any-hit]
check() {
    c_n=$1 c_rays=$2 c_hits=$3 c_tj=$4 c_wl=$5 c_v=$6 c_i=$7; shift 7
    $R check "$asf" "$c_rays" "$c_hits" "$@" -q --samples "$SAMPLES" --compare "$c_tj" --json "$OUT/$c_n.same-rays.json"
    rc=$?; [ $rc -eq 0 ] || [ $rc -eq 6 ] || { echo "recompute_published: check $c_n failed ($rc)" >&2; exit 2; }
    [ $rc -eq 6 ] && status=6
    $R check "$asf" "$c_rays" "$c_hits" "$@" -q --samples "$SAMPLES" --compare "$ACC" --select "variant=$c_v" \
        --select "intersector=$c_i" --select "workload=$c_wl" --json "$OUT/$c_n.published.json"
    rc=$?; [ $rc -eq 0 ] || [ $rc -eq 6 ] || { echo "recompute_published: check $c_n failed ($rc)" >&2; exit 2; }
    [ $rc -eq 6 ] && status=6
}
for v in "$@"; do
    set -- $v
    st=$1 bu=$2 la=$3; shift 3; vname=$*
    tag=$st-$bu-$la
    asf=$OUT/$tag.asf
    step "$BIN/as-build" "$SCENE" -o "$asf" --structure "$st" --builder "$bu" --layout "$la" -q
    [ -f "$OUT/primary.rays" ] || step $R rays "$asf" $CAM_ARGS -W "$W" -H "$H" -o "$OUT/primary.rays"
    for i in $INTERSECTORS; do
        n=$tag-$i
        step "$BIN/as-trace" "$asf" --device "$DEVICE" --intersector "$i" --rays "$OUT/primary.rays" \
            --hits-out "$OUT/$n-primary.hits" --verify="$VERIFY" --format json > "$OUT/$n-primary.trace.json"
        check "$n-primary" "$OUT/primary.rays" "$OUT/$n-primary.hits" "$OUT/$n-primary.trace.json" primary "$vname" "$i"
        step $R rays "$asf" --shadow-from "$OUT/primary.rays" "$OUT/$n-primary.hits" -o "$OUT/$n-shadow.rays"
        step "$BIN/as-trace" "$asf" --device "$DEVICE" --intersector "$i" --rays "$OUT/$n-shadow.rays" --any-hit \
            --hits-out "$OUT/$n-shadow.hits" --verify="$VERIFY" --format json > "$OUT/$n-shadow.trace.json"
        check "$n-shadow" "$OUT/$n-shadow.rays" "$OUT/$n-shadow.hits" "$OUT/$n-shadow.trace.json" shadow "$vname" "$i" --any-hit
        rm -f "$OUT/$n-shadow.rays" "$OUT/$n-shadow.hits" "$OUT/$n-primary.hits"
    done
    rm -f "$asf"
done
$R table "$OUT"/*.same-rays.json "$OUT"/*.published.json > "$OUT/summary.md"
rc=$?; [ $rc -eq 0 ] || [ $rc -eq 6 ] || exit 2
cat "$OUT/summary.md"
exit $status
