set -u
# Run 96: KD SAH on many threads. A: 5580b69. B: the larger of two big children always shared (KD driver).
# C: B and the task pool publishing several parallel steps at once. Same bytes; interleaved rounds, median of 5.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma
for d in 'ABC':
    open('.dev/ab/%s/libas.so.0' % d,'wb').write(lzma.open('.dev/ab/%s/libas.so.0.xz' % d).read())
"
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S=$PWD/.dev/scenes; S0=$(date +%s)
for sc in staircase.ply.zst bathroom.drc bmw-m6.drc; do
 for t in 16 8; do for r in 1 2 3; do for v in A B C; do
  echo -n "$v r$r "; LD_LIBRARY_PATH=$PWD/.dev/ab/$v:$PWD/.dev/lib timeout 60 .dev/ab/bl $S/$sc kd:sah $t 5
 done; done; done
 for b in bvh:sah bvh:sbvh; do for r in 1 2 3; do for v in A C; do
  echo -n "$v r$r "; LD_LIBRARY_PATH=$PWD/.dev/ab/$v:$PWD/.dev/lib timeout 60 .dev/ab/bl $S/$sc $b 16 5
 done; done; done
 echo "(at $(( $(date +%s) - S0 )) s)"
done
date -u
