set -u
# Run 84: build time against the thread count (1 to 16) for binned SAH, grid, BIH and SBVH at
# 9497cb1, with each build's system time and minor page faults (buildloop: one import, 7 builds).
export LD_LIBRARY_PATH=$PWD/.dev/bl:$PWD/.dev/lib
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
for s in staircase.ply.zst bmw-m6.drc; do for b in bvh:sah grid:grid bih:bih bvh:sbvh; do for t in 1 2 4 8 16; do
  timeout 60 .dev/bl/bl2 $S/$s $b $t 7
done; done; echo "(at $(el) s)"; done
date -u; echo "total $(el) s"
