#!/bin/sh
# Every tool: --help and --version exit 0 on stdout, --help documents the exit
# codes, an unknown option or a missing option argument exits 1 with a
# message on stderr and nothing on stdout.
. "$(dirname "$0")/cli_lib.sh"

for tool in as-build as-inspect as-convert as-trace; do
    run help "$TOOLS/$tool" --help
    expect_rc "$tool --help" 0
    expect_grep "$tool --help prints usage on stdout" "$WORK/help.out" "^Usage: $tool "
    expect_eq "$tool --help writes nothing on stderr" "" "$(cat "$WORK/help.err")"
    expect_grep "$tool --help documents exit code 2" "$WORK/help.out" "2 I/O error"
    expect_grep "$tool --help documents exit code 3" "$WORK/help.out" "3 invalid input file"
    expect_grep "$tool --help documents exit code 5" "$WORK/help.out" "5 unsupported"

    run version "$TOOLS/$tool" --version
    expect_rc "$tool --version" 0
    expect_grep "$tool --version prints name and version on stdout" "$WORK/version.out" "^$tool \\(libas\\) [0-9]+\\.[0-9]+\\.[0-9]+$"
    run version "$TOOLS/$tool" -V
    expect_rc "$tool -V" 0

    run unknown "$TOOLS/$tool" --no-such-option
    expect_rc "$tool --no-such-option" 1
    expect_grep "$tool --no-such-option names the option on stderr" "$WORK/unknown.err" "^$tool: .*--no-such-option"
    expect_eq "$tool --no-such-option writes nothing on stdout" "" "$(cat "$WORK/unknown.out")"

    run noargs "$TOOLS/$tool"
    expect_rc "$tool without a file" 1
    expect_grep "$tool without a file says so on stderr" "$WORK/noargs.err" "^$tool: expected one"
done

# An option whose argument is missing (it is the last word).
run missing "$TOOLS/as-build" "$BUNNY" -o
expect_rc "as-build MESH -o (no argument)" 1
expect_grep "as-build -o without argument names the option" "$WORK/missing.err" "^as-build: .*'-o'"
run missing "$TOOLS/as-build" "$BUNNY"
expect_rc "as-build MESH without -o" 1
expect_grep "as-build without -o says so" "$WORK/missing.err" "missing -o"
run missing "$TOOLS/as-inspect" x.asf --format
expect_rc "as-inspect --format (no argument)" 1
expect_grep "as-inspect --format without argument names the option" "$WORK/missing.err" "^as-inspect: .*--format"
run missing "$TOOLS/as-inspect" x.asf --format yaml
expect_rc "as-inspect --format yaml" 1
expect_grep "as-inspect --format yaml names the format" "$WORK/missing.err" "unknown format 'yaml'"
run missing "$TOOLS/as-convert" x.asf
expect_rc "as-convert IN without -o" 1
expect_grep "as-convert without -o says so" "$WORK/missing.err" "missing -o"
run missing "$TOOLS/as-trace" x.asf --rays
expect_rc "as-trace --rays (no argument)" 1
expect_grep "as-trace --rays without argument names the option" "$WORK/missing.err" "^as-trace: .*--rays"
run missing "$TOOLS/as-trace" x.asf --device tpu
expect_rc "as-trace --device tpu" 1
expect_grep "as-trace --device tpu names the device" "$WORK/missing.err" "unknown device 'tpu'"
run missing "$TOOLS/as-trace" x.asf --eye 0,0,1
expect_rc "as-trace --eye without --target" 1
expect_grep "as-trace --eye without --target says they go together" "$WORK/missing.err" "--eye and --target go together"
finish
