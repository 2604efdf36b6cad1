set -u
# Run 146: 16 threads, paired: u = blocked KD/BIH SAH sums and bins as build temporaries against s = 23b9aef.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for d in ('s','u'):
    os.makedirs('/tmp/b16/'+d,exist_ok=True)
    open('/tmp/b16/'+d+'/libas.so.0','wb').write(lzma.open('.dev/z/'+d+'/libas.so.0.xz').read())
open('/tmp/b16/loopd','wb').write(lzma.open('.dev/z/loopd.xz').read()); os.chmod('/tmp/b16/loopd',0o755)
"
S=$PWD/.dev/scenes; A=.dev/z/abdl
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
for a in "bunny.ply.zst bvh:sah 81" "staircase2.ply.zst bvh:sah 81" "staircase.ply.zst bvh:sah 31" "bathroom.drc bvh:sah 21" "bunny.ply.zst bvh:sbvh 31" "bmw-m6.drc bvh:sbvh 9" "bunny.ply.zst kd:sah 31" "staircase2.ply.zst kd:sah 31" "bathroom.drc kd:sah 7" "bunny.ply.zst bih:bih 41"; do set -- $a
  timeout 100 $A /tmp/b16/s /tmp/b16/u $S/$1 $2 16 $3
done
for L in s u; do for a in "staircase2.ply.zst bvh sah 300" "bunny.ply.zst kd sah 40"; do set -- $a; LD_LIBRARY_PATH=/tmp/b16/$L:$LD_LIBRARY_PATH /tmp/b16/loopd $S/$1 $2 $3 16 $4 | tail -1; done; done
date -u; echo "total $(el) s"
