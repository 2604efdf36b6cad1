set -u
# Run 139: 16 threads, paired A/B in one process: g = e7eeba4, p = several parallel steps published at once in the task pool. Then timelines of p, binned SAH, bunny.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for d in ('g','p'):
    os.makedirs('/tmp/b16/'+d,exist_ok=True)
    open('/tmp/b16/'+d+'/libas.so.0','wb').write(lzma.open('.dev/z/'+d+'/libas.so.0.xz').read())
open('/tmp/b16/loopd','wb').write(lzma.open('.dev/z/loopd.xz').read()); os.chmod('/tmp/b16/loopd',0o755)
"
S=$PWD/.dev/scenes; A=.dev/z/abdl
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
cp /lib/x86_64-linux-gnu/libc.so.6 $OUT/libc.so.6
for a in "bunny.ply.zst bvh:sah 61" "staircase.ply.zst bvh:sah 31" "bathroom.drc bvh:sah 21" "bunny.ply.zst bvh:sbvh 31" "bathroom.drc bvh:sbvh 11" "bmw-m6.drc bvh:sbvh 9" "bunny.ply.zst kd:sah 21" "staircase2.ply.zst bih:bih 41" "bunny.ply.zst bih:bih 41"; do set -- $a
  timeout 100 $A /tmp/b16/g /tmp/b16/p $S/$1 $2 16 $3
done
echo "ab done at $(el) s"
SAMPLER_CLOCK=wall SAMPLER_US=100 SAMPLER_OUT=$OUT/smp-bunny-p LD_PRELOAD=$PWD/.dev/prof/sampler.so LD_LIBRARY_PATH=/tmp/b16/p:$LD_LIBRARY_PATH /tmp/b16/loopd $S/bunny.ply.zst bvh sah 16 300 | tail -1
gzip $OUT/smp-*
date -u; echo "total $(el) s"
