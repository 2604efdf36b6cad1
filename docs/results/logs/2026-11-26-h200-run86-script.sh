set -u
# Run 86: grid and BIH, 9497cb1 (.dev/bla) against 3907e50 (.dev/bl), interleaved in one run,
# 4 and 16 threads (buildloop: one import, 7 builds each).
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
for r in 1 2; do for s in staircase.ply.zst bathroom.drc bmw-m6.drc; do for b in grid:grid bih:bih; do for t in 4 16; do for v in bla bl; do
  LD_LIBRARY_PATH=$PWD/.dev/$v:$PWD/.dev/lib timeout 60 .dev/bl/bl2 $S/$s $b $t 7 | sed "s/^/r$r $v /"
done; done; done; done; echo "(at $(el) s)"; done
date -u; echo "total $(el) s"
