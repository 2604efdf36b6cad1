#!/bin/sh
# Writes the seed corpus of fuzz_mesh_import (fuzz/corpus/mesh_import) from
# the tiny meshes of tests/data: each seed is the harness's parameter byte
# (the format: 0 OBJ, 1 PLY, 2 OFF, 3 STL, 4 Draco; +8 for NAME.EXT.zst)
# followed by the file. The Draco seeds need draco_encoder (Debian: draco),
# the compressed ones zstd. Run from the repository root; the outputs are
# committed:
#   fuzz/make_mesh_seeds.sh
set -eu
data=tests/data
out=fuzz/corpus/mesh_import
work=$(mktemp -d "${TMPDIR:-/tmp}/as_mesh_seeds.XXXXXX")
trap 'rm -rf "$work"' EXIT
mkdir -p "$out"

# seed NAME PARAM FILE
seed() {
    printf "\\$(printf '%03o' "$2")" >"$out/$1"
    cat "$3" >>"$out/$1"
}

seed cube_obj 0 $data/cube.obj
seed attributes_obj 0 $data/attributes.obj
seed nan_obj 0 $data/nan.obj
seed degenerate_ply 1 $data/degenerate.ply
seed quad_binary_ply 1 $data/quad_binary.ply
seed truncated_binary_ply 1 $data/truncated_binary.ply
seed bad_element_count_ply 1 $data/bad_element_count.ply
seed tri_off 2 $data/tri.off
seed tri_normals_off 2 $data/tri_normals.off
seed index_out_of_range_off 2 $data/index_out_of_range.off
seed short_face_off 2 $data/short_face.off
seed off_counts_line_two_numbers_off 2 $data/off_counts_line_two_numbers.off
seed off_vertex_line_short_off 2 $data/off_vertex_line_short.off
seed off_normal_short_off 2 $data/off_normal_short.off
seed coff_face_colours_off 2 $data/coff_face_colours.off
seed tiny_ascii_stl 3 $data/tiny.stl
seed tiny_binary_stl 3 $data/tiny_binary.stl
seed quad_binary_ply_zst 9 $data/quad_binary.ply.zst
seed tri_normals_off_zst 10 $data/tri_normals.off.zst
seed damaged_ply_zst 9 $data/damaged.ply.zst
seed truncated_ply_zst 9 $data/truncated.ply.zst

draco_encoder -i $data/cube.obj -o "$work/cube.drc" -cl 7 >/dev/null
seed cube_drc 4 "$work/cube.drc"
draco_encoder -i $data/cube.obj -o "$work/cube_points.drc" -point_cloud >/dev/null
seed cube_points_drc 4 "$work/cube_points.drc"
zstd -q -19 -c "$work/cube.drc" >"$work/cube.drc.zst"
seed cube_drc_zst 12 "$work/cube.drc.zst"
zstd -q -19 -c $data/tiny_binary.stl >"$work/tiny_binary.stl.zst"
seed tiny_binary_stl_zst 11 "$work/tiny_binary.stl.zst"
zstd -q -19 -c $data/cube.obj >"$work/cube.obj.zst"
seed cube_obj_zst 8 "$work/cube.obj.zst"
