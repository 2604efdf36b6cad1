#!/bin/sh
# as-stiff writes a stiff case (OBJ, ray file, expected outcomes); as-build
# builds the OBJ and as-trace --rays traces it on the CPU, and every ray
# meets the outcome its .expect line states (reference lines aside): zero
# leaks on the lattice cube at 1e7, seam rays on one of the two triangles,
# in-plane grazing rays missing, bad rays missing. The same seed gives the
# same files, another seed another mesh; an unknown case is a usage error.
. "$(dirname "$0")/cli_lib.sh"
need_python

# check CASE NAME [OPTION...]: writes the case as $WORK/NAME, builds and
# traces it, then counts in BROKEN the rays that break their .expect line.
check() {
    _case=$1 _n=$2
    shift 2
    run "gen_$_n" "$TOOLS/as-stiff" "$_case" -o "$WORK/$_n" "$@"
    expect_rc "as-stiff $_case $*" 0
    run "build_$_n" "$TOOLS/as-build" "$WORK/$_n.obj" -o "$WORK/$_n.asf" -q
    expect_rc "as-build $_n.obj" 0
    run "trace_$_n" "$TOOLS/as-trace" "$WORK/$_n.asf" --device cpu --rays "$WORK/$_n.rays" --hits-out "$WORK/$_n.hits"
    expect_rc "as-trace --rays $_n.rays" 0
    BROKEN=$(python3 - "$WORK/$_n.expect" "$WORK/$_n.hits" <<'PY'
import math, struct, sys
lines = open(sys.argv[1]).read().split("\n")[:-1]
b = open(sys.argv[2], "rb").read()
count = struct.unpack_from("<Q", b, 16)[0]
hits = [struct.unpack_from("<fIff", b, 32 + 16 * i) for i in range(count)]
raw = [b[32 + 16 * i:48 + 16 * i] for i in range(count)]
assert len(lines) == count, (len(lines), count)
bad = 0
for i, line in enumerate(lines):
    w = line.split()
    kind, t, prim = w[0], hits[i][0], hits[i][1]
    listed = []
    k = 1
    while k < len(w) and w[k].isdigit():
        listed.append(int(w[k]))
        k += 1
    ok = {"hit": prim != 0xFFFFFFFF, "miss": prim == 0xFFFFFFFF and math.isinf(t), "prim": prim in listed,
          "not-prim": prim not in listed, "reference": True}[kind]
    if "same-as" in w:
        ok = ok and raw[i] == raw[int(w[w.index("same-as") + 1])]
    bad += not ok
print(bad)
PY
)
}

check watertight-cube cube --offset 1e7
expect_grep "as-stiff prints the case's outcome" "$WORK/gen_cube.out" "^outcome: +every ray hits: zero leaks"
N=$(sed -n 's/^rays: .*: \([0-9]*\) rays, closest hit$/\1/p' "$WORK/gen_cube.out")
expect_grep "lattice cube at 1e7: every ray hits (zero leaks)" "$WORK/trace_cube.out" "^file +$N rays \\(closest hit\\), $N hit: "
expect_eq "lattice cube at 1e7: every ray meets its outcome" 0 "$BROKEN"

check seam seam
expect_eq "seam: every ray hits one of the two triangles" 0 "$BROKEN"
check grazing grazing --ray-count 800
expect_eq "grazing: in-plane rays miss" 0 "$BROKEN"
check signed-zero zero --ray-count 2400
expect_eq "signed zero: +0 and -0 give the same hits" 0 "$BROKEN"
check bad-rays bad --ray-count 2000
expect_eq "bad rays: the bad copies miss" 0 "$BROKEN"

run again "$TOOLS/as-stiff" flat --ray-count 500 -o "$WORK/flat1"
run again "$TOOLS/as-stiff" flat --ray-count 500 -o "$WORK/flat2"
expect_same_file "the same seed gives the same mesh" "$WORK/flat1.obj" "$WORK/flat2.obj"
expect_same_file "the same seed gives the same rays" "$WORK/flat1.rays" "$WORK/flat2.rays"
run other "$TOOLS/as-stiff" flat --ray-count 500 --seed 3 -o "$WORK/flat3"
if cmp -s "$WORK/flat1.obj" "$WORK/flat3.obj"; then fail "another seed gives another mesh"; else ok "another seed gives another mesh"; fi

run unknown "$TOOLS/as-stiff" no-such-case
expect_rc "an unknown case is a usage error" 1
finish
