set -u
# Run 88: the grid's blocks of 512 triangles (.dev/blb) against 2048 (3907e50, .dev/bl), 16 and
# 4 threads, two interleaved rounds (buildloop, 7 builds each).
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
for r in 1 2; do for s in staircase.ply.zst bmw-m6.drc bathroom.drc bunny.ply.zst; do for t in 16 4; do for v in bl blb; do
  LD_LIBRARY_PATH=$PWD/.dev/$v:$PWD/.dev/lib timeout 60 .dev/bl/bl2 $S/$s grid:grid $t 7 | sed "s/^/r$r $v /"
done; done; done; done
date -u
