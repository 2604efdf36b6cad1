#!/bin/sh
# The study of San Miguel (9.4M triangles) on the GPU host, in parts.
#
#   scripts/study_sanmiguel.sh --bin DIR [--out DIR] [--scene FILE]
#                              [--time-limit SECONDS] PART [-- AS-STUDY-OPTIONS]
#   scripts/study_sanmiguel.sh --merge [--out DIR]
#   scripts/study_sanmiguel.sh --list
#
# All thirteen variants take longer than one command may run on the GPU host
# (10 minutes), so each PART (1 to 5) studies a few of them into
# OUT/part-PART/, one call per part, and --merge puts the parts together into
# OUT/merged/sanmiguel/ with `as-study --merge`, as one run would have
# written it. The parts are sized from the bench of San Miguel on the H100
# (docs/results/2026-11-22-bench-sanmiguel-h100.md: 19-25 s per variant for
# the BVHs and KD-trees, 65-78 s for BIH, octree and grid, without the
# statistics pass and verification that the study adds): about 4-5 minutes
# each, the slow traversals apart.
#
# A run is stopped after --time-limit seconds (default 530, under the
# host's 10 minutes with room to start and copy back); as-study rewrites
# results.json after every variant, so what finished is kept, and the
# variants that did not are listed with the command that runs them as a part
# of their own (PART may also be a list of variants, NAME,NAME...).
#
# OUT defaults to study-sanmiguel; the scene to ../shared/scenes/sanmiguel.drc
# beside the repository. as-study sees it from scenes/cameras/sanmiguel.cam
# (the protocol camera of the performance issue), as it does any scene NAME
# with a NAME.cam there. Options after -- go to as-study (a trial on the CPU:
# --scene scenes/bunny.drc 3 -- --device cpu --width 64 --height 36).
set -eu

ROOT=$(cd "$(dirname "$0")/.." && pwd)
BIN='' OUT=study-sanmiguel SCENE="$ROOT/../shared/scenes/sanmiguel.drc" LIMIT=530 PART='' MODE=part

# The paper's mid-cut BVH took over 8 s a frame on San Miguel; the cap stops
# a build after 60 s and a trace after 240 s, so that one slow variant
# cannot take a part's whole run.
CAP=60

part_variants() {
    case "$1" in
        1) echo "bvh-midcut-bvh2-child-bounds,bvh-sah-bvh2-child-bounds,bvh-sbvh-bvh2-child-bounds,bvh-sah-bvh2-own-bounds" ;;
        2) echo "kd-midcut-kd-standard,kd-sah-kd-standard,kd-midcut-kd-ropes,kd-sah-kd-ropes" ;;
        3) echo "bih-bih-bih,grid-grid-grid" ;;
        4) echo "octree-octree-octree" ;;
        5) echo "bvh-sah-cwbvh,bvh-sbvh-cwbvh" ;;
        *,* | *-*) echo "$1" ;;
        *) return 1 ;;
    esac
}

usage() {
    sed -n '4,7p' "$0" | sed 's/^# \{0,1\}//' >&2
    exit 1
}

while [ $# -gt 0 ]; do
    case "$1" in
        --bin) BIN=$2; shift 2 ;;
        --out) OUT=$2; shift 2 ;;
        --scene) SCENE=$2; shift 2 ;;
        --time-limit) LIMIT=$2; shift 2 ;;
        --merge) MODE=merge; shift ;;
        --list) MODE=list; shift ;;
        -h | --help) sed -n '2,29p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
        --) shift; break ;;
        -*) echo "study_sanmiguel.sh: unknown option $1" >&2; usage ;;
        *) [ -z "$PART" ] || usage; PART=$1; shift ;;
    esac
done

STUDY="$ROOT/tools/as-study"

if [ "$MODE" = list ]; then
    for p in 1 2 3 4 5; do echo "part $p: $(part_variants $p)"; done
    exit 0
fi

if [ "$MODE" = merge ]; then
    parts=
    for d in "$OUT"/part-*; do
        # A part stopped before its first variant finished has nothing to give.
        if ls "$d"/*/results.json > /dev/null 2>&1; then parts="$parts $d"; else echo "skipping $d: no results" >&2; fi
    done
    [ -n "$parts" ] || { echo "study_sanmiguel.sh: no parts in $OUT (run the parts first)" >&2; exit 2; }
    # shellcheck disable=SC2086  # the part folders, one word each
    exec python3 "$STUDY" --merge $parts --out "$OUT/merged"
fi

if [ -z "$BIN" ] || [ -z "$PART" ]; then usage; fi
variants=$(part_variants "$PART") || { echo "study_sanmiguel.sh: no part '$PART' (1 to 5, or NAME,NAME...)" >&2; exit 1; }
[ -f "$SCENE" ] || { echo "study_sanmiguel.sh: $SCENE: no such file (use --scene)" >&2; exit 2; }
name=$(basename "$SCENE"); name=${name%%.*}
case "$PART" in
    [1-5]) dir="$OUT/part-$PART" ;;
    *) dir="$OUT/part-$(echo "$PART" | tr -c 'A-Za-z0-9\n' '_' | cut -c1-60)" ;;
esac

echo "== $name, part $PART: $variants"
date -u
(cd "$ROOT" && git rev-parse --short HEAD 2>/dev/null) || true
nvidia-smi --query-gpu=name,driver_version --format=csv,noheader 2>/dev/null || true
start=$(date +%s)
status=0
# timeout signals its whole process group, as-trace included.
timeout "$LIMIT" python3 "$STUDY" "$SCENE" --bin "$BIN" --device gpu --out "$dir" --cap "$CAP" \
    --variants "$variants" "$@" || status=$?
# A run stopped part way leaves the structure file it was tracing (600 MB).
rm -f "$dir/$name"/*.asf "$dir/$name"/*.tmp
echo "part $PART: exit $status after $(( $(date +%s) - start )) s"

missing=$(python3 - "$dir/$name/results.json" "$variants" <<'EOF'
import json, sys
try:
    done = {r["structure"] + "-" + r["builder"] + "-" + r["layout"]: r for r in json.load(open(sys.argv[1]))["variants"]}
except (OSError, ValueError):
    done = {}
for v in sys.argv[2].split(","):
    r = done.get(v)
    print("%s: %s" % (v, "not reached" if r is None else "failed: " + r["error"] if "error" in r else "ok"),
          file=sys.stderr)
print(",".join(v for v in sys.argv[2].split(",") if v not in done or "error" in done[v]))
EOF
)
if [ -n "$missing" ]; then
    echo "not measured in this part: $missing"
    extra=; [ $# -eq 0 ] || extra=" -- (the options after -- of this run)"
    echo "to run them in a part of their own: $0 --bin $BIN --out $OUT --scene $SCENE $missing$extra"
fi
if [ "$status" -eq 124 ]; then
    # as-study packs its archive only at the end; the merge needs the folder.
    tar -czf "$dir/$name.tar.gz" -C "$dir" "$name" 2>/dev/null || true
fi
echo "when every part has run: $0 --merge --out $OUT"
exit "$status"
