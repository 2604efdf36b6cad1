set -u
# Run 128: 16 threads, paired A/B of c33 (5b41486) against q3 (pieces of 1,024, SBVH shares down to 1,024, threads watch 100 us before sleeping); step cost; timelines of q3.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for L in ['c33','q3']:
    os.makedirs('/tmp/'+L,exist_ok=True); open('/tmp/'+L+'/libas.so.0','wb').write(lzma.open('.dev/z21/'+L+'.xz').read())
"
S=$PWD/.dev/scenes; Z=.dev/z21
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
for L in c33 q3; do for w in 100 10000; do LD_LIBRARY_PATH=/tmp/$L:$LD_LIBRARY_PATH $Z/prl 16 2000 $w | head -1; done; done
for a in "bunny.ply.zst bvh:sah 41" "bunny.ply.zst bvh:sbvh 15" "bunny.ply.zst kd:sah 15" "staircase.ply.zst bvh:sah 21" "staircase.ply.zst bvh:sbvh 11" "staircase.ply.zst kd:sah 11" "bathroom.drc bvh:sah 11" "bathroom.drc bvh:sbvh 9" "bmw-m6.drc bvh:sbvh 9" "staircase2.ply.zst bvh:sah 41" "staircase2.ply.zst bvh:sbvh 21"; do
  set -- $a
  timeout 60 $Z/abdl /tmp/c33 /tmp/q3 $S/$1 $2 16 $3 | sed 's/.*scenes.//'
done
echo "ab done at $(el) s"
for a in "bunny.ply.zst bvh sah 300" "bunny.ply.zst bvh sbvh 60"; do
  set -- $a
  SAMPLER_CLOCK=wall SAMPLER_US=100 SAMPLER_OUT=$OUT/smp-$1-$3 LD_PRELOAD=$PWD/.dev/prof/sampler.so LD_LIBRARY_PATH=/tmp/q3:$LD_LIBRARY_PATH $Z/loopf $S/$1 $2 $3 16 $4 | tail -1
done
gzip $OUT/smp-*
date -u; echo "total $(el) s"
