set -u
# Run 121: binned SAH at 5fae42e with phase timers (bl3-s19i: set-up, build, tree write), 2-16 threads.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for f in ('bl3-s19i',):
    open('/tmp/'+f,'wb').write(lzma.open('.dev/z17/'+f+'.xz').read()); os.chmod('/tmp/'+f,0o755)
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
for s in bunny.ply.zst staircase2.ply.zst staircase.ply.zst bathroom.drc; do
  for t in 2 4 8 16; do
    echo "== $s t$t"; timeout 60 /tmp/bl3-s19i $S/$s bvh:sah $t 30 2>&1 | grep -vE "^[0-9 ]+$" | sed 's/\/[^ ]*\.\(drc\|zst\)//'
  done
done
date -u
