#!/bin/sh
# as-build killed with SIGKILL while it builds over an existing .asf file
# leaves either the previous file, byte-identical, or the whole new one,
# never a mixture: killed while the temporary file is being written, the
# previous file; killed at a moment during the build, whichever of the two
# the rename had made it by then. The only trace a killed writer can leave
# is its temporary file, named FILE.tmp.XXXXXX beside the target
# (formats/atomic_file.h); nothing reads such files, and they may be deleted.
# A run that is not killed replaces the file, so a writer that wrote in
# place would be caught half-way.
. "$(dirname "$0")/cli_lib.sh"
need_python

# A generated mesh (300,000 small random triangles, 15 MB of binary STL)
# that takes as-build about a second: long enough to be caught mid-way.
MESH=$WORK/random.stl
python3 - "$MESH" 300000 <<'PY'
import random, struct, sys
n = int(sys.argv[2])
r = random.Random(1)
rec = struct.Struct('<12fH')
out = [b'\0' * 80, struct.pack('<I', n)]
for _ in range(n):
    x, y, z = r.random(), r.random(), r.random()
    out.append(rec.pack(0, 0, 0, x, y, z, x + 0.01, y, z, x, y + 0.01, z + 0.005, 0))
open(sys.argv[1], 'wb').write(b''.join(out))
PY
[ -s "$MESH" ] || { echo "FAIL - could not write $MESH"; exit 1; }

ASF=$WORK/scene.asf
run previous "$TOOLS/as-build" "$SRC/tests/data/cube.obj" -o "$ASF" -q
expect_rc "the previous file is built" 0
cp "$ASF" "$WORK/previous.asf"

# kill_build WHEN: starts as-build over $ASF and SIGKILLs it either after
# WHEN seconds or, for WHEN=write, as soon as it starts writing: its
# temporary file appears, or the target itself changes (a writer that
# wrote in place would be caught half-way).
# Prints what happened: "killed", or "finished" when the build won the race.
kill_build() {
    python3 - "$TOOLS/as-build" "$MESH" "$ASF" "$1" <<'PY'
import os, signal, subprocess, sys, time
tool, mesh, asf, when = sys.argv[1:5]
before = os.stat(asf)
p = subprocess.Popen([tool, mesh, "-o", asf, "--threads", "1", "--no-build-record", "-q"],
                     stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
d, base = os.path.dirname(asf), os.path.basename(asf) + ".tmp."
deadline = time.monotonic() + (60 if when == "write" else float(when))
def writing():
    now = os.stat(asf)
    return (any(n.startswith(base) for n in os.listdir(d)) or
            (now.st_ino == before.st_ino and (now.st_size, now.st_mtime_ns) != (before.st_size, before.st_mtime_ns)))
while p.poll() is None and time.monotonic() < deadline:
    if when == "write" and writing():
        break
    time.sleep(0.0005)
if p.poll() is None:
    p.send_signal(signal.SIGKILL)
    p.wait()
    print("killed")
else:
    print("finished")
PY
}

# A whole build, timed, so that the first kill lands inside the import and
# build on a machine of any speed; its output is what a finished build
# writes (no build record: the same bytes every time).
full=$(python3 - "$TOOLS/as-build" "$MESH" -o "$WORK/complete.asf" --threads 1 --no-build-record -q <<'PY'
import subprocess, sys, time
start = time.monotonic()
subprocess.run(sys.argv[1:], check=True)
print(time.monotonic() - start)
PY
) || { echo "FAIL - as-build of $MESH failed, cannot go on"; exit 1; }
early=$(python3 -c "import sys; print(round(0.3 * float(sys.argv[1]), 4))" "$full")
echo "# a whole build takes ${full}s here; the first kill comes after ${early}s"

for when in "$early" write; do
    outcome=$(kill_build "$when")
    # The write round must catch the writer mid-write; a timed kill may come
    # too late on a loaded machine, which leaves nothing to check but the
    # file it wrote.
    if [ "$outcome" = killed ]; then
        ok "as-build killed ($when)"
    elif [ "$when" = write ]; then
        fail "as-build finished before it could be killed ($when)"
    else
        ok "as-build finished before the kill after ${when}s (a loaded machine)"
    fi
    if cmp -s "$ASF" "$WORK/previous.asf"; then
        ok "previous file byte-identical after as-build was killed ($when)"
    elif [ "$when" != write ] && cmp -s "$ASF" "$WORK/complete.asf"; then
        ok "the whole new file after as-build was killed ($when), past its rename"
    else
        fail "after as-build was killed ($when) the target is neither the previous file nor the whole new one: $(cmp "$ASF" "$WORK/previous.asf" 2>&1 | head -1)"
    fi
    run inspect "$TOOLS/as-inspect" "$ASF" --validate
    expect_rc "the target loads and validates after the kill ($when)" 0
    # What a kill may leave: only temporary files of the documented pattern.
    others=$(ls "$WORK" | grep -F 'scene.asf.' | grep -Ev '^scene\.asf\.tmp\.[A-Za-z0-9]{6}$' || true)
    expect_eq "nothing but FILE.tmp.XXXXXX left beside the target ($when)" "" "$others"
    stale=$(ls "$WORK" | grep -E '^scene\.asf\.tmp\.' | tr '\n' ' ')
    [ -n "$stale" ] && echo "# stale temporary file(s) after the kill ($when): $stale"
    rm -f "$WORK"/scene.asf.tmp.*
    cp "$WORK/previous.asf" "$ASF"
done

# Not killed, the same build replaces the file.
run finish "$TOOLS/as-build" "$MESH" -o "$ASF" --threads 1 --no-build-record -q
expect_rc "as-build run to the end" 0
expect_same_file "the completed build replaced the file with the whole new one" "$WORK/complete.asf" "$ASF"
finish
