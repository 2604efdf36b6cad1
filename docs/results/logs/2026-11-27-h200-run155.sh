set -u
# Run 155: bench_build at the commit in .dev/commit (tables with the first build apart), twice, 16 threads, the five benchmark scenes, per-round times.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
os.makedirs('/tmp/b16',exist_ok=True)
open('/tmp/b16/bench_build','wb').write(lzma.open('.dev/z/bench_build.xz').read()); os.chmod('/tmp/b16/bench_build',0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc); at $(cat .dev/commit)"; lscpu | grep -E "Model name|^CPU\(s\)|Thread"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
for r in a b; do
BENCH_ROUNDS=1 timeout 250 /tmp/b16/bench_build --runs 5 --paired 15 --commit $(cat .dev/commit) --out $OUT/bench-16t-$r.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t-$r.log 2>&1; echo "bench $r exit $? at $(el) s"
grep -E "triangles\)?$|met|MISS" $OUT/bench-16t-$r.log
done
date -u; echo "total $(el) s"
