set -u
# Run 133: 16 threads, timelines of binned SAH at e91e646 on bunny and bathroom, with the host's libc to name its functions.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
os.makedirs('/tmp/c37',exist_ok=True); open('/tmp/c37/libas.so.0','wb').write(lzma.open('.dev/z23/c37.xz').read())
"
S=$PWD/.dev/scenes; Z=.dev/z21
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
mkdir -p $OUT
cp /lib/x86_64-linux-gnu/libc.so.6 $OUT/libc.so.6
for a in "bunny.ply.zst 300" "bathroom.drc 40"; do set -- $a
LD_LIBRARY_PATH=/tmp/c37:$LD_LIBRARY_PATH $Z/loopf $S/$1 bvh sah 16 $2 | tail -2
SAMPLER_CLOCK=wall SAMPLER_US=100 SAMPLER_OUT=$OUT/smp-$1 LD_PRELOAD=$PWD/.dev/prof/sampler.so LD_LIBRARY_PATH=/tmp/c37:$LD_LIBRARY_PATH $Z/loopf $S/$1 bvh sah 16 $2 | tail -1
done
gzip $OUT/smp-*
date -u
