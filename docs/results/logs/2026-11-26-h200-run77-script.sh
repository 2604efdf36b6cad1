set -u
# Build benchmark on the 16-core GPU host: the builders at 8cfbd09 (bench_build) and at 9332f03
# (bench_build_old, this session's start) with Embree 3 beside them in each run.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,glob,os
os.makedirs('/tmp/b',exist_ok=True)
for f in glob.glob('.dev/z5/bench*.xz'):
    d='/tmp/b/'+os.path.basename(f)[:-3]; open(d,'wb').write(lzma.open(f).read()); os.chmod(d,0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
B=/tmp/b; S=$PWD/.dev/scenes; mkdir -p $OUT
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"; lscpu | grep -E "Model name|Thread|Socket"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
echo "== KD SAH and binned SAH, before (9332f03) and after (8cfbd09), 16 and 2 threads (at $(el) s)"
for r in 1 2; do for v in bench_build_old bench_build; do for T in 16 2; do
  timeout 120 $B/$v --runs 5 --threads $T --only "KD Standard (SAH)" $S/staircase.ply.zst $S/bathroom.drc 2>&1 | grep -E "KD Standard|^/|MISS|met " | grep -vE "n/a" | sed "s/^/r$r T$T $v /"
done; done; done
echo "== every variant, 16 threads, after (at $(el) s)"
timeout 300 $B/bench_build --runs 5 --threads 16 --commit 8cfbd09 --out $OUT/bench-16t.md $S/bunny.drc $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc 2>&1 | tail -80
echo "== larger scenes, 16 threads, after, without the sweep SAH builder (at $(el) s)"
for o in "Mid. Cut" "binned" "SBVH" "KD Standard (SAH)" "BIH" "Octree" "Grid"; do
  timeout 100 $B/bench_build --runs 3 --threads 16 --only "$o" $S/bathroom2.drc $S/chopper-titan.drc 2>&1 | grep -vE "n/a|^variant|^date" | sed "s/^/[$o] /"
done
date -u; echo "total $(el) s"
