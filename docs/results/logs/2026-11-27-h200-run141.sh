set -u
# Run 141: 16 threads, paired A/B: r = q + crew threads start a batch seen while watching without the lock; q = several steps published at once + adaptive pool mutex; g = e7eeba4. Then timelines of r.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for d in ('g','q','r'):
    os.makedirs('/tmp/b16/'+d,exist_ok=True)
    open('/tmp/b16/'+d+'/libas.so.0','wb').write(lzma.open('.dev/z/'+d+'/libas.so.0.xz').read())
open('/tmp/b16/loopd','wb').write(lzma.open('.dev/z/loopd.xz').read()); os.chmod('/tmp/b16/loopd',0o755)
"
S=$PWD/.dev/scenes; A=.dev/z/abdl
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
cp /lib/x86_64-linux-gnu/libc.so.6 $OUT/libc.so.6
for a in "bunny.ply.zst bvh:sah 61" "staircase.ply.zst bvh:sah 31" "bathroom.drc bvh:sah 21" "bunny.ply.zst bvh:sbvh 31" "bunny.ply.zst kd:sah 21" "staircase2.ply.zst grid:grid 41"; do set -- $a
  echo "-- q vs r"; timeout 100 $A /tmp/b16/q /tmp/b16/r $S/$1 $2 16 $3
  echo "-- g vs r"; timeout 100 $A /tmp/b16/g /tmp/b16/r $S/$1 $2 16 $3
done
echo "ab done at $(el) s"
for L in g q r; do LD_LIBRARY_PATH=/tmp/b16/$L:$LD_LIBRARY_PATH /tmp/b16/loopd $S/bunny.ply.zst bvh sah 16 300 | tail -1; done
SAMPLER_CLOCK=wall SAMPLER_US=100 SAMPLER_OUT=$OUT/smp-bunny-r LD_PRELOAD=$PWD/.dev/prof/sampler.so LD_LIBRARY_PATH=/tmp/b16/r:$LD_LIBRARY_PATH /tmp/b16/loopd $S/bunny.ply.zst bvh sah 16 300 | tail -1
gzip $OUT/smp-*
date -u; echo "total $(el) s"
