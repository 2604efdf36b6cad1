set -u
# Run 119: eef89c3 (bl3-s17) against 175af51 (bl3-s18), interleaved, 16 threads: the grid with its
# ranges dealt out in runs of 64 cells and its SAH cost in one expression; binned SAH with the
# binning's noted bins, loose frames and the AVX2 ranks of the exact subtrees. Then 1-16 threads.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for f in ('bl3-s17','bl3-s18'):
    open('/tmp/'+f,'wb').write(lzma.open('.dev/z17/'+f+'.xz').read()); os.chmod('/tmp/'+f,0o755)
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"; grep -o -w avx2 /proc/cpuinfo | head -1
run() { timeout 100 /tmp/$1 $S/$2 $3 $4 $5 2>&1 | grep -vE "^[0-9 ]+$" | sed 's/\/[^ ]*\.\(drc\|zst\)//; s/cpu\/build.*//; s/(n=[0-9]*)//g'; }
for round in 1 2 3; do
  for s in staircase.ply.zst bathroom.drc bmw-m6.drc; do
    for b in bl3-s17 bl3-s18; do echo -n "$b "; run $b $s grid:grid 16 10; done
  done
  for s in bunny.ply.zst staircase.ply.zst bathroom.drc; do
    for b in bl3-s17 bl3-s18; do echo -n "$b "; run $b $s bvh:sah 16 10; done
  done
done
echo "--- threads"
for t in 1 2 4 8 16; do
  for s in staircase.ply.zst bathroom.drc; do
    for bu in bvh:sah grid:grid kd:sah; do echo -n "s18 "; run bl3-s18 $s $bu $t 5; done
  done
done
date -u
