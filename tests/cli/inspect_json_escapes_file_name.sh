#!/bin/sh
# as-inspect --format json stays valid JSON whatever the file's name: a
# double quote or a backslash in the path is escaped.
. "$(dirname "$0")/cli_lib.sh"
need_python

build_bunny "$WORK/plain.asf"
for name in 'say "hi".asf' 'back\slash.asf'; do
    cp "$WORK/plain.asf" "$WORK/$name"
    run json "$TOOLS/as-inspect" --format json "$WORK/$name"
    expect_rc "as-inspect --format json on '$name'" 0
    got=$(python3 -c 'import json, sys; print(json.load(sys.stdin)["file"])' <"$WORK/json.out" 2>&1 | tail -1)
    expect_eq "json 'file' field round-trips '$name'" "$WORK/$name" "$got"
done
finish
