#!/bin/sh
# as-trace -w whitted --materials MESH.obj: each triangle's material comes
# from the OBJ the structure was built from and the .mtl it names. On the
# fixture (a diffuse floor, a mirror, glass), the first bounce has one ray per
# primary hit on the mirror and two (reflection, refraction) per hit on the
# glass, none from the floor; without --materials the seeded default gives
# other counts. Material files that cannot be read, unknown materials,
# libraries outside the OBJ's directory and FIFOs are refused, naming the
# file and line.
. "$(dirname "$0")/cli_lib.sh"
need_python

OBJ=$DATA/whitted_materials.obj
"$TOOLS/as-build" "$OBJ" -o "$WORK/w.asf" -q || { echo "FAIL - build of $OBJ failed"; exit 1; }
CAM="--device cpu -W 64 -H 48 --eye 0,1,6 --target 0,0.8,0 --bounces 1"

run prim "$TOOLS/as-trace" $CAM --hits-out "$WORK/p.hits" "$WORK/w.asf"
expect_rc "primary hits for the expected counts" 0
# Triangles 0-1 floor, 2-3 mirror, 4-5 glass (file order, two per quad).
EXPECTED=$(python3 - "$WORK/p.hits" <<'PY'
import struct, sys
b = open(sys.argv[1], "rb").read()
count = struct.unpack_from("<Q", b, 16)[0]
prims = [struct.unpack_from("<fIff", b, 32 + 16 * i)[1] for i in range(count)]
print(sum(p in (2, 3) for p in prims) + 2 * sum(p in (4, 5) for p in prims))
PY
)

run mat "$TOOLS/as-trace" $CAM -w whitted --materials "$OBJ" "$WORK/w.asf"
expect_rc "as-trace -w whitted --materials" 0
expect_grep "materials line: 2 mirror, 2 glass, 2 opaque" "$WORK/mat.out" "^materials: $OBJ: 2 mirror, 2 glass, 2 opaque triangles, from its material files$"
expect_grep "bounce 1: a ray per mirror hit, two per glass hit ($EXPECTED)" "$WORK/mat.out" "^whitted 1 +$EXPECTED rays "
run seeded "$TOOLS/as-trace" $CAM -w whitted "$WORK/w.asf"
if grep -Eq "^whitted 1 +$EXPECTED rays " "$WORK/seeded.out"; then fail "the seeded default gives other counts"; else ok "the seeded default gives other counts"; fi
run json "$TOOLS/as-trace" $CAM -w whitted --materials "$OBJ" -f json "$WORK/w.asf"
expect_eq "JSON: material counts" "2 2 2" "$(json_get "$WORK/json.out" '"%d %d %d" % (j["opaque_triangles"], j["mirror_triangles"], j["glass_triangles"])')"

run nowhitted "$TOOLS/as-trace" $CAM --materials "$OBJ" "$WORK/w.asf"
expect_rc "--materials without the whitted workload" 1
expect_refused "--materials with a mesh the structure was not built from" "$DATA/tri.obj" 3 "not the mesh the structure was built from" \
    "$TOOLS/as-trace" $CAM -w whitted --materials "$DATA/tri.obj" "$WORK/w.asf"

# Copies of the OBJ (same geometry, so the same structure) naming other libraries.
with_lib() { sed "s|^mtllib .*|mtllib $2|" "$OBJ" >"$WORK/$1.obj"; }
with_lib missing none.mtl
expect_refused "a material file that does not exist: the file, and the OBJ's line" "$WORK/none.mtl" 2 \
    "no such file \\(mtllib on line 3 of .*missing.obj\\) \\[FILE_NOT_FOUND\\]" \
    "$TOOLS/as-trace" $CAM -w whitted --materials "$WORK/missing.obj" "$WORK/w.asf"
sed 's/^newmtl glass$/newmtl crystal/' "$DATA/whitted_materials.mtl" >"$WORK/renamed.mtl"
with_lib unknown renamed.mtl
expect_refused "usemtl of a material the library lacks: the OBJ and its line" "$WORK/unknown.obj" 3 \
    "line 20: usemtl 'glass': no material of that name" \
    "$TOOLS/as-trace" $CAM -w whitted --materials "$WORK/unknown.obj" "$WORK/w.asf"
printf 'newmtl floor\nKs 1 1\n' >"$WORK/badks.mtl"
with_lib badks badks.mtl
expect_refused "a malformed statement: the library and its line" "$WORK/badks.mtl" 3 "line 2: Ks needs 1 or 3 numbers" \
    "$TOOLS/as-trace" $CAM -w whitted --materials "$WORK/badks.obj" "$WORK/w.asf"
with_lib abs /etc/hostname
expect_refused "an absolute library path" "$WORK/abs.obj" 2 "line 3: mtllib '/etc/hostname' is an absolute path" \
    "$TOOLS/as-trace" $CAM -w whitted --materials "$WORK/abs.obj" "$WORK/w.asf"
if mkfifo "$WORK/pipe.mtl" 2>/dev/null; then
    with_lib fifo pipe.mtl
    # timeout: a reader that waited for a writer would hang here.
    expect_refused "a FIFO is refused at once" "$WORK/pipe.mtl" 2 "not a regular file \\(a FIFO\\): refused" \
        timeout 20 "$TOOLS/as-trace" $CAM -w whitted --materials "$WORK/fifo.obj" "$WORK/w.asf"
fi
finish
