set -u
# Run 94: the task pool publishing several parallel steps at once (B) against one at a time (A, 7e0d5cd),
# same bytes; build time against the thread count, interleaved rounds, median of 5 builds each.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma
for d in 'AB':
    open('.dev/ab/%s/libas.so.0' % d,'wb').write(lzma.open('.dev/ab/%s/libas.so.0.1.0.xz' % d).read())
"
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S=$PWD/.dev/scenes; S0=$(date +%s)
for sc in staircase.ply.zst bathroom.drc bmw-m6.drc; do
 for b in kd:sah bvh:sah bvh:sbvh bih:bih; do
  for t in 16 8 4; do
   for r in 1 2; do for v in A B; do
    echo -n "$v r$r "; LD_LIBRARY_PATH=$PWD/.dev/ab/$v:$PWD/.dev/lib timeout 60 .dev/ab/bl $S/$sc $b $t 5
   done; done
  done
 done
 echo "(at $(( $(date +%s) - S0 )) s)"
done
date -u
