# Shared by the CLI tests (sourced, not run). Each test script is called as
#   SCRIPT TOOL_DIR SOURCE_DIR [SCENES_DIR]
# and prints one line per behaviour: "ok - ..." or "FAIL - ..." with what was
# expected and what came out. Exit 0 when every check passed, 1 when one
# failed, 77 when the test cannot run here (skipped).

set -u
export LC_ALL=C

TOOLS=${1:?usage: $0 TOOL_DIR SOURCE_DIR [SCENES_DIR]}
SRC=${2:?usage: $0 TOOL_DIR SOURCE_DIR [SCENES_DIR]}
SCENES=${3:-}
DATA=$SRC/tests/data/cli
BUNNY=$SRC/scenes/bunny.drc

FAILED=0
WORK=$(mktemp -d "${TMPDIR:-/tmp}/as-cli.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT

ok() { printf 'ok - %s\n' "$1"; }
fail() {
    printf 'FAIL - %s\n' "$1"
    FAILED=1
}
finish() { exit "$FAILED"; }

# run NAME CMD...: runs CMD with stdout in $WORK/NAME.out, stderr in
# $WORK/NAME.err and the exit status in RC.
run() {
    _name=$1
    shift
    "$@" >"$WORK/$_name.out" 2>"$WORK/$_name.err"
    RC=$?
}

# expect_rc WHAT EXPECTED: checks RC from the last run.
expect_rc() {
    if [ "$RC" = "$2" ]; then ok "$1: exit $RC"; else fail "$1: expected exit $2, got $RC (stderr: $(head -c 300 "$WORK/$_name.err"))"; fi
}

# expect_grep WHAT FILE PATTERN: FILE (a run's .out or .err) has a line
# matching the extended regular expression PATTERN.
expect_grep() {
    if [ -z "$3" ]; then fail "$1: empty pattern (the expected value could not be computed)"; return; fi
    if grep -Eq -- "$3" "$2"; then
        ok "$1"
    else
        fail "$1: expected a line matching /$3/ in $(basename "$2"), got: $(head -c 400 "$2")"
    fi
}

# expect_eq WHAT EXPECTED ACTUAL
expect_eq() {
    if [ "$2" = "$3" ]; then ok "$1"; else fail "$1: expected '$2', got '$3'"; fi
}

# expect_same_file WHAT A B: byte-identical.
expect_same_file() {
    if cmp -s "$2" "$3"; then ok "$1"; else fail "$1: $(basename "$2") and $(basename "$3") differ: $(cmp "$2" "$3" 2>&1 | head -1)"; fi
}

# expect_refused WHAT FILE EXPECTED_RC PATTERN CMD...: the command (which
# reads FILE) exits EXPECTED_RC and its stderr names FILE and matches PATTERN.
expect_refused() {
    _what=$1 _file=$2 _rc=$3 _pat=$4
    shift 4
    run refused "$@"
    if [ "$RC" != "$_rc" ]; then
        fail "$_what: expected exit $_rc, got $RC (stderr: $(head -c 300 "$WORK/refused.err"))"
    elif ! grep -Fq -- "$_file" "$WORK/refused.err"; then
        fail "$_what: stderr does not name $_file: $(head -c 300 "$WORK/refused.err")"
    elif ! grep -Eq -- "$_pat" "$WORK/refused.err"; then
        fail "$_what: expected stderr matching /$_pat/, got: $(head -c 300 "$WORK/refused.err")"
    else
        ok "$_what: exit $RC, $(head -c 160 "$WORK/refused.err" | tr -d '\n')"
    fi
}

# need_scenes: skip (77) when the shared scenes are absent, except under
# CI=true, where their absence is a failure.
need_scenes() {
    if [ -z "$SCENES" ] || [ ! -d "$SCENES" ]; then
        if [ "${CI:-}" = true ]; then
            echo "FAIL - scenes directory '$SCENES' is absent and CI=true"
            exit 1
        fi
        echo "skipped: scenes directory '$SCENES' is absent (../shared/scenes)"
        exit 77
    fi
}

need_python() {
    if ! command -v python3 >/dev/null 2>&1; then
        if [ "${CI:-}" = true ]; then
            echo "FAIL - python3 is needed to write and patch binary files and CI=true"
            exit 1
        fi
        echo "skipped: python3 is needed to write and patch binary files"
        exit 77
    fi
}

# json_get FILE EXPR: evaluates the Python expression EXPR over the parsed
# JSON document `j` in FILE and prints the result.
json_get() {
    python3 -c 'import json, sys; j = json.load(open(sys.argv[1])); print(eval(sys.argv[2]))' "$1" "$2"
}

# build_bunny OUT: builds the bundled bunny once per test.
build_bunny() {
    "$TOOLS/as-build" "$BUNNY" -o "$1" -q || { echo "FAIL - as-build of $BUNNY failed, cannot go on"; exit 1; }
}

# patch SRC DST OFFSET HEX|flip: copies SRC to DST with the bytes at OFFSET
# replaced by HEX (little-endian as written), or the byte there inverted.
patch() {
    python3 - "$@" <<'PY'
import sys
src, dst, off, val = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
b = bytearray(open(src, "rb").read())
if val == "flip":
    b[off] ^= 0xFF
else:
    v = bytes.fromhex(val)
    b[off:off + len(v)] = v
open(dst, "wb").write(b)
PY
}

# le32 N: N as a little-endian int32 in hex.
le32() { python3 -c 'import struct, sys; print(struct.pack("<i", int(sys.argv[1])).hex())' "$1"; }

# section_offset JSON TAG: the section's file offset from as-inspect's JSON.
section_offset() { json_get "$1" '[s for s in j["sections"] if s["tag"] == "'"$2"'"][0]["offset"]'; }
