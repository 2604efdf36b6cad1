set -u
# Run 124: the grid's one-thread passes on small scenes: 6549ef4 with phase timers (bl3-s21a) against
# the same with its bounds pass parallel from 32,768 triangles and its zeroing and prefix sum from
# 131,072 cells (bl3-s21b; 262,144 and 1,048,576 before), interleaved, 16, 8 and 2 threads.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for f in ('bl3-s21a','bl3-s21b'):
    open('/tmp/'+f,'wb').write(lzma.open('.dev/z17/'+f+'.xz').read()); os.chmod('/tmp/'+f,0o755)
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
for round in 1 2 3; do
  for t in 16 8 2; do
    for s in bunny.ply.zst staircase2.ply.zst staircase.ply.zst; do
      for b in bl3-s21a bl3-s21b; do echo "== $b $s t$t"; timeout 60 /tmp/$b $S/$s grid:grid $t 20 2>&1 | grep -vE "^[0-9 ]+$" | sed 's/\/[^ ]*\.\(drc\|zst\)//'; done
    done
  done
done
date -u
