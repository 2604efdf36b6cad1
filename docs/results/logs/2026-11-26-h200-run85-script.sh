set -u
# Run 85: grid and BIH against the thread count after 35d8a1d-3907e50 (grid: the cells a large
# triangle's plane reaches, counts from a kept block; BIH: kept blocks, the task pool, the SAH
# summed while writing), binned SAH beside them (buildloop: one import, 7 builds).
export LD_LIBRARY_PATH=$PWD/.dev/bl:$PWD/.dev/lib
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
for s in staircase.ply.zst bathroom.drc bmw-m6.drc bunny.ply.zst; do for b in bvh:sah grid:grid bih:bih; do for t in 1 4 16; do
  timeout 60 .dev/bl/bl2 $S/$s $b $t 7
done; done; echo "(at $(el) s)"; done
date -u; echo "total $(el) s"
