set -u
# Run 145: 16 threads: BIH pieces from 8,192 objects (t) against 23b9aef (s), paired; timelines of grid and BIH on staircase2 and of KD SAH on bunny (t).
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for d in ('s','t'):
    os.makedirs('/tmp/b16/'+d,exist_ok=True)
    open('/tmp/b16/'+d+'/libas.so.0','wb').write(lzma.open('.dev/z/'+d+'/libas.so.0.xz').read())
open('/tmp/b16/loopd','wb').write(lzma.open('.dev/z/loopd.xz').read()); os.chmod('/tmp/b16/loopd',0o755)
"
S=$PWD/.dev/scenes; A=.dev/z/abdl
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
cp /lib/x86_64-linux-gnu/libc.so.6 $OUT/libc.so.6
for a in "staircase2.ply.zst bih:bih 61" "bunny.ply.zst bih:bih 61" "bathroom.drc bih:bih 21"; do set -- $a
  timeout 100 $A /tmp/b16/s /tmp/b16/t $S/$1 $2 16 $3
done
echo "ab done at $(el) s"
for a in "staircase2.ply.zst grid grid 600" "staircase2.ply.zst bih bih 600" "staircase2.ply.zst bvh sah 600" "bunny.ply.zst kd sah 60"; do set -- $a
  LD_LIBRARY_PATH=/tmp/b16/t:$LD_LIBRARY_PATH /tmp/b16/loopd $S/$1 $2 $3 16 $4 | tail -1
  SAMPLER_CLOCK=wall SAMPLER_US=100 SAMPLER_OUT=$OUT/smp-$1-$2 LD_PRELOAD=$PWD/.dev/prof/sampler.so LD_LIBRARY_PATH=/tmp/b16/t:$LD_LIBRARY_PATH /tmp/b16/loopd $S/$1 $2 $3 16 $4 | tail -1
done
gzip $OUT/smp-*
date -u; echo "total $(el) s"
