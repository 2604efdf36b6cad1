set -u
# Run 138: at HEAD (SAH sums in blocks, BIH pieces, grid/BIH thresholds): thread scaling (lthr), timelines of binned SAH on bunny at 16 threads, bench_build 16 threads.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
os.makedirs('/tmp/b16/lib',exist_ok=True); os.makedirs('/tmp/b16/base',exist_ok=True)
for n in ('bench_build','loopf','lthr','loopd'):
    open('/tmp/b16/'+n,'wb').write(lzma.open('.dev/z/'+n+'.xz').read()); os.chmod('/tmp/b16/'+n,0o755)
open('/tmp/b16/lib/libas.so.0','wb').write(lzma.open('.dev/z/libas.so.0.xz').read())
open('/tmp/b16/base/libas.so.0','wb').write(lzma.open('.dev/z/base/libas.so.0.xz').read())
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc); at $(cat .dev/commit)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
cp /lib/x86_64-linux-gnu/libc.so.6 $OUT/libc.so.6
for sc in staircase2.ply.zst bunny.ply.zst bathroom.drc; do
  timeout 90 /tmp/b16/lthr $S/$sc 11 bvh:sah bih:bih grid:grid -- 1 8 16
done
echo "lthr done at $(el) s"
for L in base lib; do
  echo "== loopd binned bunny 16 threads, $L"
  LD_LIBRARY_PATH=/tmp/b16/$L:$LD_LIBRARY_PATH /tmp/b16/loopd $S/bunny.ply.zst bvh sah 16 300 | tail -1
  LD_LIBRARY_PATH=/tmp/b16/$L:$LD_LIBRARY_PATH /tmp/b16/loopd $S/bathroom.drc bvh sah 16 40 | tail -1
done
SAMPLER_CLOCK=wall SAMPLER_US=100 SAMPLER_OUT=$OUT/smp-bunny LD_PRELOAD=$PWD/.dev/prof/sampler.so LD_LIBRARY_PATH=/tmp/b16/lib:$LD_LIBRARY_PATH /tmp/b16/loopd $S/bunny.ply.zst bvh sah 16 300 | tail -1
echo "samples done at $(el) s"
timeout 400 /tmp/b16/bench_build --runs 5 --paired 15 --commit $(cat .dev/commit) --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1; echo "bench exit $? at $(el) s"
grep -E "triangles\)?$|met|MISS" $OUT/bench-16t.log
gzip $OUT/smp-*
date -u; echo "total $(el) s"
