set -u
# Run 131: 16 threads, timelines (wall-clock samples) of the binned SAH build at 9eda610 on bunny, staircase, bathroom.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for L in ['c36']:
    os.makedirs('/tmp/'+L,exist_ok=True); open('/tmp/'+L+'/libas.so.0','wb').write(lzma.open('.dev/z22/'+L+'.xz').read())
"
S=$PWD/.dev/scenes; Z=.dev/z21
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
mkdir -p $OUT
for a in "bunny.ply.zst 300" "staircase.ply.zst 100" "bathroom.drc 40"; do set -- $a
LD_LIBRARY_PATH=/tmp/c36:$LD_LIBRARY_PATH $Z/loopf $S/$1 bvh sah 16 $2 | tail -2
SAMPLER_CLOCK=wall SAMPLER_US=50 SAMPLER_OUT=$OUT/smp-$1 LD_PRELOAD=$PWD/.dev/prof/sampler.so LD_LIBRARY_PATH=/tmp/c36:$LD_LIBRARY_PATH $Z/loopf $S/$1 bvh sah 16 $2 | tail -1
done
gzip $OUT/smp-*
date -u
