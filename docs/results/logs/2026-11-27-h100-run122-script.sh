set -u
# Run 122: the build memory cache from 1 MB instead of 4 (bl3-s20) against 5fae42e (bl3-s19),
# interleaved, 16 and 2 threads: binned SAH, grid, BIH, KD SAH on the small scenes.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for f in ('bl3-s19','bl3-s20'):
    open('/tmp/'+f,'wb').write(lzma.open('.dev/z17/'+f+'.xz').read()); os.chmod('/tmp/'+f,0o755)
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
run() { timeout 100 /tmp/$1 $S/$2 $3 $4 $5 2>&1 | grep -vE "^[0-9 ]+$" | sed 's/\/[^ ]*\.\(drc\|zst\)//; s/(n=[0-9]*)//g'; }
for round in 1 2 3; do
  for t in 16 2; do
    for s in bunny.ply.zst staircase2.ply.zst staircase.ply.zst; do
      for bu in bvh:sah grid:grid bih:bih; do
        for b in bl3-s19 bl3-s20; do echo -n "$b $s "; run $b $s $bu $t 20; done
      done
    done
    for b in bl3-s19 bl3-s20; do echo -n "$b bunny "; run $b bunny.ply.zst kd:sah $t 10; done
  done
done
date -u
