#!/bin/sh
# as-trace --dump DIR writes each traced workload's rays and hits as a ray
# file and a hit file (DIR/NAME.rays, DIR/NAME.hits): traced again from the
# ray file (--rays, with --any-hit for the any-hit workloads) they give the
# same hits byte for byte, so another tracer, or an independent check, can
# take exactly the rays as-trace traced. The counts are those as-trace
# prints; a DIR that is not a directory is an I/O error (exit 2).
. "$(dirname "$0")/cli_lib.sh"
need_python

ASF=$WORK/bunny.asf
build_bunny "$ASF"
D=$WORK/dump
mkdir -p "$D"

run dump "$TOOLS/as-trace" "$ASF" --device cpu -W 48 -H 32 -w all --shuffle --format json --dump "$D"
expect_rc "as-trace -w all --shuffle --dump" 0
for name in primary "shadow random" "ao random" "diffuse random" "whitted 0 shadow" "whitted 1"; do
    f=$(echo "$name" | tr ' ' '-')
    RAYS=$(json_get "$WORK/dump.out" "[w['rays'] for w in j['workloads'] if w['workload'] == '$name'][0]")
    # A ray file: 32-byte header, 32-byte records; a hit file: 32-byte header, 16-byte records.
    expect_eq "$f.rays holds the $RAYS rays traced" "$((32 + 32 * RAYS))" "$(wc -c < "$D/$f.rays" | tr -d ' ')"
    expect_eq "$f.hits holds their $RAYS hits" "$((32 + 16 * RAYS))" "$(wc -c < "$D/$f.hits" | tr -d ' ')"
    case $name in
        *shadow*|ao*) ANY=--any-hit ;;
        *) ANY= ;;
    esac
    run again "$TOOLS/as-trace" "$ASF" --device cpu --rays "$D/$f.rays" $ANY --hits-out "$WORK/$f.again.hits"
    expect_rc "$f.rays traced again" 0
    expect_same_file "$f: the same hits from the ray file" "$D/$f.hits" "$WORK/$f.again.hits"
done

run notdir "$TOOLS/as-trace" "$ASF" --device cpu -W 8 -H 8 --dump "$WORK/no-such-dir"
expect_rc "--dump into a missing directory" 2
expect_grep "the message names it" "$WORK/notdir.err" "--dump .*no-such-dir: not a directory"
finish
