#!/bin/sh
# as-trace --device cpu with a ray file: a ray aimed at the bunny's centre
# from outside hits it, a ray pointing away misses (prim 0xFFFFFFFF, t = +inf),
# the hit file has the header of formats/SPEC.md section 4; --image writes a
# PNG of the requested size; bad ray files are refused with exit 3.
. "$(dirname "$0")/cli_lib.sh"
need_python

ASF=$WORK/bunny.asf
build_bunny "$ASF"
# Bunny box (-0.0947, 0.0330, -0.0619)-(0.0610, 0.1873, 0.0588); centre
# (-0.0168, 0.1102, -0.0015). Rays start at z = +1 or -1, beyond the box.
python3 - "$WORK/probe.rays" <<'PY'
import struct, sys
inf = float("inf")
cx, cy = -0.0168405, 0.110152
rays = [
    (cx, cy, 1.0, 0.0, 0.0, 0.0, -1.0, inf),   # 0: from +z at the centre: hit
    (cx, cy, 1.0, 0.0, 0.0, 0.0, 1.0, inf),    # 1: from +z pointing away: miss
    (cx, cy, -1.0, 0.0, 0.0, 0.0, 1.0, inf),   # 2: from -z at the centre: hit
    (cx, cy, 1.0, 0.0, 0.0, 0.0, -1.0, 0.5),   # 3: towards it but tmax short of the box: miss
    (cx, cy, 1.0, 0.0, 0.0, 0.0, -2.0, inf),   # 4: ray 0 with a direction twice as long: t halves
]
with open(sys.argv[1], "wb") as f:
    f.write(b"ASRAYS\0\0" + struct.pack("<HHIQQ", 1, 0, 32, len(rays), 0))
    for r in rays:
        f.write(struct.pack("<8f", *r))
PY
run trace "$TOOLS/as-trace" --device cpu --rays "$WORK/probe.rays" --hits-out "$WORK/probe.hits" "$ASF"
expect_rc "as-trace --rays --hits-out" 0
expect_grep "summary: 5 rays, 3 hit" "$WORK/trace.out" "^file +5 rays \\(closest hit\\), 3 hit: "
expect_grep "summary: cpu device" "$WORK/trace.out" "^device: +cpu "
expect_grep "summary: Mrays/s" "$WORK/trace.out" "^Mrays/s: +[0-9]+\\.[0-9]+ \\(file\\)$"
expect_grep "summary: hit file written" "$WORK/trace.out" "^hits: +$WORK/probe.hits$"

H=$WORK/probe.hits
hits() { python3 - "$H" "$1" <<'PY'
import math, struct, sys
b = open(sys.argv[1], "rb").read()
magic, major, minor, rsize, count, reserved = struct.unpack_from("<8sHHIQQ", b, 0)
recs = [struct.unpack_from("<fIff", b, 32 + 16 * i) for i in range(count)]
print(eval(sys.argv[2]))
PY
}
expect_eq "hit file size: 32 + 5 x 16" "112" "$(wc -c <"$H" | tr -d ' ')"
expect_eq "hit file header" "(b'ASHITS\\x00\\x00', 1, 0, 16, 5, 0)" "$(hits '(magic, major, minor, rsize, count, reserved)')"
expect_eq "ray 0 (at the centre from +z) hits a triangle of the mesh" "True" "$(hits 'recs[0][1] < 69451')"
expect_eq "ray 0 hits where the box says (0.94 <= t <= 1.07)" "True" "$(hits '0.94 <= recs[0][0] <= 1.07')"
expect_eq "ray 0 barycentrics inside the triangle" "True" "$(hits 'recs[0][2] >= 0 and recs[0][3] >= 0 and recs[0][2] + recs[0][3] <= 1')"
expect_eq "ray 1 (pointing away) misses: prim 0xFFFFFFFF, t = +inf" "0xffffffff inf" "$(hits '"0x%08x %r" % (recs[1][1], recs[1][0])')"
expect_eq "ray 2 (at the centre from -z) hits" "True" "$(hits 'recs[2][1] < 69451 and 0.93 <= recs[2][0] <= 1.07')"
expect_eq "ray 2 hits another triangle than ray 0 (the far side)" "True" "$(hits 'recs[2][1] != recs[0][1]')"
expect_eq "ray 3 (tmax 0.5, short of the box) misses" "0xffffffff inf" "$(hits '"0x%08x %r" % (recs[3][1], recs[3][0])')"
expect_eq "ray 4 (direction twice as long) hits the same triangle at half the t" "True" "$(hits 'recs[4][1] == recs[0][1] and abs(recs[4][0] * 2 - recs[0][0]) <= 1e-6')"

