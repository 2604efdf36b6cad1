set -u
# Run 130: 16 threads. Paired A/B, SBVH: c35 (7431810) vs c36 (9eda610, parallel partition). Timeline of c36 SBVH on bathroom. bench_build at 9eda610.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
os.makedirs('/tmp/b16',exist_ok=True)
open('/tmp/b16/bench_build','wb').write(lzma.open('.dev/z22/bench_build.xz').read()); os.chmod('/tmp/b16/bench_build',0o755)
for L in ['c35','c36']:
    os.makedirs('/tmp/'+L,exist_ok=True); open('/tmp/'+L+'/libas.so.0','wb').write(lzma.open('.dev/z22/'+L+'.xz').read())
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
S=$PWD/.dev/scenes; Z=.dev/z21
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
for a in "bunny.ply.zst bvh:sbvh 21" "staircase.ply.zst bvh:sbvh 15" "bathroom.drc bvh:sbvh 11" "bmw-m6.drc bvh:sbvh 11" "staircase2.ply.zst bvh:sbvh 31"; do
  set -- $a
  timeout 60 $Z/abdl /tmp/c35 /tmp/c36 $S/$1 $2 16 $3 | sed 's/.*scenes.//'
done
echo "ab done at $(el) s"
SAMPLER_CLOCK=wall SAMPLER_US=100 SAMPLER_OUT=$OUT/smp-bathroom-sbvh LD_PRELOAD=$PWD/.dev/prof/sampler.so LD_LIBRARY_PATH=/tmp/c36:$LD_LIBRARY_PATH $Z/loopf $S/bathroom.drc bvh sbvh 16 12 | tail -1
gzip $OUT/smp-*
timeout 400 /tmp/b16/bench_build --runs 5 --paired 15 --commit $(cat .dev/commit22) --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1; echo "bench exit $? at $(el) s"
grep -E "met|MISS" $OUT/bench-16t.log
date -u; echo "total $(el) s"
