set -u
# Run 83: fresh 16-thread run of every variant at 9497cb1 (bench_build), then SBVH and KD SAH
# against e5e2d64 (bench_build_prev, the build of runs 82), two interleaved rounds.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,glob,os
os.makedirs('/tmp/b',exist_ok=True)
for f in glob.glob('.dev/z5/bench*.xz'):
    d='/tmp/b/'+os.path.basename(f)[:-3]; open(d,'wb').write(lzma.open(f).read()); os.chmod(d,0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
B=/tmp/b; S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"; grep -m1 "model name" /proc/cpuinfo
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
timeout 300 $B/bench_build --runs 5 --commit 9497cb1 --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1
echo "fresh run done (at $(el) s)"
for r in 1 2; do for v in bench_build_prev bench_build; do for o in "SBVH" "KD Standard (SAH)"; do
  timeout 60 $B/$v --runs 5 --only "$o" $S/bunny.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc 2>&1 | grep -E "^/|SBVH|KD Standard|Embree 3 high" | sed "s/^/r$r $v [$o] /"
done; done; echo "(at $(el) s)"; done
date -u; echo "total $(el) s"