# --image: a PNG of the requested size.
run image "$TOOLS/as-trace" --device cpu -W 80 -H 60 --image "$WORK/bunny.png" "$ASF"
expect_rc "as-trace --image" 0
expect_grep "summary: camera" "$WORK/image.out" "^camera: +eye .* fov 45, 80x60$"
expect_grep "summary: 4800 rays" "$WORK/image.out" "^primary +4800 rays \\(closest hit\\), [1-9][0-9]* hit: "
expect_eq "PNG signature and IHDR 80 x 60, 8-bit RGB" "True 80 60 8 2" \
    "$(python3 -c 'import struct, sys; b = open(sys.argv[1], "rb").read(); w, h, d, c = struct.unpack(">IIBB", b[16:26]); print(b[:8] == b"\x89PNG\r\n\x1a\n" and b[12:16] == b"IHDR", w, h, d, c)' "$WORK/bunny.png")"
expect_eq "PNG ends with IEND" "True" "$(python3 -c 'import sys; print(open(sys.argv[1], "rb").read()[-8:-4] == b"IEND")' "$WORK/bunny.png")"
run cam "$TOOLS/as-trace" --device cpu -W 32 -H 32 --eye 0,0.1,0.5 --target 0,0.1,0 --fov 30 --image "$WORK/cam.png" "$ASF"
expect_rc "as-trace with an explicit camera" 0
expect_grep "explicit camera echoed" "$WORK/cam.out" "^camera: +eye 0,0.1,0.5 target 0,0.1,0 up 0,1,0 fov 30, 32x32$"
run both "$TOOLS/as-trace" --device cpu --rays "$WORK/probe.rays" --image "$WORK/x.png" "$ASF"
expect_rc "--image with --rays" 1

# Bad ray files: exit 3, message naming the file.
head -c 40 "$WORK/probe.rays" >"$WORK/short.rays"
expect_refused "ray file shorter than its count says" "$WORK/short.rays" 3 "truncated: header says 5 records, 192 bytes; file has 40 bytes \\[CORRUPT\\]" \
    "$TOOLS/as-trace" --device cpu --rays "$WORK/short.rays" "$ASF"
head -c 20 "$WORK/probe.rays" >"$WORK/tiny.rays"
expect_refused "ray file shorter than its header" "$WORK/tiny.rays" 3 "file is 20 bytes, shorter than the 32-byte header \\[CORRUPT\\]" \
    "$TOOLS/as-trace" --device cpu --rays "$WORK/tiny.rays" "$ASF"
expect_refused "hit file given as a ray file" "$H" 3 "a hit file, not a ray file \\[CORRUPT\\]" \
    "$TOOLS/as-trace" --device cpu --rays "$H" "$ASF"
patch "$WORK/probe.rays" "$WORK/bad.rays" 0 flip
expect_refused "ray file with a damaged magic" "$WORK/bad.rays" 3 "not a ray file \\(bad magic at offset 0\\) \\[CORRUPT\\]" \
    "$TOOLS/as-trace" --device cpu --rays "$WORK/bad.rays" "$ASF"
patch "$WORK/probe.rays" "$WORK/bad.rays" 12 10000000
expect_refused "ray file with record size 16" "$WORK/bad.rays" 3 "record_size 16 at offset 12, a ray record is 32 bytes \\[CORRUPT\\]" \
    "$TOOLS/as-trace" --device cpu --rays "$WORK/bad.rays" "$ASF"
patch "$WORK/probe.rays" "$WORK/bad.rays" 24 01
expect_refused "ray file with a reserved byte set" "$WORK/bad.rays" 3 "reserved field at offset 24 is 0x0000000000000001, not zero \\[CORRUPT\\]" \
    "$TOOLS/as-trace" --device cpu --rays "$WORK/bad.rays" "$ASF"
patch "$WORK/probe.rays" "$WORK/bad.rays" 8 0200
expect_refused "ray file of major version 2" "$WORK/bad.rays" 5 "ray file version 2\\.0 is newer than this reader \\(1\\.x\\) \\[VERSION\\]" \
    "$TOOLS/as-trace" --device cpu --rays "$WORK/bad.rays" "$ASF"
expect_refused "missing ray file" "$WORK/none.rays" 2 "no such file \\[FILE_NOT_FOUND\\]" \
    "$TOOLS/as-trace" --device cpu --rays "$WORK/none.rays" "$ASF"
finish
