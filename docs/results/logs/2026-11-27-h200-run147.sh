set -u
# Run 147: 16 threads, paired: v = BIH subtrees shared from 1,024 objects and grid units of up to 2,048 cells, against u = 9a60d27.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for d in ('u','v'):
    os.makedirs('/tmp/b16/'+d,exist_ok=True)
    open('/tmp/b16/'+d+'/libas.so.0','wb').write(lzma.open('.dev/z/'+d+'/libas.so.0.xz').read())
open('/tmp/b16/loopd','wb').write(lzma.open('.dev/z/loopd.xz').read()); os.chmod('/tmp/b16/loopd',0o755)
"
S=$PWD/.dev/scenes; A=.dev/z/abdl
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
for a in "staircase2.ply.zst grid:grid 81" "bunny.ply.zst grid:grid 61" "staircase.ply.zst grid:grid 31" "bathroom.drc grid:grid 21" "bmw-m6.drc grid:grid 15" "staircase2.ply.zst bih:bih 81" "bunny.ply.zst bih:bih 61" "staircase.ply.zst bih:bih 31" "bathroom.drc bih:bih 21" "staircase2.ply.zst bvh:sah 81"; do set -- $a
  timeout 100 $A /tmp/b16/u /tmp/b16/v $S/$1 $2 16 $3
done
date -u; echo "total $(el) s"
