set -u
# Run 127: bench_build at 5b41486 (z20), 16 threads; then wall-clock samples of binned SAH and SBVH builds at 16 threads.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
os.makedirs('/tmp/b16',exist_ok=True)
open('/tmp/b16/bench_build','wb').write(lzma.open('.dev/z20/bench_build.xz').read()); os.chmod('/tmp/b16/bench_build',0o755)
open('/tmp/b16/libas.so.0','wb').write(lzma.open('.dev/z20/libas.so.0.xz').read())
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc); at $(cat .dev/commit20)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
for a in "bunny.ply.zst bvh sah 300" "bunny.ply.zst bvh sbvh 60" "staircase.ply.zst bvh sah 80" "staircase.ply.zst bvh sbvh 30" "bathroom.drc bvh sbvh 12"; do
  set -- $a
  echo "== $1 $2 $3 x$4"
  LD_LIBRARY_PATH=/tmp/b16:$LD_LIBRARY_PATH timeout 60 .dev/z20/loopf $S/$1 $2 $3 16 $4 | tail -3
  SAMPLER_CLOCK=wall SAMPLER_US=100 SAMPLER_OUT=$OUT/smp-$1-$3 LD_PRELOAD=$PWD/.dev/prof/sampler.so LD_LIBRARY_PATH=/tmp/b16:$LD_LIBRARY_PATH timeout 60 .dev/z20/loopf $S/$1 $2 $3 16 $4 | tail -1
done
echo "samples done at $(el) s"
timeout 420 /tmp/b16/bench_build --runs 5 --paired 15 --commit $(cat .dev/commit20) --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1; echo "bench exit $? at $(el) s"
grep -E "triangles\)$|met|MISS" $OUT/bench-16t.log
gzip $OUT/smp-* 
date -u; echo "total $(el) s"
