#!/bin/sh
# as-trace --camera FILE gives the same camera, and so the same rays and
# hits, as the options --eye --target --up --fov; options override the file;
# a bad camera file is refused with its line (exit 3).
. "$(dirname "$0")/cli_lib.sh"

GOOD=$WORK/bunny.asf
build_bunny "$GOOD"
CAM=$WORK/view.cam
printf '# the bunny from the front\neye 0 0.1 0.3\n\ntarget 0 0.1 0\nup 0 1 0\nfov 30\n' >"$CAM"
run opts "$TOOLS/as-trace" "$GOOD" --device cpu -W 48 -H 32 --eye 0,0.1,0.3 --target 0,0.1,0 --up 0,1,0 --fov 30 --hits-out "$WORK/opts.hits"
expect_rc "as-trace with the camera as options" 0
run file "$TOOLS/as-trace" "$GOOD" --device cpu -W 48 -H 32 --camera "$CAM" --hits-out "$WORK/file.hits"
expect_rc "as-trace --camera FILE" 0
expect_eq "the same camera line" "$(grep '^camera:' "$WORK/opts.out")" "$(grep '^camera:' "$WORK/file.out")"
expect_same_file "the same hits" "$WORK/opts.hits" "$WORK/file.hits"
run over "$TOOLS/as-trace" "$GOOD" --device cpu -W 48 -H 32 --camera "$CAM" --fov 60
expect_grep "--fov overrides the file" "$WORK/over.out" "^camera: .*fov 60,"

B=$WORK/bad.cam
printf 'eye 0 0.1 0.3\ntarget 0 0.1 0\nzoom 2\n' >"$B"
expect_refused "an unknown key" "$B" 3 "line 3: unknown key 'zoom'" "$TOOLS/as-trace" "$GOOD" --device cpu -W 8 -H 8 --camera "$B"
printf 'eye 0 0.1\ntarget 0 0.1 0\n' >"$B"
expect_refused "two numbers for eye" "$B" 3 "line 1: 'eye' takes three finite numbers" "$TOOLS/as-trace" "$GOOD" --device cpu -W 8 -H 8 --camera "$B"
printf 'eye 0 0.1 0.3\ntarget 0 0.1 0\nfov 180\n' >"$B"
expect_refused "fov 180" "$B" 3 "line 3: fov must be in \\(0, 180\\) degrees" "$TOOLS/as-trace" "$GOOD" --device cpu -W 8 -H 8 --camera "$B"
printf 'eye 0 0.1 0.3\n' >"$B"
expect_refused "no target" "$B" 3 "needs both 'eye' and 'target'" "$TOOLS/as-trace" "$GOOD" --device cpu -W 8 -H 8 --camera "$B"
printf 'eye 0 1 0\ntarget 0 0 0\nup 0 1 0\n' >"$B"
expect_refused "up along the view" "$B" 3 "'up' is zero or parallel to the view direction" "$TOOLS/as-trace" "$GOOD" --device cpu -W 8 -H 8 --camera "$B"
expect_refused "a missing camera file" "$WORK/none.cam" 2 "cannot open" "$TOOLS/as-trace" "$GOOD" --device cpu -W 8 -H 8 --camera "$WORK/none.cam"
finish
