set -u
# Run 87: where the grid's and the BIH's time goes on 16 threads: 3907e50 with phase timers
# printed by the builders (.dev/blp, not committed code), buildloop, 3 builds each.
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
for s in staircase.ply.zst bathroom.drc bmw-m6.drc; do for b in grid:grid bih:bih; do for t in 1 16; do
  LD_LIBRARY_PATH=$PWD/.dev/blp:$PWD/.dev/lib timeout 60 .dev/bl/bl2 $S/$s $b $t 3 2>&1 | grep -v "bih depth [2-5]" | tail -4
done; done; done
date -u
